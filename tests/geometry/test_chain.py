import itertools

import numpy as np
import pytest

from microfab.geometry.chain import chain_segments, segment_endpoints
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment


def square_pieces(x0=0.0, y0=0.0, a=1.0, n_per_side=3):
    """A CCW square cut into n_per_side lines per side."""
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float) * a + [x0, y0]
    pts = []
    for p, q in itertools.pairwise(corners):
        for k in range(n_per_side):
            pts.append(p + (q - p) * k / n_per_side)
    pts.append(corners[0])
    return [LineSegment(p, q) for p, q in itertools.pairwise(pts)]


def shuffle_and_flip(segs, seed):
    rng = np.random.default_rng(seed)
    out = [segs[i] for i in rng.permutation(len(segs))]
    return [s.reversed() if rng.random() < 0.5 else s for s in out]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shuffled_reversed_square_closes(seed):
    segs = shuffle_and_flip(square_pieces(a=2e-3), seed)
    paths = chain_segments(segs, 1e-9)
    assert len(paths) == 1
    p = paths[0]
    assert p.closed
    assert len(p) == 12
    assert p.length == pytest.approx(8e-3, rel=1e-12)
    assert abs(p.signed_area) == pytest.approx(4e-6, rel=1e-12)
    # consecutive segments really join
    for a, b in zip(p.segments, p.segments[1:] + p.segments[:1], strict=True):
        assert np.array_equal(a.end, b.start)


def test_first_segment_keeps_direction_and_starts_closed_chain():
    segs = shuffle_and_flip(square_pieces(), 5)
    p = chain_segments(segs, 1e-9)[0]
    # the chain starts with segment 0 as given
    assert np.array_equal(p.segments[0].start, segs[0].start)
    assert np.array_equal(p.segments[0].end, segs[0].end)


def test_two_separate_contours_ordered_by_first_index():
    a = square_pieces(0, 0, 1.0, 1)
    b = square_pieces(5, 5, 2.0, 2)
    segs = [b[3], a[2], *b[:3], *b[4:], *a[:2], a[3]]
    paths = chain_segments(segs, 1e-9)
    assert len(paths) == 2
    assert all(p.closed for p in paths)
    assert paths[0].length == pytest.approx(8.0)  # b comes first: it holds segment 0
    assert paths[1].length == pytest.approx(4.0)


def test_open_chain_stays_open_and_is_ordered():
    pts = np.array([[0, 0], [1, 0], [1, 1], [2, 1], [2, 3]], dtype=float)
    segs = [LineSegment(p, q) for p, q in itertools.pairwise(pts)]
    mixed = [segs[2].reversed(), segs[0], segs[3], segs[1].reversed()]
    (p,) = chain_segments(mixed, 1e-9)
    assert not p.closed
    assert p.length == pytest.approx(5.0)
    # runs in the direction of segment 0 of the input (segs[2] reversed): from the end
    assert np.allclose(p.start, pts[-1]) and np.allclose(p.end, pts[0])


def test_gap_within_tol_closes_and_is_snapped():
    segs = square_pieces(a=1e-3, n_per_side=1)
    gap = 1e-8
    segs[1] = LineSegment(segs[1].p0 + np.array([0.0, gap]), segs[1].p1)  # a 10 nm gap at a corner
    (p,) = chain_segments(segs, 2e-8)
    assert p.closed
    assert p.length == pytest.approx(4e-3, abs=3 * gap)
    for a, b in zip(p.segments, p.segments[1:] + p.segments[:1], strict=True):
        assert np.array_equal(a.end, b.start)
    # snapped: still valid under operations that rebuild the path with default tolerance
    assert p.reversed().closed


def test_gap_beyond_tol_stays_open():
    segs = square_pieces(a=1e-3, n_per_side=1)
    segs[1] = LineSegment(segs[1].p0 + np.array([0.0, 1e-7]), segs[1].p1)
    paths = chain_segments(segs, 2e-8)
    assert len(paths) == 1
    assert not paths[0].closed
    assert paths[0].length == pytest.approx(4e-3 - 1e-7, rel=1e-9)


def test_arc_rigid_line_moves_to_it():
    arc = ArcSegment((0.0, 0.0), 1.0, 0.0, np.pi)  # (1,0) -> (-1,0) CCW
    line = LineSegment((-1.0 + 1e-9, 0.0), (1.0 - 2e-9, 0.0))
    (p,) = chain_segments([line, arc], 1e-8)
    assert p.closed
    arcs = [s for s in p.segments if isinstance(s, ArcSegment)]
    assert arcs[0].radius == 1.0 and arcs[0].center[0] == 0.0  # arc untouched
    assert p.length == pytest.approx(np.pi + 2.0, abs=1e-12)


