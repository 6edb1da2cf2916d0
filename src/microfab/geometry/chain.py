"""Join loose segments (as read from a drawing) into open and closed :class:`Path` chains.

Drawings store contours as unordered pieces: a square may be four LINE entities in any
order and direction. :func:`chain_segments` finds, with a k-d tree over all segment ends
(no quadratic search), which ends meet within a tolerance and links the pieces into
maximal chains, reversing pieces as needed.

Rules
-----
- **Meeting ends.** Two ends of different segments meet when they lie within ``tol`` of
  each other. An end that meets exactly one other end, which meets no other, is linked to
  it.
- **Junctions.** Where more than two ends meet (a T or an X, or a cluster of nearby ends),
  the pairing is ambiguous. Candidate pairs are then linked greedily by the smallest
  turning angle (the straightest continuation first), ties broken by the smaller gap and
  then by the lower end indices; an end left over at a junction ends its chain. A T thus
  gives one straight chain through the bar and an open stem; an X gives two straight
  chains.
- **Closure.** A chain whose links form a cycle is a closed path. A single arc or curve
  whose end lies within ``tol`` of its start (a circle, a closed spline) and which is
  longer than ``2 tol`` is closed too; a single straight line never is.
- **Gaps.** Gaps up to ``tol`` are snapped, so that the returned paths have no gaps (and
  stay valid when reversed or transformed): at each junction the end point of the more
  rigid segment is kept (arc over curve over line; of two alike, the shorter one's) and
  the other segment's end is moved onto it — a line gets the new end point, a curve an
  added linear correction (exact at both ends, at most the gap in between), an arc keeps
  its sweep and takes the new chord. Nothing is inserted. Gaps up to 1e-13 m (rounding
  noise, well inside :class:`Path`'s default tolerance) are left alone. Each path is
  built with ``gap_tol`` slightly above ``tol``, which covers the rare gap that cannot
  be snapped (between two near-full circles).
- **Order.** Chains are returned in the order of their lowest segment index; a closed
  chain starts at its lowest-index segment, and every chain runs in the direction of
  that segment as given. Zero-length segments are dropped.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from microfab.core.validate import check_positive
from microfab.geometry.path import Path
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment, Segment

__all__ = ["chain_segments", "segment_endpoints"]

#: the relative slack added to ``tol`` when a chained path's ``gap_tol`` is set
_GAP_SLACK = 1e-9
#: gaps up to this (m) are rounding noise, far inside Path's default tolerance: not snapped
_NOISE_GAP = 1e-13
#: segment kinds as `segment_endpoints` codes them
_KIND: dict[type, int] = {LineSegment: 0, ArcSegment: 1, CurveSegment: 2}


def segment_endpoints(segments: Sequence[Segment]) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points of many segments, vectorised by segment kind.

    Parameters
    ----------
    segments : sequence of Segment
        The segments.

    Returns
    -------
    starts, ends : numpy.ndarray
        Shape (n, 2) each, m.
    """
    n = len(segments)
    starts = np.empty((n, 2))
    ends = np.empty((n, 2))
    kinds = [_KIND.get(type(s), -1) for s in segments]  # exact types; subclasses below
    for i in [i for i, k in enumerate(kinds) if k < 0]:
        s = segments[i]
        kinds[i] = next((k for cls, k in _KIND.items() if isinstance(s, cls)), -1)
        if kinds[i] < 0:
            raise TypeError(f"not a segment: {s!r}")
    code = np.array(kinds, dtype=np.int8)
    lines = np.flatnonzero(code == 0).tolist()
    arcs = np.flatnonzero(code == 1).tolist()
    for i in np.flatnonzero(code == 2).tolist():
        # f(0) = Σ c_k (-1)^k and f(1) = Σ c_k in the variable x = 2u - 1
        c = segments[i].coef  # type: ignore[union-attr]
        sign = (-1.0) ** np.arange(c.shape[0])
        starts[i] = sign @ c
        ends[i] = c.sum(axis=0)
    if lines:
        starts[lines] = [segments[i].p0 for i in lines]  # type: ignore[union-attr]
        ends[lines] = [segments[i].p1 for i in lines]  # type: ignore[union-attr]
    if arcs:
        a = [segments[i] for i in arcs]
        c = np.array([s.center for s in a])
        r = np.array([s.radius for s in a])[:, None]
        t0 = np.array([s.theta0 for s in a])
        t1 = t0 + np.array([s.sweep for s in a])
        starts[arcs] = c + r * np.column_stack([np.cos(t0), np.sin(t0)])
        ends[arcs] = c + r * np.column_stack([np.cos(t1), np.sin(t1)])
    return starts, ends


