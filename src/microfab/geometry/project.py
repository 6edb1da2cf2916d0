"""Contour error: the exact nearest point (foot point) of a `Path` for many points.

The contour error of a measured XY trace is its distance to the exact drawing, signed by
side (seed 004 §III.A: the contour ``φ(x, y) = 0`` and the velocity across it, eqs. 5-14,
are measured from the nearest point of the contour). :func:`project_points` gives, for
each point, the foot point, its arc length ``s``, the unit tangent and left normal there,
the signed distance and the segment; :class:`Projection` holds them.

Sign convention
---------------
The distance is positive to the **left** of the direction of travel (along the left
normal, the tangent turned +90°): for a counter-clockwise closed contour, positive is
**inside**; for a clockwise one, outside. Where the foot is a junction of two segments
(a corner), the side is taken along the sum of the two segments' normals there (the
angle-weighted pseudo-normal), which decides correctly also at corners sharper than 90°;
beyond an end of an open path, along that end's own normal (ahead of the end: positive).

Algorithm and exactness
-----------------------
1. *Candidates* (:mod:`~.project_index`). Uniform grids of cells ``c0``, ``4 c0``,
   ``16 c0``, ... (``c0`` about the median segment length, halved while its lists are
   long; the coarser grids for as long as their lists stay short) list in each cell
   every segment that comes within ``ρ`` (the cell's side) of the cell: each segment is
   cut into pieces no longer than the cell, each piece has a box that provably holds
   it, and a piece is registered in every cell that its box grown by ``ρ`` touches. A
   point takes its cell's list at the finest grid; if the nearest listed segment is at
   most ``ρ`` away it is the nearest of all: the true nearest segment is then at most
   ``ρ`` from the point, hence from its cell, hence listed. Otherwise the point tries the
   next coarser grid, and after the last a k-d tree of path samples: every point of a
   segment lies within ``h`` of one of that segment's samples, so with ``ds`` the
   distance to the nearest sample (a path point, so ``d* <= ds``) the nearest segment
   owns a sample within ``d* + h <= ds + h``; the candidates are the owners of all the
   samples in that ball. (A path of at most 16 segments skips the tree: every segment
   is a candidate; a path of one segment has no grids.)
2. *Lines and arcs* in closed form, vectorised over all (point, candidate) pairs: the
   clipped orthogonal projection; the radial point if its angle lies in the sweep, else
   the nearer end (the distance to a circle point grows with the angle away from the
   radial one).
3. *Polynomial curves* by branch and bound with safeguarded Newton steps on the distance
   derivative (:mod:`~.project_curve`), to 1e-13 m, after a test of the curve's box
   against the best line or arc distance of the same point.
4. Per point, the smallest distance wins; ties go to the lower segment index.

Every bound is loosened by the coordinates' rounding (64 ε times their magnitude) so
that rounding never removes the nearest segment.

``hint`` (the previous arc length of each point, for a trace that moves along the path)
bounds the distance of a point that the finest grid did not settle by its distance to
the segment at the hint: the point goes straight to the first coarser grid (or the tree)
that certifies that bound, skipping the grids between, and the bound prunes the search
on curves and narrows the tree's ball. It does not change the result: each stage's
candidates hold every segment within the bound (a fortiori the nearest ones); a line's
or an arc's distance does not depend on the bound, and a curve's search only drops
intervals that cannot come below it, every other step depending on the interval alone
(:mod:`~.project_curve`); so the winner is the same minimum, with the same tie rule,
bit for bit.

:func:`project_points_scalar` is the slow reference: per point and per segment piece,
`scipy.optimize.minimize_scalar` (bounded Brent) on the segment's parameter.
"""

from __future__ import annotations

import itertools
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from microfab.geometry.path import Path
from microfab.geometry.project_index import ARC, CURVE, LINE, PathIndex
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment, Segment

__all__ = ["Projection", "project_points", "project_points_scalar"]