def test_curve_gap_snapped_exactly():
    c1 = CurveSegment.from_bezier([[0, 0], [1, 1], [2, 0]])
    c2 = CurveSegment.from_bezier([[2 + 1e-9, 1e-9], [1, -1], [0, 0]])
    (p,) = chain_segments([c1, c2], 1e-8)
    assert p.closed
    for a, b in zip(p.segments, p.segments[1:] + p.segments[:1], strict=True):
        assert np.array_equal(a.end, b.start) or np.allclose(a.end, b.start, atol=1e-15)


def test_single_circle_closes_single_line_does_not():
    circle = ArcSegment((0.0, 0.0), 1.0, 0.3, -2 * np.pi)
    line = LineSegment((5.0, 0.0), (6.0, 0.0))
    p_c, p_l = chain_segments([circle, line], 1e-9)
    assert p_c.closed and p_c.orientation == "cw"
    assert not p_l.closed


def test_t_junction_prefers_straight_continuation():
    left = LineSegment((-1.0, 0.0), (0.0, 0.0))
    stem = LineSegment((0.0, 0.0), (0.0, -1.0))
    right = LineSegment((1.0, 0.0), (0.0, 0.0))
    paths = chain_segments([stem, left, right], 1e-9)
    assert len(paths) == 2
    # the stem (index 0) is alone; the bar is one straight chain of length 2
    assert paths[0].length == pytest.approx(1.0) and len(paths[0]) == 1
    assert paths[1].length == pytest.approx(2.0) and len(paths[1]) == 2
    assert paths[1].corners().size == 0


def test_x_junction_gives_two_straight_chains():
    arms = [LineSegment((0.0, 0.0), d) for d in [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]]
    paths = chain_segments(arms, 1e-9)
    assert len(paths) == 2
    for p in paths:
        assert p.length == pytest.approx(2.0)
        assert p.corners().size == 0


def test_deterministic():
    segs = shuffle_and_flip(square_pieces(n_per_side=4) + square_pieces(3, 0, 1, 2), 9)
    a = chain_segments(segs, 1e-9)
    b = chain_segments(segs, 1e-9)
    assert [p.length for p in a] == [p.length for p in b]
    assert all(np.array_equal(p.start, q.start) for p, q in zip(a, b, strict=True))


def test_zero_length_dropped_and_empty():
    z = LineSegment((1.0, 1.0), (1.0, 1.0))
    assert chain_segments([], 1e-9) == []
    assert chain_segments([z], 1e-9) == []


@pytest.mark.parametrize("tol", [0.0, -1e-9, float("nan"), float("inf")])
def test_bad_tol(tol):
    with pytest.raises(ValueError, match="tol"):
        chain_segments(square_pieces(), tol)


def test_endpoints_vectorised_match():
    segs = [
        LineSegment((0, 0), (1, 2)),
        ArcSegment((1, 1), 2.0, 0.4, -1.3),
        CurveSegment.from_bezier([[0, 0], [1, 3], [2, -1], [4, 0]]),
    ]
    s, e = segment_endpoints(segs)
    for i, seg in enumerate(segs):
        assert np.allclose(s[i], seg.start, atol=1e-14)
        assert np.allclose(e[i], seg.end, atol=1e-14)


def test_many_segments_fast():
    rng = np.random.default_rng(0)
    segs = []
    for i in range(2000):
        segs += square_pieces(3.0 * (i % 50), 3.0 * (i // 50), 1.0, 1)
    segs = [segs[i] for i in rng.permutation(len(segs))]
    segs = [s.reversed() if rng.random() < 0.5 else s for s in segs]
    paths = chain_segments(segs, 1e-9)
    assert len(paths) == 2000
    assert all(p.closed and len(p) == 4 for p in paths)


def test_arc_arc_gap_moves_the_longer_arc():
    small = ArcSegment((0.0, 0.0), 1.0, 0.0, np.pi)  # (1, 0) -> (-1, 0)
    big = ArcSegment.from_bulge((-1.0 + 1e-9, 0.0), (1.0, 0.0), 2.0)  # longer, below
    (p,) = chain_segments([small, big], 1e-8)
    assert p.closed
    a, b = p.segments
    assert a is small  # the shorter arc is kept exactly
    assert np.allclose(b.start, small.end, rtol=0, atol=1e-15)
    assert np.allclose(b.end, small.start, rtol=0, atol=1e-15)
    assert b.sweep == big.sweep
    assert p.reversed().closed