def _unit_tangent(seg: Segment, at_end: bool) -> np.ndarray:
    """Unit tangent (direction of travel) of a segment at its start or end."""
    if isinstance(seg, LineSegment):
        d = seg.p1 - seg.p0
    elif isinstance(seg, ArcSegment):
        t = seg.theta0 + (seg.sweep if at_end else 0.0)
        d = np.sign(seg.sweep) * np.array([-np.sin(t), np.cos(t)])
    else:
        d1 = seg.derivative_coefs[0]
        # f'(1) = Σ d_k and f'(0) = Σ d_k (-1)^k in the variable x = 2u - 1
        d = d1.sum(axis=0) if at_end else ((-1.0) ** np.arange(d1.shape[0])) @ d1
        if not np.any(d):  # a cusp at the end: fall back to the chord direction
            d = seg.end - seg.start
    n = float(np.hypot(*d))
    return d / n if n > 0 else np.zeros(2)


def _link_ends(segs: Sequence[Segment], points: np.ndarray, tol: float) -> np.ndarray:
    """Partner end index of each end (-1: free); ends are ``2 i`` (start), ``2 i + 1`` (end)."""
    n_ends = points.shape[0]
    partner = np.full(n_ends, -1, dtype=np.int64)
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    if pairs.size == 0:
        return partner
    pairs = pairs[(pairs[:, 0] >> 1) != (pairs[:, 1] >> 1)]  # never link a segment to itself
    if pairs.size == 0:
        return partner
    degree = np.bincount(pairs.ravel(), minlength=n_ends)
    simple = (degree[pairs[:, 0]] == 1) & (degree[pairs[:, 1]] == 1)
    a, b = pairs[simple, 0], pairs[simple, 1]
    partner[a] = b
    partner[b] = a
    hard = pairs[~simple]
    if hard.size == 0:
        return partner
    # junctions: greedy on (turning angle, gap, indices)
    cache: dict[int, np.ndarray] = {}

    def outward(e: int) -> np.ndarray:
        """Direction of travel arriving at end e (leaving the segment there)."""
        if e not in cache:
            t = _unit_tangent(segs[e >> 1], at_end=bool(e & 1))
            cache[e] = t if e & 1 else -t
        return cache[e]

    keys = []
    for e0, e1 in hard.tolist():
        # arrive along outward(e0), leave into the other segment along -outward(e1)
        cosang = float(np.clip(-np.dot(outward(e0), outward(e1)), -1.0, 1.0))
        gap = float(np.hypot(*(points[e0] - points[e1])))
        keys.append((float(np.arccos(cosang)), gap, min(e0, e1), max(e0, e1)))
    keys.sort()
    for _, _, e0, e1 in keys:
        if partner[e0] < 0 and partner[e1] < 0:
            partner[e0] = e1
            partner[e1] = e0
    return partner


def _moved(seg: Segment, start: np.ndarray | None, end: np.ndarray | None) -> Segment:
    """The segment with its start and/or end moved (by at most the chaining tolerance)."""
    if isinstance(seg, LineSegment):
        return LineSegment(seg.p0 if start is None else start, seg.p1 if end is None else end)
    if isinstance(seg, CurveSegment):
        d0 = np.zeros(2) if start is None else start - seg.start
        d1 = np.zeros(2) if end is None else end - seg.end
        c = np.array(seg.coef)
        # add the linear function d0 (1 - u) + d1 u = (d0 + d1)/2 + (d1 - d0)/2 x
        c[0] += 0.5 * (d0 + d1)
        c[1] += 0.5 * (d1 - d0)
        return CurveSegment(c)
    p0 = seg.start if start is None else start
    p1 = seg.end if end is None else end
    if abs(seg.sweep) > 2.0 * np.pi - 1e-3 or not np.any(p0 != p1):
        return seg  # a (near) full circle has no chord to re-fit: keep it and the gap
    return ArcSegment.from_bulge(p0, p1, np.tan(seg.sweep / 4.0))


