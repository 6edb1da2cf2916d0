"""The fast constructors and the batched chaining give what the plain constructors give."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.geometry.chain import _chain, chain_segments, segment_endpoints
from microfab.geometry.path import Path
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment


def same_segment(a: object, b: object) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, LineSegment):
        return np.array_equal(a.p0, b.p0) and np.array_equal(a.p1, b.p1)  # type: ignore[attr-defined]
    if isinstance(a, ArcSegment):
        return (
            np.array_equal(a.center, b.center)  # type: ignore[attr-defined]
            and (a.radius, a.theta0, a.sweep) == (b.radius, b.theta0, b.sweep)  # type: ignore[attr-defined]
        )
    return np.array_equal(a.coef, b.coef)  # type: ignore[attr-defined]


def test_line_many_matches_the_constructor_and_is_read_only() -> None:
    rng = np.random.default_rng(0)
    coords = rng.normal(size=(50, 4))
    fast = LineSegment.many(coords)
    for row, seg in zip(coords, fast, strict=True):
        slow = LineSegment(row[:2], row[2:])
        assert same_segment(seg, slow)
        assert not seg.p0.flags.writeable and not seg.p1.flags.writeable
        assert seg.length == slow.length
    rev = fast[0].reversed()
    assert same_segment(rev, LineSegment(coords[0, 2:], coords[0, :2]))
    coords[3, 1] = np.nan
    with pytest.raises(ValueError, match="line 3"):
        LineSegment.many(coords)
    with pytest.raises(ValueError, match=r"\(n, 4\)"):
        LineSegment.many(coords[:, :3])


def test_arc_from_numbers_and_bulge_match_the_constructor() -> None:
    arc = ArcSegment.from_numbers(1.0, 2.0, 0.5, 0.3, -1.2)
    assert same_segment(arc, ArcSegment((1.0, 2.0), 0.5, 0.3, -1.2))
    assert not arc.center.flags.writeable
    for bad in ((np.nan, 0.0, 1.0, 0.0, 1.0), (0.0, 0.0, -1.0, 0.0, 1.0), (0, 0, 1, 0, 0)):
        with pytest.raises(ValueError):
            ArcSegment.from_numbers(*bad)
    a = ArcSegment.from_bulge((0.0, 0.0), (1.0, 0.0), 0.4)
    assert np.allclose(a.start, (0.0, 0.0), atol=1e-15)
    assert np.allclose(a.end, (1.0, 0.0), atol=1e-15)
    assert a.sweep == pytest.approx(4 * np.arctan(0.4))


def scattered(seed: int = 3) -> list:
    """Squares, slots, circles and a curve, in random order and direction, with gaps."""
    rng = np.random.default_rng(seed)
    segs: list = []
    for k in range(30):
        x, y = 3.0 * (k % 6), 3.0 * (k // 6)
        c = [(x, y), (x + 1, y), (x + 1, y + 1 + 1e-12 * k), (x, y + 1)]
        segs += [LineSegment(c[i], c[(i + 1) % 4]) for i in range(4)]
    for k in range(10):
        x, y = 3.0 * k, 20.0
        segs += [
            LineSegment((x + 0.5, y), (x + 1.5, y)),
            LineSegment((x + 1.5, y + 1), (x + 0.5, y + 1)),
        ]
        segs += [ArcSegment((x + 1.5, y + 0.5), 0.5, -np.pi / 2, np.pi)]
        segs += [ArcSegment((x + 0.5, y + 0.5), 0.5, np.pi / 2, np.pi)]
    segs += [ArcSegment((50.0 + k, 50.0), 0.4, 0.0, 2 * np.pi) for k in range(5)]
    segs += [CurveSegment.from_bezier([(60, 0), (61, 1), (62, -1), (63, 0)])]
    segs += [LineSegment((70, 0), (70, 0)), LineSegment((80, 0), (81, 0))]  # one of length 0
    order = rng.permutation(len(segs))
    return [segs[i].reversed() if rng.random() < 0.5 else segs[i] for i in order]


def test_chained_paths_equal_those_the_path_constructor_builds() -> None:
    segs = scattered()
    tol = 1e-9
    paths = chain_segments(segs, tol)
    for p in paths:
        plain = Path(p.segments, closed=p.closed, gap_tol=p.gap_tol)
        assert plain.closed == p.closed and plain.gap_tol == p.gap_tol
        assert len(plain.segments) == len(p.segments)
        assert all(same_segment(a, b) for a, b in zip(plain.segments, p.segments, strict=True))
        assert np.array_equal(plain.breaks, p.breaks) and not p.breaks.flags.writeable
    again = chain_segments(segs, tol, endpoints=segment_endpoints(segs))
    assert len(again) == len(paths)
    for p, q in zip(paths, again, strict=True):
        assert p.closed == q.closed
        assert all(same_segment(a, b) for a, b in zip(p.segments, q.segments, strict=True))
    assert sum(p.closed for p in paths) == 30 + 10 + 5
    assert len(paths) == 30 + 10 + 5 + 2  # the curve and a line open, the empty line gone
    with pytest.raises(ValueError, match="endpoints"):
        chain_segments(segs, tol, endpoints=(np.zeros((2, 2)), np.zeros((2, 2))))


def test_segment_endpoints_of_a_subclass_and_of_a_non_segment() -> None:
    class MyLine(LineSegment):
        pass

    s, e = segment_endpoints([MyLine((0, 1), (2, 3)), ArcSegment((0, 0), 1.0, 0.0, np.pi)])
    np.testing.assert_array_equal(s[0], (0, 1))
    np.testing.assert_array_equal(e[0], (2, 3))
    np.testing.assert_allclose(e[1], (-1, 0), atol=1e-15)
    with pytest.raises(TypeError, match="not a segment"):
        segment_endpoints([object()])  # type: ignore[list-item]


def test_chain_tells_the_snapped_paths_and_gives_the_others_their_breaks() -> None:
    gap = 1e-10  # within the tolerance, above rounding noise: snapped
    segs = scattered()
    for x in (100.0, 103.0):
        segs += [
            LineSegment((x, 0), (x + 1, 0)),
            LineSegment((x + 1, 0), (x + 1, 1 + gap * (x == 103.0))),
            LineSegment((x + 1, 1), (x, 1)),
            LineSegment((x, 1), (x, 0)),
        ]
    segs.append(ArcSegment((110.0, 0.0), 0.5, 0.0, 2 * np.pi - 1e-2))  # open by 5e-3 m
    segs.append(ArcSegment((112.0, 0.0), 0.5, 0.0, 2 * np.pi - 1e-10))  # closed within tol
    paths, snapped = _chain(segs, 1e-9)
    assert snapped.shape == (len(paths),)

    def given(s: object) -> bool:
        return any(same_segment(s, g) or same_segment(s, g.reversed()) for g in segs)

    for p, moved in zip(paths, snapped.tolist(), strict=True):
        assert moved == (not all(given(s) for s in p.segments))
        # the breaks of a chain as linked come with it, those of a snapped one when asked
        assert ("breaks" in vars(p)) == (not moved)
        fresh = Path(p.segments, closed=p.closed, gap_tol=p.gap_tol)
        assert np.array_equal(p.breaks, fresh.breaks) and p.length == fresh.length
    # the square with a gap is snapped, nothing else (a near-full circle keeps its gap)
    assert snapped.sum() == 1 and paths[int(np.argmax(snapped))].closed
    assert [p.closed for p in paths[-2:]] == [False, True] and not snapped[-2:].any()
