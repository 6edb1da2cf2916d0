"""Layers of a simple cubic strut lattice, the test part of seed 003 part 2 §4.

The seed builds a lattice "Stanford Bunny" with struts 250 µm thick and a volume fraction of
5 % (§4); no bunny mesh is shipped here, so a layer is the lattice's cross-section clipped
to a documented outline (a disc in the field's centre, `LatticeSpec`).

**Cell.** Struts are cylinders of diameter ``d = 2 r`` along x, y and z through the nodes
of a cubic grid of pitch ``a``. One cell holds one strut of length ``a`` per direction and
one node, where the three overlap; by inclusion-exclusion (the Steinmetz solids: two
crossing cylinders share ``16 r³ / 3``, three share ``8 (2 - √2) r³``)

``φ(a) = (3 π r² a - 16 r³ + 8 (2 - √2) r³) / a³``,

exact for ``a >= 2 r``. `cubic_cell` solves ``φ(a) = 5 %`` for ``d = 250 µm``: ``a`` =
1.637 mm, the seed's "cell ≈ 1.64 mm" (without the node overlap it would be 1.716 mm).

**Section at height z.** The vertical struts cut every layer as discs of radius ``r`` at the
nodes; within ``|z - k a| < r`` of a node plane the horizontal struts add strips of
half-width ``sqrt(r² - (z - k a)²)`` along the rows and columns. Discs are polygons of
``circle_sides`` sides (32: chord error 0.6 µm, below the 1.5 µm bit; assumed).

**Vectors** (`lattice_layer`): first the hatch (`microfab.geometry.hatch.hatch`, spacing 100
µm, assumed), band by band (one band of height ``a`` per row of nodes, edges half-way
between hatch lines, so that no line is lost on a cut), then the contours (each ring of
the section as a closed polyline of marks), in serpentine order of their rows. Hatch then
contour is assumed (the seed gives no scan strategy).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import shapely

from microfab.core.validate import check_finite, check_in_range, check_int, check_positive
from microfab.geometry.hatch import hatch
from microfab.geometry.layer import Layer
from microfab.geometry.path import Path
from microfab.geometry.segments import LineSegment
from microfab.process.slm.program import VectorPath

__all__ = [
    "STRUT_DIAMETER_M",
    "VOLUME_FRACTION",
    "LatticeSpec",
    "cubic_cell",
    "cubic_volume_fraction",
    "lattice_layer",
    "lattice_section",
]

STRUT_DIAMETER_M = 250e-6  # seed 003 part 2 §4: strut thickness 250 µm
VOLUME_FRACTION = 0.05  # seed 003 part 2 §4: volume fraction 5 %
_TRICYLINDER = 8.0 * (2.0 - math.sqrt(2.0))  # Steinmetz: three cylinders share this r³
_BICYLINDER = 16.0 / 3.0  # Steinmetz: two crossing cylinders share this r³


def cubic_volume_fraction(cell_m: float, strut_m: float = STRUT_DIAMETER_M) -> float:
    """Volume fraction of a simple cubic lattice of cylindrical struts (module doc).

    Parameters
    ----------
    cell_m : float
        Cell size ``a``, m (>= the strut diameter).
    strut_m : float
        Strut diameter ``d``, m.
    """
    d = check_positive("strut_m", strut_m, "m")
    a = check_positive("cell_m", cell_m, "m")
    if a < d:
        raise ValueError(f"cell_m must be at least the strut diameter {d} m, got {a} m")
    x = 0.5 * d / a  # r / a: the fraction has no scale (r**3 overflowed for a 1e308 m strut)
    return 3.0 * math.pi * x * x + (_TRICYLINDER - 3.0 * _BICYLINDER) * x**3


def cubic_cell(
    volume_fraction: float = VOLUME_FRACTION, strut_m: float = STRUT_DIAMETER_M
) -> float:
    """Cell size of a simple cubic lattice with this volume fraction and strut, m.

    Solves `cubic_volume_fraction` ``= volume_fraction`` (it falls monotonically from its
    value at ``a = d`` towards 0). Seed 003 part 2 §4 (5 %, 250 µm): 1.637 mm.

    Raises
    ------
    ValueError
        When the fraction is not in ``(0, φ(d))`` (struts touching or more).
    """
    d = check_positive("strut_m", strut_m, "m")
    top = cubic_volume_fraction(d, d)
    phi = check_in_range(
        "volume_fraction", volume_fraction, 0.0, top, low_closed=False, high_closed=False
    )
    # solved for a / d (scale-free), then scaled: a huge strut cannot overflow the bracket
    hi = max(2.0, math.sqrt(3.0 * math.pi / 4.0 / phi) * 1.5)
    ratio = scipy.optimize.brentq(
        lambda c: cubic_volume_fraction(c, 1.0) - phi, 1.0, hi, xtol=1e-13, rtol=1e-14
    )
    a = float(ratio * d)
    if not math.isfinite(a):
        raise ValueError(
            f"strut_m = {d:g} m is too large: the cell of {ratio:.6g} struts overflows"
        )
    return a


@dataclass(frozen=True, kw_only=True)
class LatticeSpec:
    """A cubic strut lattice clipped to a disc, and how its layers are hatched.

    Parameters
    ----------
    strut_m : float
        Strut diameter, m (seed 003 part 2 §4: 250 µm).
    volume_fraction : float
        Lattice volume fraction (seed 003 part 2 §4: 5 %); fixes the cell (`cubic_cell`).
    outline_radius_m : float
        Radius of the disc the lattice is clipped to, centred on the field's centre, m
        (assumed 20 mm: no bunny mesh is shipped; the seed's part fits a ~40 mm disc).
    circle_sides : int
        Sides of a strut's polygon, a multiple of 4 (assumed 32, chord error 0.6 µm).
    hatch_spacing_m : float
        Hatch distance, m (assumed 100 µm).
    hatch_angle_rad : float
        Hatch direction, rad from +x (assumed 0).
    hatch_offset_m : float
        Shift of the hatch lines from the node rows, m (assumed half the spacing: no line
        runs along a strut's axis).
    """

    strut_m: float = STRUT_DIAMETER_M
    volume_fraction: float = VOLUME_FRACTION
    outline_radius_m: float = 20e-3  # assumed, see above
    circle_sides: int = 32  # assumed
    hatch_spacing_m: float = 100e-6  # assumed
    hatch_angle_rad: float = 0.0  # assumed
    hatch_offset_m: float = 50e-6  # assumed

    def __post_init__(self) -> None:
        check_positive("strut_m", self.strut_m, "m")
        cubic_cell(self.volume_fraction, self.strut_m)  # refuses an impossible fraction
        check_positive("outline_radius_m", self.outline_radius_m, "m")
        if check_int("circle_sides", self.circle_sides, 8) % 4:
            raise ValueError(f"circle_sides must be a multiple of 4, got {self.circle_sides}")
        check_positive("hatch_spacing_m", self.hatch_spacing_m, "m")
        check_finite("hatch_angle_rad", self.hatch_angle_rad, "rad")
        check_finite("hatch_offset_m", self.hatch_offset_m, "m")

    @property
    def cell_m(self) -> float:
        """Cell size ``a``, m (`cubic_cell`)."""
        return cubic_cell(self.volume_fraction, self.strut_m)


def lattice_section(z_m: float, spec: LatticeSpec | None = None) -> shapely.Geometry:
    """The lattice's material at height ``z_m`` (node planes at multiples of the cell), m.

    Returns
    -------
    shapely.Geometry
        (Multi)Polygon of the section within the outline disc, m.
    """
    sp = LatticeSpec() if spec is None else spec
    z = check_finite("z_m", z_m, "m")
    a, r, R = sp.cell_m, 0.5 * sp.strut_m, sp.outline_radius_m
    k = math.ceil((R + r) / a)
    ij = np.arange(-k, k + 1) * a
    X, Y = np.meshgrid(ij, ij)
    nodes = np.column_stack([X.ravel(), Y.ravel()])
    nodes = nodes[np.hypot(*nodes.T) < R + r]
    disc = shapely.Point(0.0, 0.0).buffer(R, quad_segs=64)
    circles = shapely.buffer(shapely.points(nodes), r, quad_segs=sp.circle_sides // 4)
    dz = z - a * round(z / a)
    if abs(dz) < r:  # horizontal struts: strips along the rows and columns
        w = math.sqrt(r * r - dz * dz)
        rows = ij[np.abs(ij) < R + w]
        strips = [shapely.box(-R, y - w, R, y + w) for y in rows]
        strips += [shapely.box(x - w, -R, x + w, R) for x in rows]
        geom = shapely.union_all(np.concatenate([circles, np.array(strips, dtype=object)]))
        return shapely.intersection(geom, disc)
    parts = shapely.intersection(circles, disc)
    parts = shapely.get_parts(parts[~shapely.is_empty(parts)])
    return shapely.multipolygons(parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON])


def _rings(geom: shapely.Geometry) -> list[np.ndarray]:
    """Every exterior and interior ring of ``geom``, vertices (k, 2) without the repeat."""
    polys = shapely.get_parts(geom)
    rings = []
    for p in polys:
        if p.is_empty or shapely.get_type_id(p) != shapely.GeometryType.POLYGON:
            continue
        for ring in (p.exterior, *p.interiors):
            v = np.asarray(ring.coords)[:-1]
            if v.shape[0] >= 3:
                rings.append(v)
    return rings


def _ring_path(v: np.ndarray) -> Path:
    """A closed polyline `Path` through ``v`` (k, 2), made in one go."""
    segs = LineSegment.many(np.hstack([v, np.roll(v, -1, axis=0)]))
    return Path(tuple(segs), closed=True)


def _serpentine(rings: list[np.ndarray], a: float) -> list[np.ndarray]:
    """Rings in rows of the cell pitch, left to right then right to left."""
    if not rings:
        return []
    first = np.array([v[0] for v in rings])
    row = np.round(first[:, 1] / a).astype(np.int64)
    x = np.where(row % 2 == 0, first[:, 0], -first[:, 0])
    return [rings[i] for i in np.lexsort((x, row))]


def lattice_layer(
    z_m: float, spec: LatticeSpec | None = None, *, start: tuple[float, float] = (0.0, 0.0)
) -> VectorPath:
    """The scan vectors of one lattice layer: hatch band by band, then the contours.

    Parameters
    ----------
    z_m : float
        Height of the layer, m (node planes at multiples of the cell).
    spec : LatticeSpec, optional
        Lattice, outline and hatch (default `LatticeSpec()`).
    start : tuple of float
        Scanner position before the layer, m.

    Returns
    -------
    VectorPath
        Marks and jumps in execution order, m.
    """
    sp = LatticeSpec() if spec is None else spec
    geom = lattice_section(z_m, sp)
    a, h = sp.cell_m, sp.hatch_spacing_m
    c, s = math.cos(sp.hatch_angle_rad), math.sin(sp.hatch_angle_rad)
    R = sp.outline_radius_m
    # bands across the hatch direction, one per node row, edges between two hatch lines
    k = math.ceil(R / a) + 1
    centre = np.arange(-k, k + 2) - 0.5
    j = np.round((centre * a - sp.hatch_offset_m) / h - 0.5)
    edges = sp.hatch_offset_m + (j + 0.5) * h
    rot = np.array([[c, -s], [s, c]])
    g_uv = shapely.transform(geom, lambda p: p @ rot)  # the section in (along, across) axes
    paths: list[VectorPath] = []
    here = np.asarray(start, dtype=float)
    big = 2.0 * R + 1.0
    for lo, hi in itertools.pairwise(edges):
        band = shapely.intersection(g_uv, shapely.box(-big, lo, big, hi))
        rings = _rings(band)
        if not rings:
            continue
        layer = Layer(tuple(_ring_path(v @ rot.T) for v in rings))
        sv = hatch(layer, spacing=h, angle=sp.hatch_angle_rad, offset=sp.hatch_offset_m)
        if len(sv):
            paths.append(VectorPath.from_scan_vectors(sv, start=here))
            here = paths[-1].points[-1]
    contours = _serpentine(_rings(geom), a)
    if contours:
        paths.append(VectorPath.from_polylines(contours, start=here))
    if not paths:
        return VectorPath(np.asarray(start, dtype=float).reshape(1, 2), np.zeros(0, bool))
    out = paths[0]
    for p in paths[1:]:  # each continues from the previous end (its first point)
        pts = np.vstack([out.points, p.points[1:]])
        out = VectorPath(pts, np.concatenate([out.is_mark, p.is_mark]))
    return out
