"""Segment primitives: exact bounding boxes, reach bounds, arcs from bulges in one go."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.geometry.segments import (
    ArcSegment,
    CurveSegment,
    LineSegment,
    bulge_arc_numbers,
    segment_bbox,
    segment_reach,
)


@given(
    ctrl=st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)), min_size=2, max_size=6),
    theta0=st.floats(-7.0, 7.0),
    sweep=st.floats(-6.28, 6.28).filter(lambda s: abs(s) > 1e-3),
)
@settings(max_examples=60, deadline=None)
def test_segment_bbox_is_exact(
    ctrl: list[tuple[float, float]], theta0: float, sweep: float
) -> None:
    # the box from the extremes holds every point and is reached by dense sampling
    curve = CurveSegment.from_bezier(np.array(ctrl))
    arc = ArcSegment(center=(0.3, -0.2), radius=0.7, theta0=theta0, sweep=sweep)
    for seg, pts in (
        (curve, curve.point(np.linspace(0.0, 1.0, 20001))),
        (
            arc,
            arc.center
            + 0.7
            * np.column_stack(
                [
                    np.cos(theta0 + sweep * np.linspace(0, 1, 20001)),
                    np.sin(theta0 + sweep * np.linspace(0, 1, 20001)),
                ]
            ),
        ),
    ):
        box = np.array(segment_bbox(seg))
        dense = np.array([*pts.min(axis=0), *pts.max(axis=0)])
        assert np.all(box[:2] <= dense[:2] + 1e-12) and np.all(box[2:] >= dense[2:] - 1e-12)
        assert np.allclose(box, dense, atol=1e-6)


def test_segment_reach_bounds_coordinates_and_is_inf_when_the_length_overflows() -> None:
    assert segment_reach(LineSegment((1.0, -3.0), (2.0, 0.5))) == 3.0
    assert segment_reach(ArcSegment((-2.0, 1.0), 0.5, 0.3, 1.0)) == 2.5
    curve = CurveSegment(np.array([[1.0, 0.0], [0.5, -2.0], [0.25, 0.0]]))
    assert segment_reach(curve) == 2.0
    assert curve.point(np.linspace(0, 1, 101)).max() <= 2.0
    # far, but of finite length: the reach itself
    assert segment_reach(LineSegment((1e300, 0.0), (1e300, 1.0))) == 1e300
    # the length overflows: inf, whatever the coordinates
    with np.errstate(over="ignore"):
        assert segment_reach(LineSegment((-1e308, 0.0), (1e308, 0.0))) == np.inf
    assert segment_reach(ArcSegment((0.0, 0.0), 1e308, 0.0, 6.0)) == np.inf
    assert segment_reach(CurveSegment(np.array([[0.0, 0.0], [1e308, 0.0]]))) == np.inf


def test_bulge_arc_numbers_are_those_of_from_bulge_to_the_bit() -> None:
    rng = np.random.default_rng(5)
    m = 400
    p0 = rng.normal(size=(m, 2)) * 10.0 ** rng.uniform(-6, 2, size=(m, 1))
    p1 = p0 + rng.normal(size=(m, 2)) * 10.0 ** rng.uniform(-9, 1, size=(m, 1))
    bulge = rng.choice([-1, 1], size=m) * 10.0 ** rng.uniform(-11, 3, size=m)
    bulge[:4] = [1.0, -1.0, 5e-324, np.nan]  # half circles; a radius overflow; not a number
    p1[4] = p0[4]  # no chord
    center, radius, theta0, sweep, ok = bulge_arc_numbers(p0, p1, bulge)
    assert ok.tolist() == [True, True, False, False, False] + [True] * (m - 5)
    arcs = ArcSegment._many_checked(center[ok], radius[ok], theta0[ok], sweep[ok])
    for arc, i in zip(arcs, np.flatnonzero(ok).tolist(), strict=True):
        one = ArcSegment.from_bulge(p0[i], p1[i], bulge[i])
        assert np.array_equal(arc.center, one.center) and not arc.center.flags.writeable
        assert (arc.radius, arc.theta0, arc.sweep) == (one.radius, one.theta0, one.sweep)
        assert all(type(v) is float for v in (arc.radius, arc.theta0, arc.sweep))
    for i in np.flatnonzero(~ok).tolist():
        with pytest.raises(ValueError):
            ArcSegment.from_bulge(p0[i], p1[i], bulge[i])
