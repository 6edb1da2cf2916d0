"""Nearest points on polynomial curves (`CurveSegment`), many (point, curve) pairs at once.

The squared distance ``D(u) = |f(u) − p|²`` of a point ``p`` to a curve ``f(u), u ∈ [0, 1]``
is minimised by branch and bound on ``u``, vectorised over every pair and every interval:

1. the ends ``u = 0`` and ``u = 1`` are candidates, and ``[0, 1]`` is cut into 8 equal
   intervals;
2. each round evaluates ``f`` at the midpoint ``m`` of every live interval
   ``[m − h, m + h]`` (Clenshaw) and makes it a candidate; an interval with
   ``d(m) − M1 h`` above the pair's upper bound is dropped at once (``M1 ≥ max|f'|``);
   the others get ``f'`` and ``f''`` there, and rigorous bounds from the global
   coefficient bounds ``M2 ≥ max|f''|``, ``M3 ≥ max|f'''|`` (sums of the Chebyshev
   coefficients' magnitudes, ``|T_k| ≤ 1``): speed ``≤ s1 = |f'(m)| + M2 h``,
   ``|f''| ≤ s2 = |f''(m)| + M3 h``, distance ``≤ dmax = d(m) + s1 h``; the lower bound of
   the distance on the interval is the larger of ``d(m) − s1 h`` (Lipschitz) and
   ``sqrt(D(m) − |D'(m)| h − (s1² + dmax s2) h²)`` (Taylor, ``|D''| / 2 ≤ s1² + dmax s2``);
3. an interval whose lower bound exceeds the pair's upper bound (the best candidate so
   far, or a smaller bound the caller knows: another segment's distance, or the radius
   beyond which the caller has no use for the distance) is dropped: it cannot hold the
   minimum;
4. an interval on which ``D`` is provably convex, ``D''/2 ≥ |f'(m)|² + (f(m) − p)·f''(m)
   − (3 s1 s2 + dmax M3) h > 0``, holds at most one local minimum: at the end towards
   which ``D'`` points if ``D'`` keeps its sign there, else at the root of
   ``D'/2 = (f − p)·f'`` in the bracket, found by Newton steps (false position, then
   bisection, when a step leaves the bracket) until the foot moves by less than
   ``tol / 1000``;
5. an interval whose midpoint is within ``tol`` of its lower bound is done (its points
   cannot beat the midpoint by more than ``tol``); any other interval is halved. Where
   ``D`` is flat (a point near a centre of curvature: the Taylor bounds cannot see the
   cancellation) an interval halved twice gets a third bound, ``e_0 − Σ|e_k|`` from the
   Chebyshev coefficients ``e_k`` of ``D`` itself on the interval (a polynomial of
   degree 2d, interpolated exactly at 2d + 1 points), which settles it at once.

The minimum is in some interval that is never dropped (its lower bound is at most the
minimum, which is at most every upper bound), and that interval ends in Newton's root or
in a midpoint within ``tol``: the result is the global minimum to ``tol`` (Newton's roots
to rounding). Every decision about an interval except the drop depends on the interval
alone, so a different upper bound (a ``hint``) never changes which candidate wins. The
work is adaptive: a point near a curve is settled in one or two rounds (its intervals are
convex), a point far from it drops most intervals at once.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from microfab.geometry.segments import GL_W, GL_X, N_PANELS, CurveSegment

__all__ = ["CurveBank"]

#: Largest number of halving rounds; ``h`` is then ~1e-20 of the first intervals, far
#: below any ``tol`` the caller can ask for, so the queue has emptied long before.
_MAX_ROUNDS = 80
_NEWTON_ITERS = 60
#: Relative slack on upper bounds and the convexity test (rounding of the bounds).
_SLACK = 1e-9
_COEF_BOUND_PAD = 1.0 + 1e-12  # the coefficient sums are rounded too


def _bound(c: np.ndarray) -> np.ndarray:
    """``max |f(u)|`` bound of Chebyshev series ``c`` (g, k + 1, 2): hypot of the sums."""
    s = np.abs(c).sum(axis=1)
    return np.hypot(s[:, 0], s[:, 1]) * _COEF_BOUND_PAD


def _clenshaw(ct: np.ndarray, rows: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    """Rows of Chebyshev series at ``x``: ``ct`` (k + 1, g, 2) by term; -> (n, 2).

    ``rows`` None: the group has one curve (no gathering).
    """

    def term(k: int) -> np.ndarray:
        return ct[k, 0] if rows is None else np.take(ct[k], rows, axis=0)

    n_terms = ct.shape[0]
    if n_terms == 1:
        return np.broadcast_to(term(0), (x.size, 2)).copy()
    x2 = 2.0 * x[:, None]
    b1 = np.zeros((x.size, 2))
    b2 = np.zeros((x.size, 2))
    for k in range(n_terms - 1, 0, -1):
        b1, b2 = term(k) + x2 * b1 - b2, b1
    return term(0) + x[:, None] * b1 - b2


class _Group:
    """Curves of one degree: coefficients by term, derivative bounds, length tables."""

    def __init__(self, curves: Sequence[CurveSegment]) -> None:
        c0 = np.stack([c.coef for c in curves])
        d1, d2, d3 = (np.stack(d) for d in zip(*(c.derivative_coefs for c in curves), strict=True))
        # by term first, so that one term of many rows is a contiguous gather
        self.ct = [np.ascontiguousarray(np.moveaxis(c, 1, 0)) for c in (c0, d1, d2, d3)]
        self.m0, self.m1, self.m2, self.m3 = _bound(c0), _bound(d1), _bound(d2), _bound(d3)
        self.m2_xy = np.abs(d2).sum(axis=1) * _COEF_BOUND_PAD  # per coordinate, (g, 2)
        self.table = np.stack([c.length_table for c in curves])
        self.degree = curves[0].degree
        self.single = len(curves) == 1
        self.n0 = 8
        # Chebyshev points and the matrix from values there to coefficients, degree 2d
        k = 2 * self.degree + 1
        nodes = np.cos(np.pi * (np.arange(k) + 0.5) / k)
        basis = np.cos(np.outer(np.arange(k) + 0.5, np.arange(k)) * np.pi / k) * (2.0 / k)
        basis[:, 0] *= 0.5
        self.dct = (nodes, basis)

    def eval(self, k: int, rows: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The k-th u-derivative of the curves ``rows`` at ``u``, shape (n, 2)."""
        return _clenshaw(self.ct[k], None if self.single else rows, 2.0 * u - 1.0)

    # ------------------------------------------------------------- minimisation
    def nearest(
        self, rows: np.ndarray, p: np.ndarray, ub: np.ndarray, tol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Parameter and distance of the nearest point, per pair (branch and bound).

        A pair whose every interval is dropped against ``ub`` returns its best candidate
        so far, which is then larger than ``ub`` (the caller keeps a nearer segment).
        """
        n = rows.size
        d_lo = np.hypot(*(self.eval(0, rows, np.zeros(n)) - p).T)
        d_hi = np.hypot(*(self.eval(0, rows, np.ones(n)) - p).T)
        best_u = np.where(d_hi < d_lo, 1.0, 0.0)
        best_d = np.minimum(d_lo, d_hi)
        ub = np.asarray(ub, dtype=float)
        n0 = self.n0
        item = np.repeat(np.arange(n), n0)
        a = np.tile(np.arange(n0) / n0, n)
        b = np.tile(np.arange(1, n0 + 1) / n0, n)
        for _ in range(_MAX_ROUNDS):
            if item.size == 0:
                return best_u, best_d
            r_rows = rows[item]
            m, h = 0.5 * (a + b), 0.5 * (b - a)
            r = self.eval(0, r_rows, m) - p[item]
            dm = np.sqrt(r[:, 0] ** 2 + r[:, 1] ** 2)
            _improve(best_u, best_d, item, m, dm)
            bound = np.minimum(ub[item], best_d[item]) * (1.0 + _SLACK) + tol
            # first the cheap Lipschitz bound with the curve's speed bound M1
            w = np.flatnonzero(dm - self.m1[r_rows] * h <= bound)
            item, r_rows, a, b, m, h = item[w], r_rows[w], a[w], b[w], m[w], h[w]
            r, dm, bound = r[w], dm[w], bound[w]
            f1 = self.eval(1, r_rows, m)
            f2 = self.eval(2, r_rows, m)
            sp = np.sqrt(f1[:, 0] ** 2 + f1[:, 1] ** 2)
            s1 = sp + self.m2[r_rows] * h
            s2 = np.sqrt(f2[:, 0] ** 2 + f2[:, 1] ** 2) + self.m3[r_rows] * h
            dmax = dm + s1 * h
            g = r[:, 0] * f1[:, 0] + r[:, 1] * f1[:, 1]
            gp = sp * sp + r[:, 0] * f2[:, 0] + r[:, 1] * f2[:, 1]  # D''/2 at m
            quad = s1 * s1 + dmax * s2
            lb_taylor = dm * dm - 2.0 * np.abs(g) * h - quad * h * h
            lb = np.maximum(dm - s1 * h, np.sqrt(np.maximum(lb_taylor, 0.0)))
            keep = lb <= bound
            curv = gp - (3.0 * s1 * s2 + dmax * self.m3[r_rows]) * h
            convex = keep & (curv > _SLACK * quad)
            if np.any(convex):
                c = np.flatnonzero(convex)
                u_c, d_c = self._newton(r_rows[c], p[item[c]], a[c], b[c], m[c], g[c], gp[c], tol)
                _improve(best_u, best_d, item[c], u_c, d_c)
            # halved twice and still no proof, with D nearly stationary at m: maybe flat
            # (a point near a centre of curvature), where only the interpolated
            # polynomial sees the cancellation
            flat = (h <= 0.25 / n0) & (np.abs(g) < 0.25 * quad * h)
            hard = np.flatnonzero(keep & ~convex & (dm - lb > tol) & flat)
            if hard.size:
                lb_p = self._poly_bound(r_rows[hard], p[item[hard]], m[hard], h[hard])
                lb[hard] = np.maximum(lb[hard], lb_p)
                keep &= lb <= bound
            split = keep & ~convex & (dm - lb > tol)
            item = np.repeat(item[split], 2)
            lo, mid, hi = a[split], m[split], b[split]
            a = np.column_stack([lo, mid]).ravel()
            b = np.column_stack([mid, hi]).ravel()
        raise RuntimeError("curve projection did not converge (report this path and point)")

    def _poly_bound(
        self, rows: np.ndarray, p: np.ndarray, m: np.ndarray, h: np.ndarray
    ) -> np.ndarray:
        """Lower bound of the distance on ``[m − h, m + h]`` from D's Chebyshev expansion.

        ``D(u) = |f(u) − p|²`` is a polynomial of degree 2d: interpolation at 2d + 1
        Chebyshev points of the interval gives its coefficients ``e_k`` exactly (up to
        rounding), and ``D ≥ e_0 − Σ_{k≥1} |e_k|`` there (``|T_k| ≤ 1``), less a rounding
        margin of ``8 (2d + 1) ε (max D + 2 sqrt(max D) X)``, ``X`` the size of the
        coordinates (``f − p`` is rounded to ``ε X``).
        """
        nodes, basis = self.dct
        k = nodes.size
        u = (m[:, None] + h[:, None] * nodes[None, :]).ravel()
        rr = np.repeat(rows, k)
        r = self.eval(0, rr, u) - np.repeat(p, k, axis=0)
        dv = (r[:, 0] ** 2 + r[:, 1] ** 2).reshape(-1, k)
        e = dv @ basis  # (n, 2d + 1) coefficients
        # rounding: of the sums, and of f - p (absolute: epsilon times the coordinates)
        big = dv.max(axis=1)
        coords = self.m0[rows] + np.abs(p).max(axis=1)
        margin = 8.0 * k * np.finfo(float).eps * (big + 2.0 * np.sqrt(big) * coords)
        lb_d = e[:, 0] - np.abs(e[:, 1:]).sum(axis=1) - margin
        return np.sqrt(np.maximum(lb_d, 0.0))

    def _newton(
        self,
        rows: np.ndarray,
        p: np.ndarray,
        a: np.ndarray,
        b: np.ndarray,
        m: np.ndarray,
        gm: np.ndarray,
        gpm: np.ndarray,
        tol: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Minimiser of a convex ``D`` on ``[a, b]`` per item: safeguarded Newton on D'/2.

        ``g = D'/2 = (f − p)·f'`` increases on the interval. Its sign at the midpoint
        ``m`` (``gm``, with ``gpm = D''/2`` there) tells on which side the minimum lies;
        the end on that side decides whether it is that end (``g`` keeps its sign) or a
        root in between, bracketed and found by Newton steps that fall back to bisection.
        """
        u = m.copy()
        right = gm < 0.0
        end = np.where(right, b, a)
        ge = self._g(rows, p, end)
        at_end = np.where(right, ge <= 0.0, ge >= 0.0) & (gm != 0.0)
        u[at_end] = end[at_end]
        live = np.flatnonzero(~at_end & (gm != 0.0))
        lo = np.where(right, m, a)[live]
        hi = np.where(right, b, m)[live]
        g_lo = np.where(right, gm, ge)[live]
        g_hi = np.where(right, ge, gm)[live]
        x = m[live] - gm[live] / gpm[live]
        for _ in range(_NEWTON_ITERS):
            # outside the bracket: false position (the root may sit next to an end),
            # else bisection
            fp = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
            fp = np.where((fp > lo) & (fp < hi), fp, 0.5 * (lo + hi))
            x = np.where((x > lo) & (x < hi), x, fp)
            rr, pp = rows[live], p[live]
            r = self.eval(0, rr, x) - pp
            f1 = self.eval(1, rr, x)
            f2 = self.eval(2, rr, x)
            gx = r[:, 0] * f1[:, 0] + r[:, 1] * f1[:, 1]
            sp2 = f1[:, 0] ** 2 + f1[:, 1] ** 2
            gp = sp2 + r[:, 0] * f2[:, 0] + r[:, 1] * f2[:, 1]
            neg, pos = gx < 0.0, gx > 0.0
            lo, g_lo = np.where(neg, x, lo), np.where(neg, gx, g_lo)
            hi, g_hi = np.where(pos, x, hi), np.where(pos, gx, g_hi)
            step = gx / gp  # gp > 0: D is convex on the interval
            # converged: the Newton step moves the foot by less than tol / 1000
            done = (gx == 0.0) | (np.abs(step) * np.sqrt(sp2) <= 1e-3 * tol) | (hi - lo <= 4e-16)
            u[live[done]] = np.clip(x[done] - step[done], lo[done], hi[done])
            keep = ~done
            live, x = live[keep], (x - step)[keep]
            lo, hi, g_lo, g_hi = lo[keep], hi[keep], g_lo[keep], g_hi[keep]
            if live.size == 0:
                break
        u[live] = np.clip(x, lo, hi)  # not reached in practice: the bracket halves at worst
        r = self.eval(0, rows, u) - p
        return u, np.sqrt(r[:, 0] ** 2 + r[:, 1] ** 2)

    def _g(self, rows: np.ndarray, p: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``D'/2 = (f(u) − p)·f'(u)``."""
        r = self.eval(0, rows, u) - p
        f1 = self.eval(1, rows, u)
        return r[:, 0] * f1[:, 0] + r[:, 1] * f1[:, 1]

    # ------------------------------------------------------------- arc length
    def sigma(self, rows: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Local arc length at ``u`` (m): the length table plus one Gauss–Legendre panel."""
        tab = self.table[rows]
        j = np.clip(np.floor(u * N_PANELS).astype(np.int64), 0, N_PANELS - 1)
        u_lo = j / N_PANELS
        w = u - u_lo
        nodes = u_lo[:, None] + w[:, None] * (GL_X[None, :] + 1.0) / 2.0
        sp = np.empty(nodes.shape)
        for q in range(nodes.shape[1]):
            d1 = self.eval(1, rows, nodes[:, q])
            sp[:, q] = np.hypot(d1[:, 0], d1[:, 1])
        out = tab[np.arange(rows.size), j] + (sp * GL_W).sum(axis=1) * w / 2.0
        return np.where(u >= 1.0, tab[:, -1], np.where(u <= 0.0, 0.0, out))

    def tangent(self, rows: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Unit tangents at ``u``; at a stop (``f' = 0``) the direction of ``±f''``.

        A speed below 1e-13 of the curve's speed bound is a stop: what is left of ``f'``
        there is rounding, and its direction means nothing.
        """
        d1 = self.eval(1, rows, u)
        sp = np.hypot(d1[:, 0], d1[:, 1])
        stop = sp <= 1e-13 * self.m1[rows]  # zero but for the rounding of f'

        if np.any(stop):
            # f'(u + e) ≈ e f''(u): leaving a stop along f'', arriving at u = 1 along −f''
            d2 = self.eval(2, rows[stop], u[stop])
            d1[stop] = np.where((u[stop] >= 1.0)[:, None], -d2, d2)
            sp = np.hypot(d1[:, 0], d1[:, 1])
        return d1 / np.maximum(sp, 1e-300)[:, None]

    # ------------------------------------------------------------- bounding
    def piece_boxes(self, rows: np.ndarray, n_pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes that hold each piece of the curves cut evenly in u, and the pieces' curve.

        A piece ``[u0, u1]`` lies in the box of its end points grown by ``M2 (u1 − u0)² / 8``
        per coordinate (the chord's interpolation error with ``|x''| ≤ M2``), so the boxes
        hold the curve whatever its shape. Returns boxes (k, 4) and row per box (k,).
        """
        owner = np.repeat(rows, n_pieces)
        start = np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
        j = np.arange(owner.size) - start
        npc = np.repeat(n_pieces, n_pieces)
        u0, u1 = j / npc, (j + 1) / npc
        q0, q1 = self.eval(0, owner, u0), self.eval(0, owner, u1)
        grow = self.m2_xy[owner] * ((1.0 / npc) ** 2 / 8.0)[:, None]
        lo = np.minimum(q0, q1) - grow
        hi = np.maximum(q0, q1) + grow
        return np.column_stack([lo, hi]), owner


def _improve(
    best_u: np.ndarray, best_d: np.ndarray, item: np.ndarray, u: np.ndarray, d: np.ndarray
) -> None:
    """Keep, per pair, the smaller distance (ties: the smaller u), in place.

    ``item`` (the pair of each candidate) is sorted: the intervals are made pair after
    pair and keep that order through every filter and split.
    """
    if item.size == 0:
        return
    head = np.ones(item.size, dtype=bool)
    head[1:] = item[1:] != item[:-1]
    starts = np.flatnonzero(head)
    gid = np.cumsum(head) - 1
    dmin = np.minimum.reduceat(d, starts)
    umin = np.minimum.reduceat(np.where(d == dmin[gid], u, np.inf), starts)
    k = item[starts]
    better = (dmin < best_d[k]) | ((dmin == best_d[k]) & (umin < best_u[k]))
    best_d[k[better]] = dmin[better]
    best_u[k[better]] = umin[better]


class CurveBank:
    """The curve segments of a path, grouped by degree for vectorised evaluation.

    Parameters
    ----------
    curves : sequence of CurveSegment
        The curves, in any order.
    seg_index : sequence of int
        Each curve's index among the path's segments.
    """

    def __init__(self, curves: Sequence[CurveSegment], seg_index: Sequence[int]) -> None:
        by_deg: dict[int, list[int]] = {}
        for i, c in enumerate(curves):
            by_deg.setdefault(c.degree, []).append(i)
        seg = np.asarray(seg_index, dtype=np.int64)
        n_seg = int(seg.max()) + 1 if seg.size else 0
        self.group_of = np.full(n_seg, -1, dtype=np.int64)
        self.row_of = np.full(n_seg, -1, dtype=np.int64)
        self.groups: list[_Group] = []
        for g, (_, idx) in enumerate(sorted(by_deg.items())):
            self.groups.append(_Group([curves[i] for i in idx]))
            self.group_of[seg[idx]] = g
            self.row_of[seg[idx]] = np.arange(len(idx))
        self.m1 = np.zeros(n_seg)
        for g, grp in enumerate(self.groups):
            self.m1[self.group_of == g] = grp.m1[self.row_of[self.group_of == g]]

    def _split(self, seg: np.ndarray) -> list[tuple[_Group, np.ndarray, np.ndarray]]:
        """(group, positions in seg, rows) for each group present in ``seg``."""
        g_of = self.group_of[seg]
        out = []
        for g, grp in enumerate(self.groups):
            where = np.flatnonzero(g_of == g)
            if where.size:
                out.append((grp, where, self.row_of[seg[where]]))
        return out

    def nearest(
        self, seg: np.ndarray, p: np.ndarray, ub: np.ndarray, tol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Curve parameter u and distance (m) of the nearest point, per (segment, point) pair.

        ``ub`` (m) is a known upper bound of the distance of each pair's point to the path:
        intervals that cannot beat it are dropped, and such a pair may return any distance
        above it. The distance is the global minimum over the curve to ``tol`` (m).
        """
        u = np.zeros(seg.size)
        d = np.zeros(seg.size)
        for grp, where, rows in self._split(seg):
            u[where], d[where] = grp.nearest(rows, p[where], ub[where], tol)
        return u, d

    def point(self, seg: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Points ``f(u)``, shape (n, 2), m."""
        out = np.zeros((seg.size, 2))
        for grp, where, rows in self._split(seg):
            out[where] = grp.eval(0, rows, u[where])
        return out

    def sigma(self, seg: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Local arc length at ``u``, m."""
        out = np.zeros(seg.size)
        for grp, where, rows in self._split(seg):
            out[where] = grp.sigma(rows, u[where])
        return out

    def tangent(self, seg: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Unit tangents at ``u``, shape (n, 2)."""
        out = np.zeros((seg.size, 2))
        for grp, where, rows in self._split(seg):
            out[where] = grp.tangent(rows, u[where])
        return out

    def piece_boxes(self, seg: np.ndarray, n_pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (k, 4) holding the curves ``seg`` cut into ``n_pieces`` each; segment per box."""
        boxes, owners = [], []
        for grp, where, rows in self._split(seg):
            b, own_rows = grp.piece_boxes(rows, n_pieces[where])
            boxes.append(b)
            # map rows back to segment indices
            seg_of_row = np.empty(grp.table.shape[0], dtype=np.int64)
            seg_of_row[rows] = seg[where]
            owners.append(seg_of_row[own_rows])
        if not boxes:
            return np.zeros((0, 4)), np.zeros(0, dtype=np.int64)
        return np.vstack(boxes), np.concatenate(owners)
