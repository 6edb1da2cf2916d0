import numpy as np
import pytest
import shapely

from microfab.geometry.hatch import ScanVectors, hatch, layer_polygon
from microfab.geometry.layer import Layer
from microfab.geometry.path import Path
from microfab.geometry.segments import ArcSegment

MM = 1e-3
SIDE = 10 * MM
H = 0.1 * MM


def square(side=SIDE, x0=0.0, y0=0.0):
    return Path.polyline(
        [[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]], closed=True
    )


def circle(c, r):
    return Path((ArcSegment(c, r, 0.0, 2 * np.pi),), closed=True)


def seg_point_dist(marks, p):
    a, b = marks[:, 0], marks[:, 1]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / (ab * ab).sum(1), 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=1)


def test_square_total_length_and_containment():
    sv = hatch(Layer((square(),)), spacing=H)
    assert abs(sv.total_mark_length - SIDE**2 / H) <= SIDE * (1 + 1e-9)
    # 99 interior lines: the two along the top and bottom edges are dropped
    assert len(sv) == 99
    pts = sv.marks.reshape(-1, 2)
    assert np.all(pts >= -1e-15) and np.all(pts <= SIDE + 1e-15)
    np.testing.assert_allclose(sv.mark_lengths, SIDE, rtol=1e-12)


def test_direction_alternates_and_jumps_connect():
    sv = hatch(Layer((square(),)), spacing=H)
    d = sv.marks[:, 1] - sv.marks[:, 0]
    assert np.all((d[:-1] * d[1:]).sum(axis=1) < 0)
    np.testing.assert_array_equal(sv.jumps[:, 0], sv.marks[:-1, 1])
    np.testing.assert_array_equal(sv.jumps[:, 1], sv.marks[1:, 0])
    assert sv.jumps.shape == (len(sv) - 1, 2, 2)
    # meander over a square: every jump is one line spacing
    np.testing.assert_allclose(sv.jump_lengths, H, rtol=1e-9)
    assert sv.total_jump_length == pytest.approx((len(sv) - 1) * H, rel=1e-9)
    # lines are horizontal at angle 0, taken bottom to top
    np.testing.assert_allclose(d[:, 1], 0.0, atol=1e-18)
    assert np.all(np.diff(sv.marks[:, 0, 1]) > 0)


def test_angle_90_swaps_axes():
    a = hatch(Layer((square(),)), spacing=H)
    b = hatch(Layer((square(),)), spacing=H, angle=np.pi / 2)
    d = b.marks[:, 1] - b.marks[:, 0]
    np.testing.assert_allclose(d[:, 0], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.abs(d[:, 1]), SIDE, rtol=1e-9)
    assert len(b) == len(a) == 99  # the lines along the left and right edges are dropped
    assert b.total_mark_length == pytest.approx(a.total_mark_length, rel=1e-9)


def test_oblique_angle():
    ang = np.deg2rad(30)
    sv = hatch(Layer((square(),)), spacing=H, angle=ang)
    d = sv.marks[:, 1] - sv.marks[:, 0]
    u = d / np.linalg.norm(d, axis=1)[:, None]
    np.testing.assert_allclose(np.abs(u @ [np.cos(ang), np.sin(ang)]), 1.0, atol=1e-12)
    assert sv.total_mark_length == pytest.approx(SIDE**2 / H, rel=0.02)


def test_hole_is_not_crossed():
    c, r = np.array([5 * MM, 5 * MM]), 2 * MM
    layer = Layer((square(), circle(c, r)))
    sv = hatch(layer, spacing=H)
    mid = sv.marks.mean(axis=1)
    assert np.all(np.linalg.norm(mid - c, axis=1) > r - 1e-9)
    assert np.all(seg_point_dist(sv.marks, c) >= r * (1 - 1e-3))
    want = (SIDE**2 - np.pi * r**2) / H
    assert sv.total_mark_length == pytest.approx(want, rel=0.03)
    # lines through the hole give two marks, and the jump between them crosses the hole
    assert len(sv) > 99
    assert np.max(sv.jump_lengths) >= 2 * r * 0.9


def test_island_in_hole_is_filled():
    c = np.array([5 * MM, 5 * MM])
    layer = Layer((square(), circle(c, 3 * MM), circle(c, 1 * MM)))
    sv = hatch(layer, spacing=H)
    mid = sv.marks.mean(axis=1)
    rr = np.linalg.norm(mid - c, axis=1)
    assert np.any(rr < 1 * MM)
    assert not np.any(
        (rr > 1 * MM + 1e-9) & (rr < 3 * MM - 1e-9) & (np.abs(mid[:, 1] - c[1]) < 0.5 * MM)
    )
    area = SIDE**2 - np.pi * (9 - 1) * MM**2
    assert layer_polygon(layer, tol=1e-9).area == pytest.approx(area, rel=1e-6)
    assert sv.total_mark_length == pytest.approx(area / H, rel=0.03)


