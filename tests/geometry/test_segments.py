"""Segment primitives: exact bounding boxes."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.geometry.segments import ArcSegment, CurveSegment, segment_bbox


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