_RIGIDITY = {LineSegment: 0, CurveSegment: 1, ArcSegment: 2}


def _full_circle(seg: Segment) -> bool:
    """An arc that `_moved` keeps as it is: alone in a closed chain, `_snap` changes nothing."""
    return isinstance(seg, ArcSegment) and abs(seg.sweep) > 2.0 * np.pi - 1e-3


def _snap(chain: list[Segment], closed: bool) -> list[Segment]:
    """Remove the gaps between consecutive segments of a chain (see the module notes)."""
    n = len(chain)
    new_start: list[np.ndarray | None] = [None] * n
    new_end: list[np.ndarray | None] = [None] * n
    for k in range(n if closed else n - 1):
        a, b = chain[k], chain[(k + 1) % n]
        pa, pb = a.end, b.start
        if np.hypot(*(pa - pb)) <= _NOISE_GAP:
            continue
        ra, rb = _RIGIDITY[type(a)], _RIGIDITY[type(b)]
        keep_a = ra > rb or (ra == rb and a.length <= b.length)
        if keep_a:
            new_start[(k + 1) % n] = pa
        else:
            new_end[k] = pb
    if all(s is None for s in new_start) and all(e is None for e in new_end):
        return chain
    return [
        s if (p is None and q is None) else _moved(s, p, q)
        for s, p, q in zip(chain, new_start, new_end, strict=True)
    ]


