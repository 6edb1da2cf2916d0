"""Foot-point projection onto a Path: the exact, signed contour error (geometry/project.py)."""

from __future__ import annotations

import gc
import itertools
import math
import pathlib
import weakref

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import microfab.geometry.project as project_module
from microfab.geometry.dxf import read_dxf
from microfab.geometry.path import Path
from microfab.geometry.project import Projection, project_points, project_points_scalar
from microfab.geometry.project_index import PathIndex
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment, Segment
from microfab.geometry.shapes import circle, ellipse, rectangle, regular_polygon, square

SEEDED = settings(derandomize=True, max_examples=25, deadline=None)
UM = 1e-6


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# --------------------------------------------------------------------- circles
@pytest.mark.parametrize("ccw", [True, False])
def test_circle_distance_foot_and_arc_length_are_the_closed_forms(ccw: bool) -> None:
    R, c, th0 = 100 * UM, np.array([3 * UM, -2 * UM]), 0.3
    path = circle(R, center=tuple(c), theta0=th0)
    if not ccw:
        path = path.reversed()
    rng = _rng(1)
    rho = rng.uniform(0.1, 2.0, 300) * R
    phi = rng.uniform(-np.pi, np.pi, 300)
    u = np.column_stack([np.cos(phi), np.sin(phi)])
    p = c + rho[:, None] * u
    proj = project_points(path, p)
    # positive to the left of travel: inside for the counter-clockwise circle
    expect = (R - rho) if ccw else (rho - R)
    assert np.allclose(proj.distance, expect, rtol=0, atol=1e-19)
    assert np.allclose(proj.foot, c + R * u, rtol=0, atol=1e-18)
    turn = np.mod(phi - th0, 2 * np.pi) if ccw else np.mod(th0 - phi, 2 * np.pi)
    assert np.allclose(proj.s, R * turn, rtol=0, atol=1e-15)
    sign = 1.0 if ccw else -1.0
    assert np.allclose(proj.tangent, sign * np.column_stack([-u[:, 1], u[:, 0]]), atol=1e-14)
    assert np.allclose(proj.normal, -sign * u, atol=1e-14)
    assert np.all(proj.segment == 0)


def test_circle_centre_is_a_radius_away() -> None:
    # every point of the circle is nearest: any foot will do, the distance is R
    R, c = 100 * UM, (5 * UM, 7 * UM)
    proj = project_points(circle(R, center=c), [c, c])
    assert np.allclose(proj.distance, R, rtol=1e-15, atol=0)
    assert np.allclose(np.hypot(*(proj.foot - np.array(c)).T), R, rtol=1e-15)


def test_centre_of_a_polynomial_circle_is_a_radius_away() -> None:
    # a circle held as a Chebyshev curve: the distance is flat along the whole curve,
    # where only the interpolated-polynomial bound settles the search
    R = 100 * UM
    path = ellipse(R, R)
    assert isinstance(path.segments[0], CurveSegment)
    p = np.array([[0.0, 0.0], [1e-11, -1e-11], [3e-9, 2e-9]])
    proj = project_points(path, p)
    # the nearest point is straight out through p: at R minus p's offset
    assert np.allclose(proj.distance, R - np.hypot(*p.T), rtol=0, atol=1e-13)
    assert np.allclose(np.hypot(*proj.foot.T), R, rtol=0, atol=1e-13)


# --------------------------------------------------------------------- corners
def test_rectangle_corner_region_projects_to_the_vertex() -> None:
    a = 100 * UM
    path = square(2 * a)  # counter-clockwise, corners at (±a, ±a)
    rng = _rng(2)
    off = rng.uniform(0.01, 20.0, (200, 2)) * UM
    signs = rng.choice([-1.0, 1.0], (200, 2))
    corner = signs * a
    p = corner + signs * off  # beyond both edges of the corner: the vertex is nearest
    proj = project_points(path, p)
    assert np.allclose(proj.foot, corner, rtol=0, atol=1e-20)
    # off is exact up to the rounding of p = corner + off (1e-4 m: ulp 1.4e-20 m)
    assert np.allclose(proj.distance, -np.hypot(*off.T), rtol=0, atol=1e-19)  # outside
    # inside, near a corner: the nearer edge, at the perpendicular distance
    q = corner - signs * off
    proj = project_points(path, q)
    assert np.allclose(proj.distance, off.min(axis=1), rtol=1e-12, atol=1e-21)


