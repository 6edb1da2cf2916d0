"""Text outlines as exact contours, from the fonts matplotlib ships.

A glyph outline is a chain of straight lines and quadratic (TrueType) or cubic
(PostScript/CFF) Bézier curves; :class:`matplotlib.textpath.TextPath` lays the text out and
returns them, and each becomes an exact :class:`~microfab.geometry.segments.LineSegment` or
:class:`~microfab.geometry.segments.CurveSegment` (Bézier → Chebyshev conversion is exact).
"""

from __future__ import annotations

import numpy as np
from matplotlib.font_manager import FontProperties, findfont, get_font
from matplotlib.path import Path as MplPath
from matplotlib.textpath import TextPath

from microfab.core.validate import check_in_range
from microfab.geometry.layer import MAX_COORDINATE_M, Layer
from microfab.geometry.path import Path
from microfab.geometry.segments import CurveSegment, LineSegment, Segment

__all__ = ["SEED002_LETTERS", "letters_seed002", "text_layer"]

SEED002_LETTERS = ("u", "r", "c", "h")
"""The letters test case of seed 002 §II-C: "u", "r", "c", "h" of the ETH Zürich logo."""


def _contours(mpl: MplPath, k: float, shift: np.ndarray) -> list[Path]:
    """Closed contours of a matplotlib path, mapped by ``p -> k p + shift``."""
    out: list[Path] = []
    segs: list[Segment] = []
    first = cur = None

    def close() -> None:
        nonlocal segs
        if segs:
            assert first is not None and cur is not None
            if np.any(cur != first):
                segs.append(LineSegment(cur, first))
            kept = [s for s in segs if s.length > 0]
            # FreeType leaves zero-length stub contours (a moveto and a lineto to the same
            # point); they draw nothing and are dropped
            if kept:
                out.append(Path(tuple(kept), closed=True))
        segs = []

    for verts, code in mpl.iter_segments(simplify=False, curves=True):
        v = k * np.asarray(verts, dtype=float).reshape(-1, 2) + shift
        if code == MplPath.MOVETO:
            close()
            first = cur = v[-1]
        elif code == MplPath.LINETO:
            segs.append(LineSegment(cur, v[0]))
            cur = v[0]
        elif code in (MplPath.CURVE3, MplPath.CURVE4):
            segs.append(CurveSegment.from_bezier(np.vstack([cur, v])))
            cur = v[-1]
        elif code == MplPath.CLOSEPOLY:
            close()
            cur = first
        else:  # pragma: no cover - TextPath emits only the codes above
            raise ValueError(f"unexpected matplotlib path code {code}")
    close()  # an outline left open is closed by a straight segment
    return out


def text_layer(
    text: str,
    *,
    height: float = 0.01,
    font: str = "DejaVu Sans",
    weight: str = "normal",
) -> Layer:
    """Outlines of ``text`` set in a font matplotlib can find, as closed contours.

    Parameters
    ----------
    text : str
        The text, one line (no layout beyond matplotlib's: a newline is not a line break).
    height : float
        Font size, m: the height of the font's em square, the usual typographic size. A
        glyph is smaller than that: in DejaVu Sans a capital letter is 0.729 ``height``
        tall, a lower-case "x" 0.547 ``height``, and the glyph box of the text is
        ``height`` × (its ink extent in em units); outlines scale linearly with it.
        matplotlib delivers outline coordinates on a grid of 1/6400 em (FreeType 26.6
        fixed point at its internal size 100), i.e. to within ``height / 6400``. At most
        `~microfab.geometry.layer.MAX_COORDINATE_M`.
    font : str
        Font family name, e.g. ``"DejaVu Sans"`` (bundled with matplotlib, always there)
        or ``"DejaVu Serif"``.
    weight : str
        Font weight: ``"normal"``, ``"bold"``, ``"light"``, …

    Returns
    -------
    Layer
        The glyph contours, closed, each outer boundary followed by its holes (the
        counter of an "o"); oriented with outer boundaries counter-clockwise and holes
        clockwise (:meth:`~microfab.geometry.layer.Layer.oriented`); translated so that
        the lower-left corner of the text's bounding box (ink, not advance box) is the
        origin. ``source`` is the text.

    Raises
    ------
    ValueError
        If the text has no visible outline (empty or blank), holds a control character or
        a character the font lacks, ``height`` is not a positive length, or the font is
        not found.
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a string, got {type(text).__name__}")
    if not text.strip():
        raise ValueError(f"text {text!r} has no visible characters; give at least one glyph")
    h = check_in_range("text height", height, 0.0, MAX_COORDINATE_M, "m", low_closed=False)
    prop = FontProperties(family=font, weight=weight)
    try:
        ft = get_font(findfont(prop, fallback_to_default=False))
    except ValueError as exc:
        raise ValueError(f"font {font!r} (weight {weight!r}) not found: {exc}") from exc
    for ch in text:
        # a glyph the font lacks would be drawn as a placeholder box (dozens of contours)
        if not ch.isprintable() or (not ch.isspace() and ft.get_char_index(ord(ch)) == 0):
            what = "not a printable character" if not ch.isprintable() else f"not in font {font!r}"
            raise ValueError(
                f"text {text!r}: character {ch!r} (U+{ord(ch):04X}) is {what}; "
                "give letters the font has"
            )
    tp = TextPath((0.0, 0.0), text, size=1.0, prop=prop)
    if len(tp.vertices) == 0:
        raise ValueError(f"text {text!r} has no outline in font {font!r}")
    ext = tp.get_extents()  # exact: Bézier extrema, not the control polygon
    shift = -h * np.array([ext.x0, ext.y0])
    contours = _contours(tp, h, shift)
    if not contours:
        raise ValueError(f"text {text!r} has no outline in font {font!r}")
    return _outer_first(Layer(tuple(contours), (), source=text)).oriented()


def _outer_first(layer: Layer) -> Layer:
    """Reorder contours depth-first: each outer boundary followed by its holes (and islands).

    Fonts list a glyph's contours in any order (DejaVu's "o" gives the hole first).
    """
    depth = layer.depth
    polys = [MplPath(c.flatten()) for c in layer.contours]
    probes = [c.point([0.5 * c.segments[0].length])[0] for c in layer.contours]
    keys = []
    for i in range(len(layer)):
        anc = [j for j in range(len(layer)) if j != i and polys[j].contains_point(tuple(probes[i]))]
        keys.append((*sorted(anc, key=lambda j: depth[j]), i))
    order = sorted(range(len(layer)), key=lambda i: keys[i])
    return Layer(tuple(layer.contours[i] for i in order), layer.skipped, layer.source)


def letters_seed002(height: float = 0.01) -> dict[str, Layer]:
    """The letters "u", "r", "c", "h" of seed 002 §II-C (the "letters" test case).

    The seed takes the four letters from the ETH Zürich logo, whose typeface is not
    available here; DejaVu Sans (bundled with matplotlib) stands in. Each letter is a
    single closed contour with sharp corners, straight segments and curves of varying
    curvature, which is what the test case is for (seed 002 §II-C).

    Parameters
    ----------
    height : float
        Font size, m (see :func:`text_layer`).

    Returns
    -------
    dict of str to Layer
        One layer per letter, each with its lower-left ink corner at the origin.
    """
    return {ch: text_layer(ch, height=height) for ch in SEED002_LETTERS}
