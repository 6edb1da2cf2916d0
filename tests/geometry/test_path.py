"""Path, segments and parametric shapes: arc length, closure, derivatives, transforms."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.geometry.path import MAX_FLATTEN, Path, concatenate
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment
from microfab.geometry.shapes import (
    butterfly,
    circle,
    ellipse,
    lissajous,
    parse_shape,
    rectangle,
    regular_polygon,
    spiral,
    spiral_length,
    square,
)

SEEDED = settings(derandomize=True, max_examples=40, deadline=None)
sizes = st.floats(1e-5, 1.0)


def _numeric_derivs(path: Path, s: np.ndarray, h: float) -> list[np.ndarray]:
    out = []
    for k in range(3):
        fp = path.evaluate(s + h, k)[k]
        fm = path.evaluate(s - h, k)[k]
        out.append((fp - fm) / (2 * h))
    return out


# --------------------------------------------------------------------- arc length
@SEEDED
@given(r=sizes)
def test_circle_length_and_area(r: float) -> None:
    c = circle(r)
    assert c.length == pytest.approx(2 * np.pi * r, rel=1e-12)
    assert c.signed_area == pytest.approx(np.pi * r * r, rel=1e-9)
    assert c.orientation == "ccw"


@SEEDED
@given(w=sizes, h=sizes, frac=st.floats(0.0, 0.5))
def test_rectangle_length(w: float, h: float, frac: float) -> None:
    r = frac * min(w, h)
    p = rectangle(w, h, corner_radius=r)
    assert p.length == pytest.approx(2 * (w + h) - 8 * r + 2 * np.pi * r, rel=1e-9)
    assert p.signed_area == pytest.approx(w * h - (4 - np.pi) * r * r, rel=1e-9)
    assert np.allclose(p.start, p.end, rtol=0, atol=1e-12 * (w + h))


@SEEDED
@given(b=st.floats(1e-4, 0.1), th0=st.floats(0.0, 3.0), span=st.floats(0.5, 30.0))
def test_spiral_length_matches_closed_form(b: float, th0: float, span: float) -> None:
    p = spiral(b, th0, th0 + span)
    assert p.length == pytest.approx(spiral_length(b, th0, th0 + span), rel=1e-6)


def test_seed002_spiral_default() -> None:
    # seed 002 Fig. 1: b = 50/(2π) mm/rad, θ ∈ [0, 4π]
    p = spiral()
    exact = spiral_length(50e-3 / (2 * np.pi), 0.0, 4 * np.pi)
    assert p.length == pytest.approx(exact, rel=1e-10)
    assert np.allclose(p.end, [100e-3, 0.0], atol=1e-12)


def test_ellipse_length() -> None:
    from scipy.special import ellipe

    p = ellipse(0.02, 0.01)
    assert p.length == pytest.approx(4 * 0.02 * ellipe(1 - 0.25), rel=1e-10)


@SEEDED
@given(n=st.integers(3, 40), r=sizes)
def test_polygon_length(n: int, r: float) -> None:
    p = regular_polygon(n, r)
    assert p.length == pytest.approx(2 * n * r * np.sin(np.pi / n), rel=1e-12)
    assert len(p.corners()) == n


# --------------------------------------------------------------------- closure, monotone s
@pytest.mark.parametrize(
    "path",
    [
        circle(0.01),
        square(0.01),
        rectangle(0.02, 0.01, corner_radius=0.003),
        ellipse(0.02, 0.005),
        lissajous(),
        butterfly(),
        regular_polygon(7, 0.01),
    ],
    ids=["circle", "square", "rounded", "ellipse", "lissajous", "butterfly", "heptagon"],
)
def test_closed_shapes_close_and_s_is_monotone(path: Path) -> None:
    assert path.closed
    scale = max(np.ptp(path.flatten(), axis=0))
    assert np.hypot(*(path.start - path.end)) <= 1e-9 * scale
    assert np.all(np.diff(path.breaks) > 0)
    # points equally spaced in s are (nearly) equally spaced in space on a fine grid
    pts = path.resample(n=4000)
    chord = np.hypot(*np.diff(np.vstack([pts, pts[:1]]), axis=0).T)
    assert chord.sum() == pytest.approx(path.length, rel=1e-3)
    assert np.all(chord <= path.length / 4000 * (1 + 1e-9))
    # evaluation wraps on closed paths
    quarter = 0.25 * path.length
    assert np.allclose(path.point([path.length + quarter]), path.point([quarter]))


@SEEDED
@given(s=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=30))
def test_arc_length_parameter_is_unit_speed(s: list[float]) -> None:
    p = spiral(0.005, 0.0, 6 * np.pi)
    sv = np.sort(np.array(s)) * p.length
    d1 = p.tangent(sv)
    assert np.allclose(np.linalg.norm(d1, axis=1), 1.0, atol=1e-10)
    # distance between points never exceeds the arc length between them
    q = p.point(sv)
    assert np.all(np.hypot(*np.diff(q, axis=0).T) <= np.diff(sv) * (1 + 1e-9) + 1e-15)


# --------------------------------------------------------------------- derivatives
@pytest.mark.parametrize(
    "path",
    [spiral(0.005, 0.5, 8.0), ellipse(0.02, 0.01), rectangle(0.02, 0.01, corner_radius=0.004)],
    ids=["spiral", "ellipse", "rounded-rect"],
)
def test_arc_length_derivatives_match_finite_differences(path: Path) -> None:
    rng = np.random.default_rng(0)
    # keep away from segment junctions, where one-sided derivatives differ
    s = rng.uniform(0.02, 0.98, 20) * path.length
    j = path.junctions()
    if j.size:
        s = s[np.min(np.abs(s[:, None] - j[None, :]), axis=1) > 1e-4 * path.length]
    h = 1e-6 * path.length
    exact = path.evaluate(s, 3)
    num = _numeric_derivs(path, s, h)
    for k in range(3):
        scale = np.max(np.abs(exact[k + 1])) + 1e-300
        assert np.max(np.abs(num[k] - exact[k + 1])) <= 1e-5 * scale


def test_curvature_of_circle_and_line() -> None:
    r = 0.0123
    c = circle(r)
    assert np.allclose(c.curvature(np.linspace(0, c.length, 11)), 1 / r, rtol=1e-12)
    assert np.allclose(c.reversed().curvature([0.1 * c.length]), -1 / r, rtol=1e-12)
    line = Path((LineSegment([0, 0], [1, 1]),))
    assert np.allclose(line.curvature([0.3]), 0.0)
    _, d1, d2, d3 = line.evaluate([0.3], 3)
    assert np.allclose(d1, [[2**-0.5, 2**-0.5]]) and not d2.any() and not d3.any()


def test_normal_points_left_of_travel() -> None:
    c = circle(1.0)
    s = np.linspace(0, c.length, 9)[:-1]
    # for a counter-clockwise circle the left normal points to the centre
    assert np.allclose(c.normal(s), -c.point(s), atol=1e-12)


# --------------------------------------------------------------------- structure
def test_corners_and_junctions() -> None:
    sq = square(0.01)
    assert sq.corners() == pytest.approx([0.005, 0.015, 0.025, 0.035])
    rr = rectangle(0.02, 0.01, corner_radius=0.002)
    assert rr.corners().size == 0
    assert rr.junctions().size == len(rr.segments)
    poly = Path.polyline([[0, 0], [1, 0], [1, 1]])
    assert poly.corners() == pytest.approx([1.0])


def test_gap_is_refused_and_open_path_must_close_when_asked() -> None:
    with pytest.raises(ValueError, match=r"starts .* away"):
        Path((LineSegment([0, 0], [1, 0]), LineSegment([1.1, 0], [2, 0])))
    with pytest.raises(ValueError, match="does not close"):
        Path((LineSegment([0, 0], [1, 0]), LineSegment([1, 0], [1, 1])), closed=True)
    with pytest.raises(ValueError, match="at least one segment"):
        Path(())


def test_transforms_preserve_length_and_flip_orientation_on_mirror() -> None:
    p = rectangle(0.02, 0.01, corner_radius=0.003)
    rot = p.rotated(0.7, origin=(0.01, 0.0))
    assert rot.length == pytest.approx(p.length, rel=1e-12)
    assert rot.signed_area == pytest.approx(p.signed_area, rel=1e-12)
    mir = p.transformed([[-1, 0], [0, 1]])
    assert mir.signed_area == pytest.approx(-p.signed_area, rel=1e-12)
    big = p.scaled(3.0)
    assert big.length == pytest.approx(3 * p.length, rel=1e-12)
    # a non-uniform scale turns arcs into elliptic curves, area scales by det
    stretched = circle(1.0).transformed([[2.0, 0.0], [0.0, 1.0]])
    assert stretched.signed_area == pytest.approx(2 * np.pi, rel=1e-10)
    assert isinstance(stretched.segments[0], CurveSegment)


def test_reverse_and_restart() -> None:
    p = rectangle(0.02, 0.01, corner_radius=0.003)
    r = p.reversed()
    assert r.length == pytest.approx(p.length, rel=1e-12)
    assert np.allclose(r.point([0.3 * p.length]), p.point([0.7 * p.length]), atol=1e-14)
    q = p.with_start(0.37 * p.length)
    assert q.length == pytest.approx(p.length, rel=1e-12)
    assert np.allclose(q.start, p.point([0.37 * p.length])[0], atol=1e-14)
    # restarting inside a curve segment splits it exactly
    sp = ellipse(0.02, 0.01).with_start(0.123)
    assert sp.length == pytest.approx(ellipse(0.02, 0.01).length, rel=1e-10)


def test_bezier_conversion_is_exact() -> None:
    ctrl = np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 2.0], [4.0, 0.0]])
    seg = CurveSegment.from_bezier(ctrl)
    u = np.linspace(0, 1, 11)[:, None]
    bern = np.hstack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u**2 * (1 - u), u**3])
    assert np.allclose(seg.point(u.ravel()), bern @ ctrl, atol=1e-13)
    dense = seg.point(np.linspace(0, 1, 200001))
    assert seg.length == pytest.approx(np.hypot(*np.diff(dense, axis=0).T).sum(), rel=1e-9)


def test_bulge_arc() -> None:
    a = ArcSegment.from_bulge([0, 0], [2, 0], 1.0)  # a CCW half circle below the chord
    assert a.radius == pytest.approx(1.0) and a.sweep == pytest.approx(np.pi)
    assert np.allclose(a.end, [2, 0], atol=1e-15)
    mid = Path((a,)).point([a.length / 2])[0]
    assert mid == pytest.approx([1.0, -1.0])
    with pytest.raises(ValueError):
        ArcSegment.from_bulge([0, 0], [0, 0], 0.5)


def test_flatten_tolerance_and_bbox() -> None:
    c = circle(0.01)
    for tol in (1e-4, 1e-6):
        pts = c.flatten(tol)
        mid = 0.5 * (pts[1:] + pts[:-1])
        assert np.max(0.01 - np.hypot(*mid.T)) <= tol * 1.0001
    # documented accuracy: 1e-6 of the size (0.02 m)
    assert c.bbox == pytest.approx((-0.01, -0.01, 0.01, 0.01), abs=2e-8)
    assert square(0.02).summary()["length_m"] == pytest.approx(0.08)


def test_concatenate_and_polyline() -> None:
    a = Path.polyline([[0, 0], [1, 0]])
    b = Path.polyline([[1, 0], [1, 1], [0, 0]])
    p = concatenate([a, b], closed=True)
    assert p.closed and p.length == pytest.approx(2 + 2**0.5)
    with pytest.raises(ValueError, match="finite"):
        Path.polyline([[0, 0]])


def test_parse_shape() -> None:
    assert parse_shape("square:side=0.01").length == pytest.approx(0.04)
    assert parse_shape("polygon:n_sides=6,radius=0.01").corners().size == 6
    with pytest.raises(ValueError, match="unknown shape"):
        parse_shape("blob")
    with pytest.raises(ValueError, match="not a number"):
        parse_shape("circle:radius=big")
    with pytest.raises(ValueError, match="bad arguments"):
        parse_shape("circle:diameter=1")
    with pytest.raises(ValueError, match="positive"):
        parse_shape("circle:radius=-1")


def test_vectorised_evaluation_of_many_segments_is_consistent() -> None:
    rng = np.random.default_rng(1)
    pts = np.cumsum(rng.normal(size=(3000, 2)), axis=0)
    p = Path.polyline(pts)
    s = np.sort(rng.uniform(0, p.length, 5000))
    q = p.point(s)
    seg = np.searchsorted(p.breaks, s, side="right") - 1
    frac = (s - p.breaks[seg]) / np.diff(p.breaks)[seg]
    assert np.allclose(q, pts[seg] + frac[:, None] * (pts[seg + 1] - pts[seg]), atol=1e-9)


def test_bulge_that_is_not_an_arc_is_refused() -> None:
    with pytest.raises(ValueError, match="radius overflows"):
        ArcSegment.from_bulge([0, 0], [2, 0], 1e-320)
    with pytest.raises(ValueError, match="finite"):
        ArcSegment.from_bulge([0, 0], [2, 0], float("nan"))


def test_arc_start_angle_must_be_finite() -> None:
    with pytest.raises(ValueError, match="theta0"):
        ArcSegment([0, 0], 1.0, float("inf"), 1.0)


@pytest.mark.filterwarnings("error")
def test_transform_that_overflows_is_refused_without_warnings() -> None:
    for seg in (LineSegment([0, 0], [2, 2]), ArcSegment([0, 0], 1.0, 0.0, 1.0)):
        with pytest.raises(ValueError, match="overflows"):
            seg.transformed(np.diag([1e308, 1e308]))


@pytest.mark.filterwarnings("error")
def test_flatten_of_a_cusp_is_bounded_and_quiet() -> None:
    # out and back along the same line: the curvature at the tip is unbounded (was a
    # MemoryError: 1e17 vertices asked for)
    ctrl = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]])
    cusp = Path((CurveSegment.from_bezier(ctrl),))
    pts = cusp.flatten(1e-9)
    assert 2 < len(pts) <= MAX_FLATTEN + 1
    assert np.all(np.isfinite(pts))
