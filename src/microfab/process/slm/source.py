"""From a drawing or a lattice description to a scan program (`VectorPath`).

`scan_program` accepts one text *source*, as the command line and job files give it:

* ``lattice:key=value,...``: one layer of the simple cubic strut lattice of seed 003 part 2
  §4 (`microfab.process.slm.lattice`). Keys (SI units), each optional:

  ========  =====================================================  =======================
  key       meaning                                                default
  ========  =====================================================  =======================
  z         height of the layer, m (node planes at multiples of    0 (a node plane)
            the cell)
  radius    radius of the outline disc the lattice is clipped to,  20e-3 (`LatticeSpec`)
            m
  strut     strut diameter, m                                      250e-6 (seed §4)
  fraction  volume fraction (fixes the cell, `cubic_cell`)         0.05 (seed §4)
  hatch     hatch spacing, m                                       ``hatch_spacing_m``
  sides     sides of a strut's polygon (a multiple of 4)           32 (`LatticeSpec`)
  ========  =====================================================  =======================

  The layer is `microfab.process.slm.lattice.lattice_layer`'s: hatch band by band, then the
  contours (``contours`` does not apply: that scan strategy is the lattice's own).
* any drawing `microfab.geometry.load.load_drawing` understands (a DXF or SVG file, a shape
  such as ``circle:radius=5e-3``, text, an airfoil): every contour must be closed (an open
  one is refused, naming it). Its closed contours are marked first, each as a closed
  polyline within `CHORD_TOL_M` of the exact contour (laser on along it, a jump to the
  next), then the material (even-odd rule) is hatched (`microfab.geometry.hatch.hatch`:
  parallel lines ``hatch_spacing_m`` apart at ``hatch_angle_deg``, meander) with jumps
  between the hatch lines: one `VectorPath` that starts at ``start``. Contour then hatch is
  assumed (the seed gives no scan strategy for a drawing); a drawing is one layer, the
  same at every height, so ``z_m`` does not apply.
"""

from __future__ import annotations

import math

import numpy as np

from microfab.core.validate import check_finite, check_positive
from microfab.geometry.hatch import hatch
from microfab.geometry.load import load_drawing
from microfab.process.slm.lattice import LatticeSpec, lattice_layer
from microfab.process.slm.program import VectorPath

__all__ = ["CHORD_TOL_M", "LATTICE_KEYS", "LATTICE_PREFIX", "parse_lattice_source", "scan_program"]

#: Prefix of a lattice source.
LATTICE_PREFIX = "lattice:"

#: Keys of a lattice source and the `LatticeSpec` field each sets (``z`` is the height).
LATTICE_KEYS: dict[str, str] = {
    "z": "z_m",
    "radius": "outline_radius_m",
    "strut": "strut_m",
    "fraction": "volume_fraction",
    "hatch": "hatch_spacing_m",
    "sides": "circle_sides",
}

#: Chord tolerance of a drawing's contours as marked, m (assumed 0.5 µm: a third of the
#: twin's 1.5 µm bit, as the lattice's 0.6 µm strut polygons).
CHORD_TOL_M = 0.5e-6


#: Highest layer accepted, m. Assumed: no SLM build volume is taller than about 1 m.
MAX_HEIGHT_M = 1.0


def _lattice_values(text: str) -> dict[str, float | int]:
    """The ``key: value`` pairs of a lattice source, checked (`parse_lattice_source`)."""
    src = text.strip()
    if not src.lower().startswith(LATTICE_PREFIX):
        raise ValueError(f"a lattice source starts with {LATTICE_PREFIX!r}, got {text!r}")
    known = ", ".join(LATTICE_KEYS)
    values: dict[str, float | int] = {}
    for item in filter(None, (a.strip() for a in src[len(LATTICE_PREFIX) :].split(","))):
        key, eq, val = item.partition("=")
        key = key.strip().lower()
        if not eq:
            raise ValueError(f"lattice item {item!r} must look like key=value (keys: {known})")
        if key not in LATTICE_KEYS:
            raise ValueError(f"unknown lattice key {key!r}; known: {known}")
        if key in values:
            raise ValueError(f"lattice key {key!r} is given twice")
        try:
            number = float(val)
        except ValueError:
            raise ValueError(f"lattice {key}={val.strip()!r} is not a number") from None
        if key == "sides":
            if not (math.isfinite(number) and number == int(number)):
                raise ValueError(f"lattice sides={val.strip()!r} must be a whole number")
            values[key] = int(number)
        else:
            values[key] = number
    return values


def _spec(values: dict[str, float | int], **defaults: float) -> LatticeSpec:
    """A `LatticeSpec` from parsed values over ``defaults`` (fields of `LatticeSpec`).

    The hatch lines keep half a spacing off the node rows whatever the spacing (the
    lattice's assumption: no line along a strut's axis).
    """
    kwargs: dict[str, float | int] = dict(defaults)
    kwargs.update({LATTICE_KEYS[k]: v for k, v in values.items() if k != "z"})
    if "hatch_spacing_m" in kwargs:
        kwargs["hatch_offset_m"] = 0.5 * float(kwargs["hatch_spacing_m"])
    return LatticeSpec(**kwargs)  # type: ignore[arg-type]