def chain_segments(
    segments: Sequence[Segment],
    tol: float,
    *,
    endpoints: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[Path]:
    """Join loose segments into maximal open or closed paths.

    Segments may come in any order and direction. See the module documentation for the
    rules at junctions (straightest continuation first), closure, gap snapping and
    output order.

    Parameters
    ----------
    segments : sequence of Segment
        The pieces, m.
    tol : float
        Largest gap between two ends that still joins them, m; positive.
    endpoints : tuple of numpy.ndarray, optional
        `segment_endpoints` of ``segments``, when the caller has them already.

    Returns
    -------
    list of Path
        The chains, ordered by their lowest segment index. Closed chains are closed
        paths; the rest are open.

    Raises
    ------
    ValueError
        If ``tol`` is not positive and finite.

    Examples
    --------
    >>> from microfab.geometry.segments import LineSegment
    >>> sq = [LineSegment((1, 0), (1, 1)), LineSegment((0, 0), (1, 0)),
    ...       LineSegment((0, 0), (0, 1)), LineSegment((1, 1), (0, 1))]
    >>> [p.closed for p in chain_segments(sq, 1e-9)]
    [True]
    """
    return _chain(segments, tol, endpoints)[0]


def _segment_lengths(
    segments: Sequence[Segment], starts: np.ndarray, ends: np.ndarray
) -> np.ndarray:
    """Each segment's ``length`` (to the bit), m: a line's from its end points, at once."""
    with np.errstate(over="ignore"):  # absurd coordinates: an infinite length, as the line's
        d = ends - starts
    # math.hypot, as LineSegment.length (numpy's hypot differs in the last bit at times)
    lengths = np.array(list(map(math.hypot, d[:, 0].tolist(), d[:, 1].tolist())))
    for i, s in enumerate(segments):
        if not isinstance(s, LineSegment):
            # an arc's radius times sweep is its length; a curve's is its quadrature
            lengths[i] = s.radius * abs(s.sweep) if isinstance(s, ArcSegment) else s.length
    return lengths


def _chain(
    segments: Sequence[Segment],
    tol: float,
    endpoints: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[list[Path], np.ndarray]:
    """`chain_segments`, and which paths hold snapped (moved) segments.

    Returns
    -------
    paths : list of Path
        As `chain_segments` returns them.
    snapped : numpy.ndarray of bool
        Shape (len(paths),): True where the path's segments were moved to close gaps;
        the others' are the given segments, some reversed (same reach, same lengths).
    """
    tol = check_positive("chaining tolerance tol", tol, "m")
    starts, ends = segment_endpoints(segments) if endpoints is None else endpoints
    if starts.shape != (len(segments), 2) or ends.shape != starts.shape:
        raise ValueError(f"endpoints must be two ({len(segments)}, 2) arrays")
    # zero length: a line whose ends coincide (its length, their distance, is 0 exactly
    # then and only then), an arc by radius times sweep, a curve by its length
    lengths = _segment_lengths(segments, starts, ends)
    keep = lengths > 0
    segs = list(segments)
    if not keep.all():
        segs = [s for s, k in zip(segments, keep.tolist(), strict=True) if k]
        starts, ends, lengths = starts[keep], ends[keep], lengths[keep]
    n = len(segs)
    if n == 0:
        return [], np.zeros(0, dtype=bool)
    points = np.empty((2 * n, 2))
    points[0::2] = starts
    points[1::2] = ends
    partner_arr = _link_ends(segs, points, tol)
    # segments with a linked end farther than floating-point noise from its partner
    linked = partner_arr >= 0
    inexact = np.zeros(2 * n, dtype=bool)
    d = points[linked] - points[partner_arr[linked]]
    inexact[linked] = np.hypot(d[:, 0], d[:, 1]) > _NOISE_GAP
    needs_snap = inexact[0::2] | inexact[1::2]

    seq, fwd, off, cyc = _walk_chains(partner_arr)
    seq_l, fwd_l, off_l = seq.tolist(), fwd.tolist(), off.tolist()
    snap_l = np.logical_or.reduceat(needs_snap[seq], off[:-1]).tolist()
    # every piece in chain order; segment seq[off[c]] of a cycle, its lowest index, runs
    # as given
    pieces = [segs[k] if f else segs[k].reversed() for k, f in zip(seq_l, fwd_l, strict=True)]
    # the pieces' lengths: a reversed line or arc has its segment's to the bit, a
    # reversed curve its own quadrature
    piece_len = lengths[seq]
    for j in np.flatnonzero(~fwd).tolist():
        if isinstance(pieces[j], CurveSegment):
            piece_len[j] = pieces[j].length
    breaks = _chain_breaks(piece_len, off)
    breaks.setflags(write=False)
    # a single arc or curve is closed when its ends lie within tol and it is longer than
    # 2 tol (a single line never is)
    ones = [
        c
        for c in np.flatnonzero(np.diff(off) == 1).tolist()
        if not isinstance(pieces[off_l[c]], LineSegment)
    ]
    try_snap = snap_l
    if ones:
        first = off[ones]
        k = seq[first]
        d = ends[k] - starts[k]
        cyc[ones] = (np.hypot(d[:, 0], d[:, 1]) <= tol) & (piece_len[first] > 2.0 * tol)
        for c in ones:
            if cyc[c] and not _full_circle(pieces[off_l[c]]):
                try_snap[c] = True
    cyc_l = cyc.tolist()
    gap_tol = tol * (1.0 + _GAP_SLACK)
    # the chains as linked (checked all at once below); chain c's breaks, the arc length at
    # its pieces' starts and at its end, at off[c] + c in `breaks`
    out = [
        Path._checked(tuple(pieces[lo:hi]), closed, gap_tol, breaks[lo + c : hi + c + 1])
        for c, (lo, hi, closed) in enumerate(zip(off_l, off_l[1:], cyc_l, strict=False))
    ]
    plain = np.ones(len(cyc_l), dtype=bool)
    for c in [c for c, t in enumerate(try_snap) if t]:
        chain = pieces[off_l[c] : off_l[c + 1]]
        snapped = _snap(chain, cyc_l[c])
        if snapped is not chain:
            out[c] = Path(tuple(snapped), closed=cyc_l[c], gap_tol=gap_tol)
            plain[c] = False
    _check_plain(out, plain, seq, fwd, off, cyc, segs, starts, ends, gap_tol)
    return out, ~plain


@njit(cache=True)
def _chain_breaks(lengths: np.ndarray, off: np.ndarray) -> np.ndarray:
    """Each chain's `Path.breaks`, one after another (chain c at ``off[c] + c``).

    ``0`` and then the running sum of the chain's piece lengths, added in order as
    ``numpy.cumsum`` adds them, so that they equal the breaks a `Path` computes.
    """
    n_chains = off.size - 1
    out = np.empty(lengths.size + n_chains)
    for c in range(n_chains):
        at = off[c] + c
        acc = 0.0
        out[at] = acc
        for j in range(off[c], off[c + 1]):
            acc += lengths[j]
            at += 1
            out[at] = acc
    return out


@njit(cache=True)
def _walk_chains(partner: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Follow the links into chains: ``(segment, forwards)`` in order, chain offsets, cycles.

    Chains come in the order of their lowest segment index ``i``; a cycle starts at
    ``i``, an open chain at its free head, and either runs so that ``i`` goes forwards.
    """
    n = partner.size // 2
    seq = np.empty(n, dtype=np.int64)
    fwd = np.empty(n, dtype=np.bool_)
    off = np.zeros(n + 1, dtype=np.int64)
    cyc = np.zeros(n, dtype=np.bool_)
    visited = np.zeros(n, dtype=np.bool_)
    pos = 0
    n_chains = 0
    for i in range(n):
        if visited[i]:
            continue
        # walk backwards from the start of segment i to the head of its chain
        head, head_fwd, cycle = i, True, False
        entry = 2 * i
        while True:
            q = partner[entry]
            if q < 0:
                break
            j = q >> 1
            if j == i:
                cycle = True
                break
            head, head_fwd = j, (q & 1) == 1  # arriving at j's end: j runs forwards
            entry = q ^ 1
        if cycle:
            head, head_fwd = i, True
        # walk forwards from the head
        s, f = head, head_fwd
        while True:
            visited[s] = True
            seq[pos] = s
            fwd[pos] = f
            pos += 1
            q = partner[2 * s + 1 if f else 2 * s]
            if q < 0:
                break
            j = q >> 1
            if j == head:
                break
            s, f = j, (q & 1) == 0
        cyc[n_chains] = cycle
        n_chains += 1
        off[n_chains] = pos
    return seq, fwd, off[: n_chains + 1], cyc[:n_chains]


def _check_plain(
    out: list[Path],
    plain: np.ndarray,
    seq: np.ndarray,
    fwd: np.ndarray,
    off: np.ndarray,
    closed: np.ndarray,
    segs: Sequence[Segment],
    starts: np.ndarray,
    ends: np.ndarray,
    gap_tol: float,
) -> None:
    """Check the chains made as linked (``plain``) as `Path` would, all at once.

    Their pieces are the given segments, forwards or reversed, of nonzero length; only
    the gaps remain to be checked, from the segments' end points. A chain that fails is
    built by `Path` itself, which raises its error.
    """
    if not plain.any():
        return
    sizes = np.diff(off)
    first, last = off[:-1], off[1:] - 1
    s0 = np.where(fwd[:, None], starts[seq], ends[seq])  # where each piece starts
    e0 = np.where(fwd[:, None], ends[seq], starts[seq])
    follows = np.repeat(plain, sizes)  # a piece of a plain chain followed by another
    follows[last] = False
    d = s0[1:] - e0[:-1]
    bad = follows[:-1] & (np.hypot(d[:, 0], d[:, 1]) > gap_tol)
    dc = s0[first] - e0[last]
    bad_close = plain & closed & (np.hypot(dc[:, 0], dc[:, 1]) > gap_tol)
    if not (bad.any() or bad_close.any()):
        return
    chain_of = np.repeat(np.arange(sizes.size), sizes)
    worst = min(set(chain_of[:-1][bad].tolist()) | set(np.flatnonzero(bad_close).tolist()))
    lo, hi = off[worst], off[worst + 1]
    pieces = [
        segs[k] if f else segs[k].reversed()
        for k, f in zip(seq[lo:hi].tolist(), fwd[lo:hi].tolist(), strict=True)
    ]
    out[worst] = Path(tuple(pieces), closed=bool(closed[worst]), gap_tol=gap_tol)
