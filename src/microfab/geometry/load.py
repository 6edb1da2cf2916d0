"""One entry point for every drawing source: files, built-in shapes, text and airfoils.

``load_drawing(spec)`` accepts

- a file: ``part.dxf`` (:func:`~microfab.geometry.dxf.read_dxf`), ``logo.svg``
  (:func:`~microfab.geometry.svg.read_svg`), ``wing.dat`` (a Selig airfoil,
  :func:`~microfab.geometry.airfoil.airfoil_path`);
- a shape: ``circle:radius=0.01`` (see :data:`~microfab.geometry.shapes.SHAPES`);
- text: ``text:urch`` (glyph outlines, :func:`~microfab.geometry.text.text_layer`);
- a built-in airfoil: ``airfoil:e344``.
"""

from __future__ import annotations

from pathlib import Path as FsPath

from microfab.geometry.layer import Layer
from microfab.geometry.shapes import SHAPES, parse_shape

__all__ = ["load_drawing"]

_FILE_SUFFIXES = (".dxf", ".svg", ".dat")


def load_drawing(
    spec: str,
    *,
    units: str | None = None,
    chord: float = 0.1,
    text_height: float = 0.01,
) -> Layer:
    """Load a drawing, shape, text or airfoil as a :class:`Layer` (metres).

    Parameters
    ----------
    spec : str
        File name or source description (see the module docstring).
    units : str, optional
        Drawing units of a DXF file without (or with wrong) ``$INSUNITS``, e.g. ``"mm"``.
    chord : float
        Chord of an airfoil, m.
    text_height : float
        Font size of text, m.

    Raises
    ------
    FileNotFoundError
        If ``spec`` names a drawing file that does not exist.
    ValueError
        If the source is not understood, the file is malformed, or the drawing has no
        contours or reaches beyond `~microfab.geometry.layer.MAX_COORDINATE_M`.
    """
    return _load(spec, units=units, chord=chord, text_height=text_height).require_extent()


def _load(spec: str, *, units: str | None, chord: float, text_height: float) -> Layer:
    spec = spec.strip()
    if not spec:
        raise ValueError("empty drawing specification")
    kind, sep, arg = spec.partition(":")
    kind_l = kind.lower()
    if sep and kind_l == "text":
        from microfab.geometry.text import text_layer

        return text_layer(arg, height=text_height)
    if sep and kind_l == "airfoil":
        from microfab.geometry.airfoil import airfoil_path

        return Layer((airfoil_path(arg or "e344", chord=chord),), source=spec)
    if kind_l in SHAPES:
        return Layer((parse_shape(spec),), source=spec)
    path = FsPath(spec)
    suffix = path.suffix.lower()
    if suffix not in _FILE_SUFFIXES:
        raise ValueError(
            f"cannot tell what {spec!r} is: expected a .dxf, .svg or .dat file, a shape "
            f"({', '.join(sorted(SHAPES))}, e.g. circle:radius=0.01), text:LETTERS or "
            "airfoil:e344"
        )
    if not path.is_file():
        raise FileNotFoundError(f"drawing file not found: {path}")
    if suffix == ".dxf":
        from microfab.geometry.dxf import read_dxf

        return read_dxf(path, units=units)
    if suffix == ".svg":
        from microfab.geometry.svg import read_svg

        return read_svg(path)
    from microfab.geometry.airfoil import airfoil_path, read_selig

    _, points = read_selig(path)
    return Layer((airfoil_path(points, chord=chord),), source=str(path))