def test_sharp_corner_side_uses_both_normals() -> None:
    # a counter-clockwise triangle with a 169° turn at (L, 0): beyond the tip the point is
    # outside, although the incoming edge's own normal points towards it
    L = 100 * UM
    tri = Path.polyline([[0.0, 0.0], [L, 0.0], [0.0, 0.2 * L]], closed=True)
    tip = np.array([L, 0.0])
    p = tip + np.array([[0.5, 0.3], [0.2, 0.05], [1.0, 0.001]]) * L
    proj = project_points(tri, p)
    assert np.allclose(proj.foot, tip, atol=1e-21)
    assert np.all(proj.distance < 0.0)
    assert np.allclose(-proj.distance, np.hypot(*(p - tip).T), rtol=1e-15)
    inside = np.array([[0.9 * L, 0.01 * L], [0.1 * L, 0.1 * L]])
    assert np.all(project_points(tri, inside).distance > 0.0)


# --------------------------------------------------------------------- polylines
def _brute_polyline(v: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|distance| and arc length by a different route: every edge, a loop over edges."""
    best = np.full(p.shape[0], np.inf)
    s_best = np.zeros(p.shape[0])
    s0 = 0.0
    for a, b in itertools.pairwise(v):
        d = b - a
        L = float(np.hypot(*d))
        t = np.clip(((p - a) @ d) / (L * L), 0.0, 1.0)
        dist = np.hypot(*(p - (a + t[:, None] * d)).T)
        better = dist < best
        best[better], s_best[better] = dist[better], s0 + t[better] * L
        s0 += L
    return best, s_best


@pytest.mark.parametrize("n_vertices", [5, 60, 400])
def test_polyline_matches_every_edge_brute_force(n_vertices: int) -> None:
    rng = _rng(n_vertices)
    v = np.cumsum(rng.normal(0.0, 10 * UM, (n_vertices, 2)), axis=0)
    path = Path.polyline(v)
    p = v[rng.integers(0, n_vertices, 500)] + rng.normal(0.0, 5 * UM, (500, 2))
    proj = project_points(path, p)
    dist, s = _brute_polyline(v, p)
    assert np.allclose(np.abs(proj.distance), dist, rtol=1e-12, atol=1e-20)
    assert np.allclose(np.hypot(*(p - proj.foot).T), dist, rtol=1e-12, atol=1e-20)
    assert np.allclose(path.point(proj.s), proj.foot, rtol=0, atol=1e-16)
    # arc lengths agree except where two edges tie (a vertex reached from both sides)
    assert np.mean(np.isclose(proj.s, s, rtol=0, atol=1e-15)) > 0.95


def test_open_path_ends() -> None:
    L = 50 * UM
    path = Path.polyline([[0.0, 0.0], [L, 0.0], [L, L]])
    p = np.array([[-3 * UM, 0.0], [-2 * UM, 1 * UM], [L, L + 4 * UM], [L + 1 * UM, L + 1 * UM]])
    proj = project_points(path, p)
    assert np.array_equal(proj.s, [0.0, 0.0, 2 * L, 2 * L])
    assert np.allclose(proj.foot, [[0, 0], [0, 0], [L, L], [L, L]], atol=0)
    assert np.allclose(np.abs(proj.distance), np.hypot(*(p - proj.foot).T), rtol=1e-15)
    # straight ahead of an end: positive; beside it, the end's own normal decides
    assert proj.distance[0] > 0 and proj.distance[2] > 0
    assert proj.distance[1] > 0 and proj.distance[3] < 0


# --------------------------------------------------------------------- arcs
@pytest.mark.parametrize("sweep", [2.0, -2.0, 5.5, -5.5])
def test_arcs_in_both_directions(sweep: float) -> None:
    c, r, th0 = np.array([10 * UM, -5 * UM]), 40 * UM, 0.7
    arc = ArcSegment(c, r, th0, sweep)
    path = Path((arc,))
    rng = _rng(3)
    rho = rng.uniform(0.0, 2.5, 400) * r
    phi = rng.uniform(-np.pi, np.pi, 400)
    p = c + rho[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
    proj = project_points(path, p)
    turn = np.mod(np.sign(sweep) * (phi - th0), 2 * np.pi)
    inside = turn <= abs(sweep)
    d_ends = np.minimum(np.hypot(*(p - arc.start).T), np.hypot(*(p - arc.end).T))
    expect = np.where(inside, np.abs(rho - r), d_ends)
    assert np.allclose(np.abs(proj.distance), expect, rtol=1e-13, atol=1e-20)
    s_in = np.where(inside, r * turn, np.nan)
    assert np.allclose(proj.s[inside], s_in[inside], rtol=0, atol=1e-15)
    assert np.all(np.isin(proj.s[~inside], [0.0, arc.length]))
    # left of travel: inside the circle for a counter-clockwise arc
    left = (rho < r) if sweep > 0 else (rho > r)
    sel = inside & (np.abs(rho - r) > 1e-3 * r)
    assert np.array_equal(proj.distance[sel] > 0, left[sel])


# --------------------------------------------------------------------- curves
@pytest.mark.parametrize(
    "ctrl",
    [
        [[0, 0], [30, 60], [70, -40], [100, 0]],  # an S: an inflection
        [[0, 0], [100, 0], [0, 50]],  # a tight parabola
        [[0, 0], [120, 80], [-20, 80], [100, 0]],  # a loop
        [[0, 0], [0, 0], [50, 50], [100, 0]],  # starts with zero speed
    ],
)
def test_bezier_matches_the_scalar_reference(ctrl: list[list[float]]) -> None:
    curve = CurveSegment.from_bezier(np.array(ctrl, dtype=float) * UM)
    path = Path((curve,))
    p = _rng(4).uniform(-40, 140, (40, 2)) * UM
    proj = project_points(path, p)
    ref = project_points_scalar(path, p)
    assert np.allclose(proj.distance, ref.distance, rtol=0, atol=1e-10 * UM)
    assert np.all(np.abs(proj.distance) <= np.abs(ref.distance) + 1e-13)
    assert np.allclose(path.point(proj.s), proj.foot, rtol=0, atol=1e-12 * UM)
    assert np.allclose(np.hypot(*(p - proj.foot).T), np.abs(proj.distance), rtol=1e-13)


# --------------------------------------------------------------------- mixed paths
def _slot_with_spline() -> Path:
    """A DXF-like closed contour, counter-clockwise: lines, bulge arcs and a spline."""
    P = np.array([[0, 0], [100, 0], [100, 40], [60, 40], [0, 40]], dtype=float) * UM
    ctrl = np.array([[60, 40], [40, 80], [20, 0], [0, 40]], dtype=float) * UM
    segs: list[Segment] = [
        LineSegment(P[0], P[1]),
        ArcSegment.from_bulge(P[1], P[2], 1.0),  # a half circle bulging outwards
        LineSegment(P[2], P[3]),
        CurveSegment.from_bezier(ctrl),
        ArcSegment.from_bulge(P[4], P[0], 0.4),
    ]
    return Path(tuple(segs), closed=True)


def test_mixed_path_matches_the_scalar_reference() -> None:
    path = _slot_with_spline()
    assert path.orientation == "ccw"
    rng = _rng(5)
    p = np.vstack(
        [
            rng.uniform(-30, 150, (25, 2)) * UM,
            path.point(rng.uniform(0, path.length, 15)) + rng.normal(0, 2 * UM, (15, 2)),
        ]
    )
    proj = project_points(path, p)
    ref = project_points_scalar(path, p)
    assert np.allclose(proj.distance, ref.distance, rtol=0, atol=1e-10 * UM)
    assert np.all(np.abs(proj.distance) <= np.abs(ref.distance) + 1e-18)
    # inside the counter-clockwise contour: positive
    assert project_points(path, [[50 * UM, 20 * UM]]).distance[0] > 0
    assert project_points(path, [[50 * UM, -5 * UM]]).distance[0] < 0


def test_contours_read_from_a_dxf_file(tmp_path: pathlib.Path) -> None:
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4  # mm
    msp = doc.modelspace()
    msp.add_lwpolyline(
        [(0, 0, 0.4), (1, 0, 0), (1, 0.5, -0.3), (0, 0.5, 0)], format="xyb", close=True
    )
    # a slot in loose entities: two lines and two half circles
    msp.add_line((2, 0), (3, 0))
    msp.add_arc((3, 0.25), 0.25, -90, 90)
    msp.add_line((3, 0.5), (2, 0.5))
    msp.add_arc((2, 0.25), 0.25, 90, 270)
    msp.add_open_spline([(4, 0), (4.3, 0.6), (4.6, -0.2), (5, 0.3)], degree=3)
    doc.saveas(tmp_path / "parts.dxf")
    layer = read_dxf(tmp_path / "parts.dxf")
    kinds = {type(seg) for path in layer for seg in path.segments}
    assert kinds == {LineSegment, ArcSegment, CurveSegment}
    rng = _rng(11)
    for path in layer:
        x0, y0, x1, y1 = path.bbox
        p = rng.uniform([x0 - 2e-4, y0 - 2e-4], [x1 + 2e-4, y1 + 2e-4], (12, 2))
        proj = project_points(path, p)
        ref = project_points_scalar(path, p)
        assert np.allclose(proj.distance, ref.distance, rtol=0, atol=1e-13)
        assert np.allclose(path.point(proj.s), proj.foot, rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "make",
    [
        lambda: circle(100 * UM),
        lambda: rectangle(400 * UM, 200 * UM, corner_radius=20 * UM),
        lambda: square(200 * UM),
        _slot_with_spline,
        lambda: regular_polygon(300, 100 * UM),
    ],
)
def test_points_on_the_path_are_at_distance_zero(make: object) -> None:
    path = make()  # type: ignore[operator]
    b = path.breaks
    frac = np.linspace(0.05, 0.95, 7)
    s = (b[:-1, None] + frac[None, :] * np.diff(b)[:, None]).ravel()  # inside the segments
    proj = project_points(path, path.point(s))
    assert np.max(np.abs(proj.distance)) <= 1e-19
    assert np.allclose(proj.s, s, rtol=0, atol=1e-15)
    assert np.allclose(proj.tangent, path.tangent(s), rtol=0, atol=1e-9)


# --------------------------------------------------------------------- hint, grids
def _tracked(path: Path, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = _rng(seed)
    s = np.sort(rng.uniform(0.0, path.length, n))
    return path.point(s) + rng.uniform(-1.0, 1.0, (n, 2)) * UM, s


def _same(a: Projection, b: Projection) -> None:
    for name in ("s", "foot", "tangent", "normal", "distance", "segment"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


@pytest.mark.parametrize(
    "make",
    [
        lambda: regular_polygon(2000, 100 * UM),
        lambda: rectangle(400 * UM, 200 * UM, corner_radius=20 * UM),
        _slot_with_spline,
    ],
)
def test_hint_never_changes_the_result(make: object) -> None:
    path = make()  # type: ignore[operator]
    p, s = _tracked(path, 3000, 6)
    p[::50] += 40 * UM  # some far off the path: they climb the grid levels
    plain = project_points(path, p)
    rng = _rng(7)
    for hint in (s, plain.s, s + rng.normal(0, 20 * UM, s.size), rng.uniform(-1, 2, s.size)):
        _same(project_points(path, p, hint=hint), plain)


def test_candidate_routes_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    # the grids, the sample tree alone, and every segment: the same answer, bit for bit
    p, _ = _tracked(regular_polygon(500, 100 * UM), 2000, 8)
    p[::7] *= 1.5  # and farther out
    walk = np.cumsum(_rng(9).normal(0.0, 10 * UM, (300, 2)), axis=0)  # a tangled polyline
    p = np.vstack([p, _rng(10).uniform(walk.min(axis=0), walk.max(axis=0), (1000, 2))])
    for make in (
        lambda: regular_polygon(500, 100 * UM),
        lambda: Path.polyline(walk),
        _slot_with_spline,
    ):
        with_grids = project_points(make(), p)
        with monkeypatch.context() as mp:
            mp.setattr(PathIndex, "n_levels", lambda self: 0)
            tree = project_points(make(), p)  # a new path: a new index, without grids
            mp.setattr(project_module, "_ALL_SEGMENTS", 10**9)
            every = project_points(make(), p)
        _same(with_grids, tree)
        _same(with_grids, every)


def _bumps() -> Path:
    """60 half circles of 5 µm radius in a row and a spline back, turned by 0.3 rad."""
    x = np.arange(61) * 10 * UM
    segs: list[Segment] = [
        ArcSegment.from_bulge((x[i], 0.0), (x[i + 1], 0.0), 1.0 if i % 2 else -1.0)
        for i in range(60)
    ]
    ctrl = np.array([[x[-1], 0.0], [x[-1], 200 * UM], [0.0, -150 * UM], [0.0, 0.0]])
    segs.append(CurveSegment.from_bezier(ctrl))
    # turned, so that the arcs' quarter pieces bulge out of their chords' boxes
    return Path(tuple(segs), closed=True).rotated(0.3)


def test_grid_lists_every_segment_within_its_radius() -> None:
    # the invariant the grids rest on, checked point by point on dense samples
    path = _bumps()
    idx = PathIndex(path)
    assert idx.usable_levels() >= 2
    for lv in range(idx.usable_levels()):
        g = idx.level(lv)
        listed = np.repeat(g.keys, np.diff(g.offsets)) * idx.n_seg + g.segs
        for k, (s0, s1) in enumerate(itertools.pairwise(path.breaks)):
            q = path.point(np.linspace(s0, s1, 400)[1:-1])  # inside segment k
            # every cell whose square comes within ρ of a sample must list segment k
            ix = np.floor((q[:, 0] - g.x0) / g.cell).astype(int)
            iy = np.floor((q[:, 1] - g.y0) / g.cell).astype(int)
            for dx, dy in itertools.product(range(-2, 3), repeat=2):
                cx, cy = ix + dx, iy + dy
                lo_x, lo_y = g.x0 + cx * g.cell, g.y0 + cy * g.cell
                gap_x = np.maximum(np.maximum(lo_x - q[:, 0], q[:, 0] - lo_x - g.cell), 0.0)
                gap_y = np.maximum(np.maximum(lo_y - q[:, 1], q[:, 1] - lo_y - g.cell), 0.0)
                near = np.hypot(gap_x, gap_y) <= g.radius * (1.0 - 1e-6)
                code = (cx * g.ny + cy)[near] * idx.n_seg + k
                assert np.all(np.isin(code, listed)), (lv, k, dx, dy)


# --------------------------------------------------------------------- checks
def test_bad_arguments_are_refused() -> None:
    path = circle(100 * UM)
    with pytest.raises(ValueError, match=r"shaped \(n, 2\)"):
        project_points(path, [1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        project_points(path, [[0.0, np.nan]])
    with pytest.raises(ValueError, match="overflow"):
        project_points(path, [[0.0, 1e200]])
    with pytest.raises(ValueError, match="hint"):
        project_points(path, [[0.0, 0.0]], hint=[0.0, 1.0])
    with pytest.raises(ValueError, match="hint"):
        project_points(path, [[0.0, 0.0]], hint=[np.inf])
    with pytest.raises(TypeError, match="Path"):
        project_points([[0.0, 0.0], [1.0, 0.0]], [[0.0, 0.0]])  # type: ignore[arg-type]


def test_the_cached_index_does_not_keep_the_path_alive() -> None:
    path = regular_polygon(50, 100 * UM)
    project_points(path, [[0.0, 0.0]])
    ref = weakref.ref(path)
    del path
    gc.collect()
    assert ref() is None


def test_projection_is_read_only_and_empty_input_works() -> None:
    proj = project_points(square(1e-4), [[0.0, 0.0]])
    with pytest.raises(ValueError):
        proj.distance[0] = 1.0
    empty = project_points(square(1e-4), np.zeros((0, 2)))
    assert len(empty) == 0 and empty.foot.shape == (0, 2)


# --------------------------------------------------------------------- properties
@st.composite
def mixed_paths(draw: st.DrawFn) -> Path:
    """Chains of 1-5 lines, bulge arcs and cubic Bézier curves, in µm, open or closed."""
    n = draw(st.integers(1, 5))
    coord = st.floats(-100.0, 100.0)
    pts = [np.array(draw(st.tuples(coord, coord)))]
    segs: list[Segment] = []
    for _ in range(n):
        a = pts[-1]
        b = np.array(draw(st.tuples(coord, coord)))
        if np.hypot(*(b - a)) < 1.0:
            b = a + np.array([5.0, 3.0])
        kind = draw(st.sampled_from(["line", "arc", "bezier"]))
        if kind == "line":
            segs.append(LineSegment(a * UM, b * UM))
        elif kind == "arc":
            bulge = draw(st.floats(0.05, 2.5)) * draw(st.sampled_from([-1.0, 1.0]))
            segs.append(ArcSegment.from_bulge(a * UM, b * UM, bulge))
        else:
            c1, c2 = (np.array(draw(st.tuples(coord, coord))) for _ in range(2))
            segs.append(CurveSegment.from_bezier(np.array([a, c1, c2, b]) * UM))
        pts.append(b)
    closed = n >= 2 and draw(st.booleans())
    if closed:
        segs.append(LineSegment(pts[-1] * UM, pts[0] * UM))
    return Path(tuple(segs), closed=closed)


def _test_points(path: Path, seed: int, n: int) -> np.ndarray:
    rng = _rng(seed)
    x0, y0, x1, y1 = path.bbox
    far = rng.uniform([x0 - 20 * UM, y0 - 20 * UM], [x1 + 20 * UM, y1 + 20 * UM], (n, 2))
    near = path.point(rng.uniform(0, path.length, n)) + rng.normal(0, 3 * UM, (n, 2))
    return np.vstack([far, near])


def _coef_bound(c: np.ndarray) -> float:
    return float(np.hypot(*np.abs(c).sum(axis=0)))


def _dense(path: Path, p: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance to dense samples of the path, and the bound of its excess per point.

    Samples at most ``2 δ`` apart in the segment's parameter (ends included): the foot
    is within ``δ`` of a sample, so the sample is at most ``min(M1 δ, (M1² + d M2) δ² /
    (2d))`` farther than the distance ``d`` (the second form at an inner foot, where
    ``(p − f)·f' = 0``; ``M1``, ``M2`` bound the first two derivatives: 1 and 0 for a line,
    1 and 1/r for an arc in arc length, the coefficient sums for a curve in u).
    """
    samples, consts = [], []
    for seg in path.segments:
        if isinstance(seg, CurveSegment):
            d1, d2, _ = seg.derivative_coefs
            m1, m2 = _coef_bound(d1), _coef_bound(d2)
            n = int(np.ceil(m1 / (2 * delta))) + 1
            samples.append(seg.point(np.linspace(0.0, 1.0, n + 1)))
            consts.append((m1, m2, 0.5 / n))
        else:
            n = int(np.ceil(seg.length / (2 * delta))) + 1
            sub = Path((seg,))
            samples.append(sub.point(np.linspace(0.0, seg.length, n + 1)))
            m2 = 1.0 / seg.radius if isinstance(seg, ArcSegment) else 0.0
            consts.append((1.0, m2, 0.5 * seg.length / n))
    q = np.vstack(samples)
    dense = np.array([np.min(np.hypot(*(q - pi).T)) for pi in p])
    return dense, np.array(consts)


def _excess_bound(consts: np.ndarray, d: np.ndarray) -> np.ndarray:
    m1, m2, h = consts[:, 0][None], consts[:, 1][None], consts[:, 2][None]
    dd = np.maximum(d, 1e-300)[:, None]
    return np.max(np.minimum(m1 * h, (m1 * m1 + dd * m2) * h * h / (2 * dd)), axis=1)


@SEEDED
@given(path=mixed_paths(), seed=st.integers(0, 2**31 - 1))
def test_distance_is_the_minimum_over_a_dense_sampling(path: Path, seed: int) -> None:
    p = _test_points(path, seed, 10)
    proj = project_points(path, p)
    d = np.abs(proj.distance)
    dense, consts = _dense(path, p, 2e-8)
    excess = _excess_bound(consts, d)
    # no sample is nearer than the foot (curves to their 1e-13 m), and the samples come
    # within the bound of it: within 1e-9 m once the point is a micrometre away
    assert np.all(d <= dense + 1e-13)
    assert np.all(dense - d <= excess + 1e-18)
    assert np.all(excess[d >= 1 * UM] <= 1e-9)
    # the foot is on the path at s, and at the distance
    assert np.allclose(path.point(proj.s), proj.foot, rtol=0, atol=1e-15)
    assert np.allclose(np.hypot(*(p - proj.foot).T), d, rtol=1e-12, atol=1e-20)


@settings(derandomize=True, max_examples=15, deadline=None)
@given(path=mixed_paths(), seed=st.integers(0, 2**31 - 1))
def test_distance_equals_the_scalar_reference(path: Path, seed: int) -> None:
    p = _test_points(path, seed, 3)
    proj = project_points(path, p)
    ref = project_points_scalar(path, p)
    assert np.allclose(proj.distance, ref.distance, rtol=0, atol=1e-10 * UM)


@SEEDED
@given(
    path=mixed_paths(),
    seed=st.integers(0, 2**31 - 1),
    angle=st.floats(-math.pi, math.pi),
    shift=st.tuples(st.floats(-1e-3, 1e-3), st.floats(-1e-3, 1e-3)),
)
def test_rigid_motion_moves_the_feet_along(
    path: Path, seed: int, angle: float, shift: tuple[float, float]
) -> None:
    p = _test_points(path, seed, 10)
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s], [s, c]])
    moved = path.rotated(angle).translated(shift)
    a = project_points(path, p)
    b = project_points(moved, p @ R.T + np.array(shift))
    # the coordinates grow to 1 mm: rounding of 1e-19 m, curves to 1e-13 m
    assert np.allclose(a.distance, b.distance, rtol=0, atol=2e-13)