def parse_lattice_source(text: str) -> tuple[float, LatticeSpec]:
    """Read ``lattice:key=value,...`` (module doc) as a height and a `LatticeSpec`.

    Parameters
    ----------
    text : str
        The source, e.g. ``"lattice:z=4e-4,radius=3e-3"``; ``"lattice:"`` alone is the
        default lattice at ``z = 0``.

    Returns
    -------
    z_m : float
        Height of the layer, m (0 when not given).
    spec : LatticeSpec
        The lattice, outline and hatch (`LatticeSpec`'s defaults for the keys not given;
        a given ``hatch`` also sets the offset of the lines to half of it).

    Raises
    ------
    ValueError
        Not a lattice source, an item that is not ``key=value``, an unknown or repeated
        key (the message lists the known ones), a value that is not a number (``sides``:
        not a whole number), or values `LatticeSpec` refuses.
    """
    values = _lattice_values(text)
    z = check_finite("lattice z", float(values.get("z", 0.0)), "m")
    if not 0.0 <= z <= MAX_HEIGHT_M:
        raise ValueError(
            f"lattice z = {z:g} m is outside the build, 0 to {MAX_HEIGHT_M:g} m; check the unit"
        )
    return z, _spec(values)


def _drawing_program(
    source: str,
    hatch_spacing_m: float,
    hatch_angle_deg: float,
    contours: bool,
    start: tuple[float, float],
) -> VectorPath:
    """Contours then hatch of a drawing source (module doc)."""
    layer = load_drawing(source)
    open_ = [i for i, c in enumerate(layer.contours) if not c.closed]
    if open_:
        desc = ", ".join(
            f"#{i} (ends {np.hypot(*(layer[i].end - layer[i].start)) * 1e3:.3g} mm apart)"
            for i in open_[:10]
        )
        more = f" and {len(open_) - 10} more" if len(open_) > 10 else ""
        raise ValueError(
            f"{source}: {len(open_)} of its {len(layer)} contours are open: {desc}{more}; a scan "
            "program marks and hatches closed contours only: close them in the drawing"
        )
    here = np.asarray(start, dtype=float)
    parts: list[VectorPath] = []
    if contours:
        rings = [c.flatten(CHORD_TOL_M)[:-1] for c in layer.contours]
        parts.append(VectorPath.from_polylines(rings, start=here, closed=True))
        here = parts[-1].points[-1]
    sv = hatch(layer, spacing=hatch_spacing_m, angle=math.radians(hatch_angle_deg), start=here)
    if len(sv):
        parts.append(VectorPath.from_scan_vectors(sv))
    if not parts:
        return VectorPath(here.reshape(1, 2), np.zeros(0, bool))
    out = parts[0]
    for p in parts[1:]:  # each starts where the previous ended
        out = VectorPath(
            np.vstack([out.points, p.points[1:]]), np.concatenate([out.is_mark, p.is_mark])
        )
    return out


def scan_program(
    source: str,
    *,
    z_m: float | None = None,
    hatch_spacing_m: float = 100e-6,
    hatch_angle_deg: float = 0.0,
    contours: bool = True,
    start: tuple[float, float] = (0.0, 0.0),
) -> VectorPath:
    """The scan program (marks and jumps, m) of a lattice layer or a drawing (module doc).

    Parameters
    ----------
    source : str
        ``lattice:key=value,...`` or a drawing source (file, shape, text, airfoil).
    z_m : float, optional
        Height of a lattice layer, m (e.g. set per layer by a build loop); the source's
        ``z`` otherwise. Giving both with different values is refused. Ignored for a
        drawing (one layer).
    hatch_spacing_m : float
        Hatch distance, m (assumed 100 µm as the lattice's); a lattice source's ``hatch``
        key takes precedence.
    hatch_angle_deg : float
        Hatch direction, degrees counter-clockwise from +x.
    contours : bool
        Mark a drawing's contours before hatching it (a lattice always has them).
    start : (float, float)
        Scanner position before the program, m.

    Returns
    -------
    VectorPath
        The program in execution order, starting at ``start``; it has no vectors when a
        drawing is narrower than the hatch spacing and ``contours`` is off.

    Raises
    ------
    ValueError
        A bad lattice source (`parse_lattice_source`), two different heights, a drawing
        that cannot be read or has open contours (named), a non-positive spacing or a
        non-finite angle or start.
    FileNotFoundError
        A drawing file that does not exist.
    """
    h = check_positive("hatch spacing", hatch_spacing_m, "m")
    ang = check_finite("hatch angle", hatch_angle_deg, "deg")
    p0 = np.asarray(start, dtype=float).reshape(-1)
    if p0.shape != (2,) or not np.all(np.isfinite(p0)):
        raise ValueError(f"start must be a finite point (x, y) in m, got {start!r}")
    here = (float(p0[0]), float(p0[1]))
    if source.strip().lower().startswith(LATTICE_PREFIX):
        values = _lattice_values(source)
        z = check_finite("lattice z", float(values.get("z", 0.0)), "m")
        if z_m is not None:
            zz = check_finite("z_m", z_m, "m")
            if "z" in values and zz != z:
                raise ValueError(
                    f"the layer height is given twice: z={z:g} m in {source!r} and z_m = "
                    f"{zz:g} m; give one"
                )
            z = zz
        spec = _spec(values, hatch_spacing_m=h, hatch_angle_rad=math.radians(ang))
        return lattice_layer(z, spec, start=here)
    return _drawing_program(source, h, ang, contours, here)
