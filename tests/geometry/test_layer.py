"""Layer: nesting depth, orientation, tours, closure checks; the drawing loader."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.geometry.layer import Layer, Skipped
from microfab.geometry.load import load_drawing
from microfab.geometry.path import Path
from microfab.geometry.shapes import circle, rectangle, square


def _nested() -> Layer:
    outer = square(0.04)  # CCW
    hole = circle(0.01)  # CCW, must turn CW
    island = square(0.004).reversed()  # CW, must turn CCW
    side = circle(0.002, center=(0.05, 0.0))
    return Layer((hole, outer, island, side))


def test_depth_and_orientation() -> None:
    layer = _nested()
    assert layer.depth == (1, 0, 2, 0)
    ori = layer.oriented()
    assert [c.orientation for c in ori] == ["cw", "ccw", "ccw", "ccw"]
    # lengths are unchanged by reorientation
    assert [c.length for c in ori] == pytest.approx([c.length for c in layer])


def test_open_contours_and_require_closed() -> None:
    line = Path.polyline([[0, 0], [0.01, 0.0]])
    layer = Layer((square(0.01), line), skipped=(Skipped("TEXT", "not geometry", "1A"),))
    assert layer.depth == (0, -1)
    assert layer.open == (line,)
    with pytest.raises(ValueError, match=r"1 contour\(s\) are open .* #1 \(gap 0\.01 m\)"):
        layer.require_closed()
    assert layer.summary()["skipped"] == [{"kind": "TEXT", "ref": "1A", "reason": "not geometry"}]
    with pytest.raises(ValueError, match="no contours"):
        Layer(()).require_closed()


def test_tour_joins_contours_with_jumps() -> None:
    a = square(0.01)
    b = circle(0.002, center=(0.02, 0.0))
    path, marks = Layer((a, b)).tour()
    jump = np.hypot(*(b.start - a.end))
    assert path.length == pytest.approx(a.length + jump + b.length)
    expected = [0.0, a.length, a.length + jump, a.length + jump + b.length]
    assert np.ravel(marks) == pytest.approx(expected)
    assert not path.closed


def test_layer_transforms_and_bbox() -> None:
    layer = Layer((rectangle(0.02, 0.01),))
    assert layer.bbox == pytest.approx((-0.01, -0.005, 0.01, 0.005), abs=1e-9)
    assert layer.scaled(2).bbox == pytest.approx((-0.02, -0.01, 0.02, 0.01), abs=1e-9)
    assert layer.translated((1, 0)).bbox[0] == pytest.approx(0.99)


def test_load_drawing_shapes_and_errors(tmp_path) -> None:
    assert load_drawing("circle:radius=0.01")[0].length == pytest.approx(2 * np.pi * 0.01)
    with pytest.raises(ValueError, match="empty"):
        load_drawing("  ")
    with pytest.raises(ValueError, match="cannot tell what"):
        load_drawing("part.step")
    with pytest.raises(FileNotFoundError, match="not found"):
        load_drawing(str(tmp_path / "part.dxf"))


def test_require_extent_refuses_empty_absurd_and_tiny_layers() -> None:
    with pytest.raises(ValueError, match="no contours"):
        Layer((), (Skipped("TEXT", "text"),), source="t.svg").require_extent()
    with pytest.raises(ValueError, match=r"big: contour #1 has coordinates up to 2e\+03 m"):
        Layer((circle(0.01), circle(1.0, center=(2e3, 0.0))), source="big").require_extent()
    with pytest.raises(ValueError, match="shorter than 1e-09 m"):
        Layer((square(1e-12),), source="tiny").require_extent()
    ok = Layer((circle(0.01),))
    assert ok.require_extent() is ok


def test_require_extent_only_checks_the_named_contours() -> None:
    far = Layer((circle(0.01), circle(1.0, center=(2e3, 0.0)), square(1e-12)), source="f")
    assert far.require_extent(only=[0]) is far  # a reader vouches for the others
    assert far.require_extent(only=()) is far
    with pytest.raises(ValueError, match=r"f: contour #1 has coordinates up to 2e\+03 m"):
        far.require_extent(only=[2, 1])  # the lowest index first, as a full check
    with pytest.raises(ValueError, match=r"f: contour #2 is 4e-12 m long"):
        far.require_extent(only=[2])
    with pytest.raises(ValueError, match="no contours"):
        Layer(()).require_extent(only=())


@pytest.mark.parametrize(
    "spec, match",
    [
        ("circle:radius=1e300", "within ±1000 m|does not close"),
        ("polygon:n_sides=3,radius=1e300", "within ±1000 m"),
        ("square:side=1e-12", "shorter than"),
    ],
)
def test_load_drawing_refuses_absurd_sizes(spec: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        load_drawing(spec)


def test_load_drawing_refuses_a_tiny_airfoil() -> None:
    # a chord of 8e-122 m took minutes to draw (every derivative underflowed)
    with pytest.raises(ValueError, match="shorter than"):
        load_drawing("airfoil:e344", chord=8e-122)