_INDEX: weakref.WeakKeyDictionary[Path, PathIndex] = weakref.WeakKeyDictionary()
#: Up to this many segments, a point no grid settles is measured against all of them.
_ALL_SEGMENTS = 16
#: Largest coordinate of a point, m (as for a segment: its square stays finite).
_MAX_COORD = 1e150


@dataclass(frozen=True, eq=False)
class Projection:
    """The foot points of ``n`` points on a path (read-only arrays).

    Attributes
    ----------
    s : numpy.ndarray
        Arc length of the foot along the path, shape (n,), m, in ``[0, length]`` (on a
        closed path ``length`` is the start again).
    foot : numpy.ndarray
        Nearest point of the path, shape (n, 2), m.
    tangent : numpy.ndarray
        Unit tangent of the path at the foot, shape (n, 2) (at a junction: the tangent of
        the winning segment at its end).
    normal : numpy.ndarray
        Unit left normal at the foot (the tangent turned +90°), shape (n, 2).
    distance : numpy.ndarray
        Signed distance to the path, shape (n,), m: positive to the left of the travel
        (inside a counter-clockwise contour); see the module's sign convention.
    segment : numpy.ndarray
        Index of the segment of the foot in ``path.segments``, shape (n,), int.
    """

    s: np.ndarray
    foot: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    segment: np.ndarray

    def __post_init__(self) -> None:
        if np.ndim(self.s) != 1:
            raise ValueError(f"s must be shaped (n,), got {np.shape(self.s)}")
        n = int(np.shape(self.s)[0])
        for name in ("s", "foot", "tangent", "normal", "distance", "segment"):
            want = (n, 2) if name in ("foot", "tangent", "normal") else (n,)
            arr = np.array(getattr(self, name), dtype=np.int64 if name == "segment" else float)
            if arr.shape != want:
                raise ValueError(f"{name} must be shaped {want} like s, got {arr.shape}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def __len__(self) -> int:
        return int(self.s.shape[0])


def _index(path: Path) -> PathIndex:
    """The path's packed segments and grids, kept while the path lives."""
    if not isinstance(path, Path):
        raise TypeError(f"path must be a microfab.geometry.path.Path, got {type(path).__name__}")
    idx = _INDEX.get(path)
    if idx is None:
        idx = PathIndex(path)
        _INDEX[path] = idx
    return idx


def _points(points: object) -> np.ndarray:
    p = np.array(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must be shaped (n, 2) in m, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        i = int(np.flatnonzero(~np.all(np.isfinite(p), axis=1))[0])
        raise ValueError(f"points must be finite (m): point {i} is {p[i].tolist()}")
    if p.size and np.max(np.abs(p)) > _MAX_COORD:
        raise ValueError(
            f"points must lie within ±{_MAX_COORD:g} m (their squared distances must not "
            f"overflow), got a coordinate of {np.max(np.abs(p)):.3g} m"
        )
    return p


def _select(counts: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per group of consecutive pairs: index of the smallest distance (the first of equals)."""
    win = np.full(counts.size, -1, dtype=np.int64)
    dmin = np.full(counts.size, np.inf)
    nz = np.flatnonzero(counts > 0)
    if nz.size:
        starts = (np.cumsum(counts) - counts)[nz]
        mins = np.minimum.reduceat(dist, starts)
        gid = np.repeat(np.arange(nz.size), counts[nz])
        at = np.where(dist == mins[gid], np.arange(dist.size), dist.size)
        win[nz] = np.minimum.reduceat(at, starts)
        dmin[nz] = mins
    return win, dmin


def project_points(path: Path, points: object, *, hint: object = None) -> Projection:
    """Exact foot points of ``points`` on ``path`` (the contour error, signed).

    Parameters
    ----------
    path : Path
        The contour.
    points : array_like
        Shape (n, 2), m.
    hint : array_like, optional
        A guess of each point's arc length, shape (n,), m (e.g. the previous sample's
        ``s`` for a tracked trace; wrapped on a closed path, clipped on an open one). It
        may make the call faster; it never changes the result.

    Returns
    -------
    Projection
        ``s``, ``foot``, ``tangent``, ``normal``, signed ``distance``, ``segment``.

    Raises
    ------
    ValueError
        If ``points`` is not a finite (n, 2) array, or ``hint`` not a finite (n,) one.

    Notes
    -----
    Exact for lines and arcs (closed forms), to 1e-13 m for polynomial curves (or the
    coordinates' rounding, 64 ε times their magnitude, if larger); the module docstring
    gives the algorithm and why no nearer segment is ever missed.
    """
    idx = _index(path)
    p = _points(points)
    n = p.shape[0]
    seg = np.zeros(n, dtype=np.int64)
    par = np.zeros(n)
    dist = np.full(n, np.inf)
    ub = np.full(n, np.inf)
    n_lv = idx.usable_levels()
    first = np.zeros(n, dtype=np.int64)
    if hint is not None:
        h = np.array(hint, dtype=float)
        if h.shape != (n,) or not np.all(np.isfinite(h)):
            raise ValueError(
                f"hint must be a finite arc length (m) per point, shape ({n},), got shape "
                f"{h.shape}" + ("" if h.shape != (n,) else " with a value that is not finite")
            )
    radii = (idx.cell0 if n_lv else 0.0) * 4.0 ** np.arange(n_lv) * (1.0 - 1e-9) - idx.eps
    todo = np.arange(n)
    for lv in range(n_lv + 1):  # the grid levels, then the rest
        if lv == 1 and hint is not None and todo.size:
            # the points the finest grid did not settle: bound them by the hint's
            # segment and go straight to the level that certifies that bound
            ub[todo] = np.minimum(ub[todo], _hint_bound(idx, p[todo], h[todo]))
            first[todo] = np.searchsorted(radii, ub[todo])
        if lv == n_lv:
            if idx.n_seg <= _ALL_SEGMENTS:
                _settle_all(idx, p, todo, ub, seg, par, dist)
            else:
                _settle_tree(idx, p, todo, ub, seg, par, dist)
            break
        sel = todo[first[todo] <= lv]
        if not sel.size:
            continue
        grid = idx.level(lv)
        q = p[sel]
        counts, cand = grid.candidates(q)
        pt = np.repeat(np.arange(sel.size), counts)
        d, prm = idx.nearest(cand, pt, q[:, 0].copy(), q[:, 1].copy(), ub[sel], grid.radius)
        win, dmin = _select(counts, d)
        ok = (win >= 0) & (dmin <= grid.radius * (1.0 - 1e-9) - idx.eps)
        seg[sel[ok]], par[sel[ok]], dist[sel[ok]] = cand[win[ok]], prm[win[ok]], dmin[ok]
        ub[sel] = np.minimum(ub[sel], dmin)
        left = np.ones(n, dtype=bool)
        left[sel[ok]] = False
        todo = todo[left[todo]]
    return _finish(idx, p, seg, par, dist, radial=True)


def _settle_all(
    idx: PathIndex,
    p: np.ndarray,
    todo: np.ndarray,
    ub: np.ndarray,
    seg: np.ndarray,
    par: np.ndarray,
    dist: np.ndarray,
) -> None:
    """The points ``todo`` against every segment, in batches; results written in place."""
    m = idx.n_seg
    for lo in range(0, todo.size, idx.chunk):
        sel = todo[lo : lo + idx.chunk]
        counts = np.full(sel.size, m)
        cand = np.tile(np.arange(m), sel.size)
        pt = np.repeat(np.arange(sel.size), m)
        d, prm = idx.nearest(cand, pt, p[sel, 0], p[sel, 1], ub[sel])
        win, dmin = _select(counts, d)
        if not np.all(np.isfinite(dmin)):  # cannot happen: the bound is a path distance
            raise RuntimeError("projection lost every candidate (report this path and point)")
        seg[sel], par[sel], dist[sel] = cand[win], prm[win], dmin


def _settle_tree(
    idx: PathIndex,
    p: np.ndarray,
    todo: np.ndarray,
    ub: np.ndarray,
    seg: np.ndarray,
    par: np.ndarray,
    dist: np.ndarray,
) -> None:
    """The points ``todo`` against the segments the sample tree finds; results in place."""
    if not todo.size:
        return
    counts, cand, bound = idx.tree_candidates(p[todo], ub[todo])
    sel = todo
    pt = np.repeat(np.arange(sel.size), counts)
    d, prm = idx.nearest(cand, pt, p[sel, 0], p[sel, 1], bound)
    win, dmin = _select(counts, d)
    if not np.all(np.isfinite(dmin)):  # cannot happen: the nearest sample's segment is there
        raise RuntimeError("projection lost every candidate (report this path and point)")
    seg[sel], par[sel], dist[sel] = cand[win], prm[win], dmin


def _hint_bound(idx: PathIndex, p: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Distance (m) of each point to the segment at its hint, rounded up: a path distance."""
    k0 = idx.segment_at(h)
    d, _ = idx.nearest(
        k0, np.arange(k0.size), p[:, 0].copy(), p[:, 1].copy(), np.full(k0.size, np.inf)
    )
    return d * (1.0 + 1e-9) + idx.eps


def _finish(
    idx: PathIndex,
    p: np.ndarray,
    seg: np.ndarray,
    par: np.ndarray,
    dist: np.ndarray,
    *,
    radial: bool,
) -> Projection:
    """Foot, tangent, side and arc length of the winning (segment, parameter) per point.

    ``radial``: an arc's inner foot is the point's radial projection (exact); otherwise
    it is computed from the local arc length (the reference's minimiser).
    """
    n = seg.size
    kind = idx.kind[seg]
    sigma = par.copy()
    foot = np.zeros((n, 2))
    tan = np.zeros((n, 2))
    L = idx.length[seg]
    w = np.flatnonzero(kind == LINE)
    foot[w] = idx.line_foot(seg[w], sigma[w])
    tan[w] = np.take(idx.t, seg[w], axis=0)
    w = np.flatnonzero(kind == ARC)
    if w.size:
        k = seg[w]
        c, r = np.take(idx.a, k, axis=0), idx.radius[k]
        if radial:
            v = p[w] - c
            v /= np.maximum(np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2), 1e-300)[:, None]
        else:
            th = idx.theta0[k] + idx.sign[k] * sigma[w] / r
            v = np.column_stack([np.cos(th), np.sin(th)])
        foot[w] = c + r[:, None] * v
        tan[w] = idx.sign[k, None] * np.column_stack([-v[:, 1], v[:, 0]])
        s0, s1 = sigma[w] == 0.0, sigma[w] == L[w]
        foot[w[s0]], tan[w[s0]] = idx.start[k[s0]], idx.tan_start[k[s0]]
        foot[w[s1]], tan[w[s1]] = idx.end[k[s1]], idx.tan_end[k[s1]]
    w = np.flatnonzero(kind == CURVE)
    if w.size:
        assert idx.bank is not None
        foot[w] = idx.bank.point(seg[w], par[w])
        tan[w] = idx.bank.tangent(seg[w], par[w])
        sigma[w] = idx.bank.sigma(seg[w], par[w])
    normal = np.column_stack([-tan[:, 1], tan[:, 0]])
    # the side: along the normal, or at a junction along the sum of both segments' normals
    ref = tan.copy()
    at_start = (sigma == 0.0) & (idx.prev[seg] >= 0)
    at_end = (sigma == L) & (idx.next[seg] >= 0) & ~at_start
    ks, ke = seg[at_start], seg[at_end]
    ref[at_start] = np.take(idx.tan_start, ks, axis=0) + np.take(idx.tan_end, idx.prev[ks], axis=0)
    ref[at_end] = np.take(idx.tan_end, ke, axis=0) + np.take(idx.tan_start, idx.next[ke], axis=0)
    turned = ref[:, 0] ** 2 + ref[:, 1] ** 2 <= 1e-24  # the path turns back: own normal
    ref[turned] = tan[turned]
    side = (p[:, 0] - foot[:, 0]) * -ref[:, 1] + (p[:, 1] - foot[:, 1]) * ref[:, 0]
    signed = np.where(side >= 0.0, dist, -dist)
    return Projection(idx.breaks[seg] + sigma, foot, tan, normal, signed, seg)


def project_points_scalar(path: Path, points: object) -> Projection:
    """The slow reference of :func:`project_points`: one bounded scalar search at a time.

    For every point and every segment, `scipy.optimize.minimize_scalar`
    (``method="bounded"``, Brent's method, ``xatol`` 1e-15 of the interval) minimises the
    distance over the segment's parameter: a line's arc length (convex: one search); an
    arc's arc length in pieces of at most 90° (on an arc of at most 180° the distance has
    one minimum); a curve's u in 32 equal pieces (a search per piece: not a proof for a
    wild curve). The pieces' ends are candidates too. This is a baseline for tests and
    benchmarks (a Python loop per point and piece, thousands of times slower), not a tool;
    the side, tangent and arc length follow the same convention as `project_points`.

    Brent's termination is ``sqrt(ε)|x| + xatol/3`` in the parameter; at an inner minimum
    the distance is second order in that error (far below 1e-10 m at the scales of
    interest), at a piece end the end itself is evaluated.
    """
    idx = _index(path)
    p = _points(points)
    n = p.shape[0]
    seg = np.zeros(n, dtype=np.int64)
    par = np.zeros(n)
    dist = np.full(n, np.inf)
    pieces = [_scalar_pieces(s) for s in path.segments]
    for i in range(n):
        x, y = float(p[i, 0]), float(p[i, 1])
        for k, (fn, edges) in enumerate(pieces):
            for lo, hi in itertools.pairwise(edges.tolist()):
                t, v = _scalar_min(fn, lo, hi, x, y)
                if v < dist[i]:
                    dist[i], seg[i], par[i] = v, k, t
    return _finish(idx, p, seg, par, dist, radial=False)


def _scalar_min(
    fn: Callable[[float], tuple[float, float]], lo: float, hi: float, x: float, y: float
) -> tuple[float, float]:
    """Parameter and distance of the nearest point of ``fn`` on ``[lo, hi]`` to (x, y)."""

    def f(t: float) -> float:
        qx, qy = fn(t)
        return math.hypot(x - qx, y - qy)

    res = minimize_scalar(
        f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-15 * (hi - lo)}
    )
    best = min((f(lo), lo), (f(hi), hi), (float(res.fun), float(res.x)))
    return best[1], best[0]


def _scalar_pieces(s: Segment) -> tuple[Callable[[float], tuple[float, float]], np.ndarray]:
    """A segment's point function of its parameter and the edges of its search pieces."""
    if isinstance(s, LineSegment):
        (ax, ay), (bx, by), L = s.p0.tolist(), s.p1.tolist(), s.length

        def line(t: float) -> tuple[float, float]:
            return ax + (bx - ax) * (t / L), ay + (by - ay) * (t / L)

        return line, np.array([0.0, L])
    if isinstance(s, ArcSegment):
        (cx, cy), r, th0 = s.center.tolist(), s.radius, s.theta0
        sg = math.copysign(1.0, s.sweep)

        def arc(t: float) -> tuple[float, float]:
            th = th0 + sg * t / r
            return cx + r * math.cos(th), cy + r * math.sin(th)

        n = max(1, math.ceil(abs(s.sweep) / (0.5 * math.pi) - 1e-12))
        return arc, np.linspace(0.0, s.length, n + 1)

    assert isinstance(s, CurveSegment)
    cx, cy = s.coef[::-1, 0].tolist(), s.coef[::-1, 1].tolist()

    def curve(t: float) -> tuple[float, float]:
        # Clenshaw's recurrence in plain floats (a NumPy call per value costs more)
        x2 = 4.0 * t - 2.0
        bx1 = bx2 = by1 = by2 = 0.0
        for ax, ay in zip(cx[:-1], cy[:-1], strict=True):
            bx1, bx2 = ax + x2 * bx1 - bx2, bx1
            by1, by2 = ay + x2 * by1 - by2, by1
        x = 0.5 * x2
        return cx[-1] + x * bx1 - bx2, cy[-1] + x * by1 - by2

    return curve, np.linspace(0.0, 1.0, 33)
