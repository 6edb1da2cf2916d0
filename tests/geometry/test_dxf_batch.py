"""The DXF reader's batch: polylines held as numbers, pending bulged ones, refusals in place."""

from __future__ import annotations

import ezdxf
import numpy as np
import pytest

import microfab.geometry.dxf_batch as batch_module
from microfab.geometry.dxf import read_dxf
from microfab.geometry.dxf_batch import SegmentBatch, extent
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment

MM = 1e-3


def _drawing(tmp_path):
    """Bulged polylines, good and bad, between entities that are skipped at once."""
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    msp = doc.modelspace()
    handles = {}
    handles["text"] = msp.add_text("a").dxf.handle
    # a bulge of 1e-9 over a 5 mm chord: an arc of radius 1.25e6 m, too far
    handles["far"] = msp.add_lwpolyline(
        [(0, 0, 0.5), (5, 0, 1e-9), (5, 5, 0)], format="xyb"
    ).dxf.handle
    handles["good"] = msp.add_lwpolyline(
        [(10, 0, 0.4), (11, 0, 0), (11, 1, -0.3), (10, 1, 0)], format="xyb", close=True
    ).dxf.handle
    handles["point"] = msp.add_point((1, 1)).dxf.handle
    # ±inf bulge: not a finite arc
    handles["inf"] = msp.add_lwpolyline(
        [(20, 0, 0.2), (21, 0, float("inf")), (21, 1, 0)], format="xyb"
    ).dxf.handle
    msp.add_line((30, 0), (31, 0))
    handles["beyond"] = msp.add_lwpolyline([(0, 0, 0.3), (2e6, 0, 0)], format="xyb").dxf.handle
    p = tmp_path / "b.dxf"
    doc.saveas(p)
    return p, handles


def _same(a: object, b: object) -> bool:
    """The same segment to the bit."""
    if type(a) is not type(b):
        return False
    fields = {LineSegment: ("p0", "p1"), ArcSegment: ("center", "radius", "theta0", "sweep")}
    names = fields.get(type(a), ("coef",))  # type: ignore[arg-type]
    return all(np.array_equal(getattr(a, n), getattr(b, n)) for n in names)


def test_bulged_polylines_are_refused_in_drawing_order_with_their_reasons(tmp_path) -> None:
    p, h = _drawing(tmp_path)
    layer = read_dxf(p)
    assert [(s.kind, s.ref) for s in layer.skipped] == [
        ("TEXT", h["text"]),
        ("LWPOLYLINE", h["far"]),
        ("POINT", h["point"]),
        ("LWPOLYLINE", h["inf"]),
        ("LWPOLYLINE", h["beyond"]),
    ]
    reasons = [s.reason for s in layer.skipped]
    assert "reaches 2.5e+06 m, beyond ±1000 m" in reasons[1]
    assert reasons[3] == "invalid geometry: a bulge must be finite, got inf"
    assert "reaches 3.33e+03 m" in reasons[4]  # a vertex beyond: made one by one, refused
    good, line = layer.contours
    assert good.closed and not line.closed
    # the good polyline's arcs are those ArcSegment.from_bulge makes, to the bit
    arc0 = ArcSegment.from_bulge((10 * MM, 0.0), (11 * MM, 0.0), 0.4)
    assert _same(good.segments[0], arc0)
    assert isinstance(good.segments[1], LineSegment)
    np.testing.assert_array_equal(good.segments[1].p1, (11 * MM, 1 * MM))


def test_pending_polylines_made_one_by_one_give_the_same_layer(tmp_path, monkeypatch) -> None:
    p, _ = _drawing(tmp_path)
    fast = read_dxf(p)
    numbers = batch_module.bulge_arc_numbers

    def none_ok(*args: np.ndarray) -> tuple[np.ndarray, ...]:
        *rest, ok = numbers(*args)
        return (*rest, np.zeros_like(ok))

    # every pending polyline is remade one segment at a time: accepted or refused as before
    monkeypatch.setattr(batch_module, "bulge_arc_numbers", none_ok)
    slow = read_dxf(p)
    assert slow.skipped == fast.skipped
    assert len(slow) == len(fast)
    for a, b in zip(slow, fast, strict=True):
        assert a.closed == b.closed and len(a) == len(b)
        assert all(_same(s, t) for s, t in zip(a.segments, b.segments, strict=True))


def test_add_polyline_holds_in_bounds_edges_only() -> None:
    b = SegmentBatch()
    assert b.add_polyline([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], [0.0, 0.5, 0.0], False, 1e-3)
    assert b.slots == [None, batch_module.ARC]
    assert b.lines == [0.0, 0.0, 1e-3, 0.0] and b.arcs == [1e-3, 0.0, 1e-3, 1e-3, 0.5]
    assert b.add_polyline([(0.0, 0.0), (0.0, 0.0)], [0.0, 0.0], True, 1.0) is None  # no edge
    assert b.add_polyline([(0.0, 0.0), (2e3, 0.0)], [0.0, 0.0], False, 1.0) is None  # beyond
    assert b.add_polyline([(0.0, np.nan), (1.0, 0.0)], [0.0, 0.0], False, 1.0) is None
    assert b.add_polyline([(5.0, 5.0), (6.0, 5.0)], [1e-12, 0.0], True, 1.0) is False
    assert len(b.slots) == 4  # the closed two-vertex polyline: there and back


def test_extent_holds_arcs_circles_and_curves() -> None:
    arc = ArcSegment((0.0, 0.0), 1.0, 0.0, np.pi / 2)  # (1, 0) to (0, 1)
    ends = np.array([arc.start]), np.array([arc.end])
    assert extent([], *ends) == pytest.approx(1.0)  # the ends only
    assert extent([arc], *ends) == pytest.approx(2.0)  # the arc's circle: -1 .. 1
    curve = CurveSegment.from_bezier([(0.0, 0.0), (1.0, 4.0), (2.0, 0.0)])  # up to y = 2
    ends = np.array([curve.start]), np.array([curve.end])
    assert extent([curve], *ends) == pytest.approx(2.0)  # its midpoint: y = 2