def test_hole_orientation_does_not_matter():
    c, r = np.array([5 * MM, 5 * MM]), 2 * MM
    a = hatch(Layer((square(), circle(c, r))), spacing=H)
    b = hatch(Layer((square().reversed(), circle(c, r).reversed())), spacing=H)
    np.testing.assert_allclose(a.marks, b.marks, atol=1e-15)


def test_offset_shifts_lines():
    sv = hatch(Layer((square(),)), spacing=H, offset=0.5 * H)
    assert len(sv) == 100
    np.testing.assert_allclose(sv.marks[0, 0, 1], 0.5 * H, rtol=1e-9)


def test_start_point_gives_initial_jump_and_vectors_interleave():
    sv = hatch(Layer((square(),)), spacing=H, start=(-1 * MM, -1 * MM))
    np.testing.assert_array_equal(sv.initial_jump[0], [-1 * MM, -1 * MM])
    np.testing.assert_array_equal(sv.initial_jump[1], sv.marks[0, 0])
    plain = hatch(Layer((square(),)), spacing=H)
    extra = np.hypot(*(sv.marks[0, 0] - [-1 * MM, -1 * MM]))
    assert sv.total_jump_length == pytest.approx(plain.total_jump_length + extra, rel=1e-12)
    vecs, is_mark = sv.vectors()
    assert vecs.shape == (2 * len(sv), 2, 2)
    assert not is_mark[0] and is_mark[1] and not is_mark[2]
    # a continuous chain: each vector starts where the previous one ended
    np.testing.assert_array_equal(vecs[1:, 0], vecs[:-1, 1])
    assert len(sv.to_paths()) == len(sv)


def test_bad_start_raises():
    with pytest.raises(ValueError, match="start"):
        hatch(Layer((square(),)), spacing=H, start=(0.0, float("nan")))


def test_spacing_larger_than_part_is_empty():
    sv = hatch(Layer((square(0.05 * MM, x0=0.01 * MM, y0=0.01 * MM),)), spacing=H)
    assert len(sv) == 0
    assert sv.marks.shape == (0, 2, 2) and sv.jumps.shape == (0, 2, 2)
    assert sv.total_mark_length == 0.0


@pytest.mark.parametrize("spacing", [0.0, -1e-4, float("nan"), float("inf")])
def test_bad_spacing_raises(spacing):
    with pytest.raises(ValueError, match="spacing"):
        hatch(Layer((square(),)), spacing=spacing)


def test_open_contour_raises():
    open_path = Path.polyline([[0, 0], [SIDE, 0], [SIDE, SIDE]])
    with pytest.raises(ValueError, match="open"):
        hatch(Layer((square(), open_path)), spacing=H)
    with pytest.raises(ValueError, match="no contours"):
        hatch(Layer(()), spacing=H)


def test_text_outline_holes_respected():
    from microfab.geometry.text import text_layer

    layer = text_layer("o", height=0.02)
    sv = hatch(layer, spacing=0.02 * MM)
    poly = layer_polygon(layer)
    mid = sv.marks.mean(axis=1)
    assert np.all(shapely.contains_xy(poly, mid[:, 0], mid[:, 1]))
    hole = shapely.Polygon(layer[1].flatten())
    assert not np.any(shapely.contains_xy(hole, mid[:, 0], mid[:, 1]))
    assert sv.total_mark_length == pytest.approx(poly.area / (0.02 * MM), rel=0.03)


def test_scanvectors_shape_check():
    with pytest.raises(ValueError, match="jumps"):
        ScanVectors(np.zeros((3, 2, 2)), np.zeros((1, 2, 2)))


@pytest.mark.parametrize("angle_deg", [0.0, 9.0, 67.0])
def test_lines_that_miss_the_part_between_two_islands_add_no_marks(angle_deg):
    # the lines between the two squares miss the material (an empty intersection each);
    # every mark lies in a square and the marked length is that of the two squares
    layer = Layer((square(MM), square(MM, 5 * MM, 5 * MM)))
    sv = hatch(layer, spacing=H, angle=np.deg2rad(angle_deg), offset=H / 2)
    poly = layer_polygon(layer)
    mids = shapely.points(sv.marks.mean(axis=1))
    assert np.all(shapely.covers(poly, mids))
    assert np.all(sv.mark_lengths <= np.sqrt(2) * MM * (1 + 1e-9))
    assert sv.total_mark_length == pytest.approx(2 * MM**2 / H, rel=0.03)
