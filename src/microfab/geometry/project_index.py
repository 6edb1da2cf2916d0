"""The segments of a `Path` packed for projection, and the grids that pick candidates.

:class:`PathIndex` holds every segment's numbers in arrays indexed by the segment's
position in the path (so that a (point, segment) pair gathers its numbers directly), the
exact distance of a point to a line or an arc (closed form, vectorised over pairs), the
polynomial curves as a :class:`~microfab.geometry.project_curve.CurveBank`, a stack of
uniform grids (:class:`GridLevel`) whose cells list the segments that come within a
radius ``ρ`` of the cell, and a k-d tree of path samples for the points no grid settles
(:meth:`PathIndex.tree_candidates`).

A grid's lists hold every segment near the cell: each segment is cut into pieces no
longer than the cell, and each piece into a box that holds it (a line piece: the box of
its ends; an arc piece of at most 90°: the box of its chord grown by the sagitta; a curve
piece: the box of its chord grown by ``M2 Δu² / 8``, ``M2`` a bound of ``|f''|``). A piece
is registered in every cell that its box, grown by ``ρ``, touches. So if any point of a
segment is within ``ρ`` of a cell, the segment is in the cell's list.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from microfab.geometry.path import Path
from microfab.geometry.project_curve import CurveBank
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment

__all__ = ["ARC", "CURVE", "LINE", "GridLevel", "PathIndex"]

LINE, ARC, CURVE = 0, 1, 2
_TWO_PI = 2.0 * math.pi
#: Most pieces a curve is cut into for a grid (its speed bound may overstate its length;
#: longer pieces only make bigger boxes). Lines and arcs need at most 2^20 in all.
_MAX_CURVE_PIECES = 1 << 16
#: Cell size of a coarser grid over the finer one's.
_LEVEL_RATIO = 4.0
#: Most segments a cell of the finest grid lists on average (else its cell is halved).
_MEAN_LIST = 8
#: Most segments a cell lists on average for its grid to be used (else the k-d tree).
_MAX_MEAN_LIST = 64
#: Most (point, segment) pairs evaluated at once when every segment is a candidate.
_CHUNK_PAIRS = 1 << 20


def _sorted_unique(a: np.ndarray) -> np.ndarray:
    """``np.unique`` of an integer array by one sort (NumPy's own is far slower at 1e7)."""
    a = np.sort(a)
    return a[np.append(True, a[1:] != a[:-1])] if a.size else a


@dataclass(frozen=True, eq=False)
class GridLevel:
    """A uniform grid of square cells of side ``cell`` (m) listing segments within ``cell``.

    ``keys`` are the sorted codes ``ix * ny + iy`` of the cells that list something,
    ``offsets[j]:offsets[j + 1]`` their slice of ``segs`` (segment indices, ascending).
    """

    cell: float
    x0: float
    y0: float
    nx: int
    ny: int
    keys: np.ndarray
    offsets: np.ndarray
    segs: np.ndarray

    @property
    def radius(self) -> float:
        """``ρ``: every segment within this distance (m) of a cell is in its list."""
        return self.cell

    def candidates(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Candidate count per point (n,) and the candidates, point after point (ascending)."""
        with np.errstate(invalid="ignore"):
            fx = np.floor((p[:, 0] - self.x0) / self.cell)
            fy = np.floor((p[:, 1] - self.y0) / self.cell)
        inside = (fx >= 0) & (fx < self.nx) & (fy >= 0) & (fy < self.ny)
        key = np.where(inside, fx, 0).astype(np.int64) * self.ny + np.where(inside, fy, 0).astype(
            np.int64
        )
        pos = np.searchsorted(self.keys, key)
        pos_c = np.minimum(pos, self.keys.size - 1)
        found = inside & (pos < self.keys.size) & (self.keys[pos_c] == key)
        lo = np.where(found, self.offsets[pos_c], 0)
        counts = np.where(found, self.offsets[pos_c + 1] - self.offsets[pos_c], 0)
        first = np.cumsum(counts) - counts
        flat = np.arange(int(counts.sum())) - np.repeat(first - lo, counts)
        return counts, self.segs[flat]


class PathIndex:
    """A path's segments as arrays, for the exact projection of many points.

    Parameters
    ----------
    path : Path
        The path.
    """

    def __init__(self, path: Path) -> None:
        segs = path.segments
        m = len(segs)
        self.closed = path.closed  # no reference to the path: it keys a weak cache of us
        self.n_seg = m
        self.kind = np.array(
            [
                LINE if isinstance(s, LineSegment) else ARC if isinstance(s, ArcSegment) else CURVE
                for s in segs
            ],
            dtype=np.int8,
        )
        self.length = np.array([s.length for s in segs])
        self.breaks = np.asarray(path.breaks)
        self.start = np.array([s.start for s in segs], dtype=float).reshape(m, 2)
        self.end = np.array([s.end for s in segs], dtype=float).reshape(m, 2)
        self.a = np.zeros((m, 2))  # line p0, arc centre
        self.t = np.zeros((m, 2))  # line unit direction
        self.radius = np.ones(m)
        self.theta0 = np.zeros(m)
        self.sweep = np.zeros(m)
        lines = np.flatnonzero(self.kind == LINE)
        self.a[lines] = self.start[lines]
        self.t[lines] = (self.end[lines] - self.start[lines]) / self.length[lines, None]
        arcs = np.flatnonzero(self.kind == ARC)
        if arcs.size:
            arc_segs = [segs[k] for k in arcs.tolist()]
            num = np.array(
                [(*a.center.tolist(), a.radius, a.theta0, a.sweep) for a in arc_segs],  # type: ignore[union-attr]
                dtype=float,
            ).reshape(-1, 5)
            self.a[arcs] = num[:, :2]
            self.radius[arcs], self.theta0[arcs], self.sweep[arcs] = num[:, 2], num[:, 3], num[:, 4]
        curve_idx = np.flatnonzero(self.kind == CURVE).tolist()
        curves = [segs[k] for k in curve_idx]
        assert all(isinstance(c, CurveSegment) for c in curves)
        self.sign = np.sign(self.sweep)
        self.abs_sweep = np.abs(self.sweep)
        self.n_kinds = int(np.count_nonzero(np.bincount(self.kind, minlength=3)))
        # one contiguous array per coordinate: a gather per pair is then cheap
        self.col = {
            "ax": self.a[:, 0].copy(),
            "ay": self.a[:, 1].copy(),
            "tx": self.t[:, 0].copy(),
            "ty": self.t[:, 1].copy(),
            "sx": self.start[:, 0].copy(),
            "sy": self.start[:, 1].copy(),
            "ex": self.end[:, 0].copy(),
            "ey": self.end[:, 1].copy(),
            "ux0": np.cos(self.theta0),
            "uy0": np.sin(self.theta0),
        }
        self.bank = CurveBank(curves, curve_idx) if curves else None
        self.curve_idx = np.asarray(curve_idx, dtype=np.int64)
        idx = np.arange(m)
        self.tan_start = self.end_tangent(idx, at_end=False)
        self.tan_end = self.end_tangent(idx, at_end=True)
        self.prev = idx - 1
        self.next = idx + 1
        if path.closed:
            self.prev[0], self.next[-1] = m - 1, 0
        else:
            self.prev[0], self.next[-1] = -1, -1
        # whole-segment boxes: a line's from its ends, the others' from 16 pieces
        boxes, owner = self._pieces(np.where(self.kind == LINE, 1, 16))
        self.box = np.full((m, 4), np.nan)
        self.box[:, :2] = np.inf
        self.box[:, 2:] = -np.inf
        np.minimum.at(self.box[:, 0], owner, boxes[:, 0])
        np.minimum.at(self.box[:, 1], owner, boxes[:, 1])
        np.maximum.at(self.box[:, 2], owner, boxes[:, 2])
        np.maximum.at(self.box[:, 3], owner, boxes[:, 3])
        lo, hi = self.box[:, :2].min(axis=0), self.box[:, 2:].max(axis=0)
        self.reach = float(np.max(np.abs(np.concatenate([lo, hi]))))
        self.size = float(np.max(hi - lo))
        #: Rounding of coordinates (m): boxes grow and tests loosen by this much.
        self.eps = 64.0 * np.finfo(float).eps * max(self.reach, 1e-300)
        #: Accuracy of a curve's nearest distance (m): 1e-13 m, or the rounding if larger.
        self.curve_tol = max(1e-13, self.eps)
        # finest cells: the median segment, at most 1/32 of the size (short lists), at
        # least 2^-16 of it (a bounded number of levels) and 2^-20 of the path's length
        # (a bounded number of pieces: their boxes are the grids' entries)
        median = float(np.median(self.length))
        self._cell_floor = max(self.size * 2.0**-16, float(self.breaks[-1]) * 2.0**-20)
        self._cell_start = min(max(median, self._cell_floor), self.size / 32.0)
        self._cell0: float | None = None
        self._usable: int | None = None
        self._levels: list[GridLevel] = []
        self._tree: tuple[cKDTree, np.ndarray, float] | None = None

    def segment_at(self, s: np.ndarray) -> np.ndarray:
        """Segment at arc length ``s`` (m; wrapped on a closed path, clipped on an open one)."""
        total = float(self.breaks[-1])
        sv = np.mod(s, total) if self.closed else np.clip(s, 0.0, total)
        k = np.searchsorted(self.breaks, sv, side="right") - 1
        return np.clip(k, 0, self.n_seg - 1)

    # ------------------------------------------------------------------ pairs
    def end_tangent(self, seg: np.ndarray, *, at_end: bool) -> np.ndarray:
        """Unit tangents of segments ``seg`` at their start (``at_end`` False) or end."""
        out = np.zeros((seg.size, 2))
        k = self.kind[seg]
        m = k == LINE
        out[m] = self.t[seg[m]]
        m = k == ARC
        th = self.theta0[seg[m]] + (self.sweep[seg[m]] if at_end else 0.0)
        out[m] = self.sign[seg[m], None] * np.column_stack([-np.sin(th), np.cos(th)])
        m = k == CURVE
        if np.any(m):
            assert self.bank is not None
            out[m] = self.bank.tangent(seg[m], np.full(int(m.sum()), 1.0 if at_end else 0.0))
        return out

    def line_pairs(
        self, seg: np.ndarray, px: np.ndarray, py: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distance and local arc length of the nearest point of lines ``seg`` (closed form)."""
        ax, ay = self.col["ax"][seg], self.col["ay"][seg]
        tx, ty = self.col["tx"][seg], self.col["ty"][seg]
        L = self.length[seg]
        sigma = np.clip((px - ax) * tx + (py - ay) * ty, 0.0, L)
        fx, fy = ax + sigma * tx, ay + sigma * ty
        end = sigma == L  # the end point exactly, not p0 + L t
        fx[end], fy[end] = self.col["ex"][seg[end]], self.col["ey"][seg[end]]
        dx, dy = px - fx, py - fy
        return np.sqrt(dx * dx + dy * dy), sigma

    def line_foot(self, seg: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Points of lines at local arc length ``sigma``; the end point exactly at the end."""
        foot = np.take(self.a, seg, axis=0) + sigma[:, None] * np.take(self.t, seg, axis=0)
        end = sigma == self.length[seg]
        foot[end] = self.end[seg[end]]
        return foot

    def arc_pairs(
        self, seg: np.ndarray, px: np.ndarray, py: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distance and local arc length of the nearest point of arcs ``seg`` (closed form).

        The nearest point of the circle is the radial one, at the point's angle; if that
        angle is outside the sweep, the distance to the circle grows with the angle away
        from it, so the nearest point of the arc is the end nearer in angle, the nearer
        end. A point at the centre (all points equidistant) takes the start.
        """
        c = self.col
        r, sg = self.radius[seg], self.sign[seg]
        vx, vy = px - c["ax"][seg], py - c["ay"][seg]
        rho = np.sqrt(vx * vx + vy * vy)
        ux, uy = c["ux0"][seg], c["uy0"][seg]
        # angle from the start direction, in the direction of travel, in [0, 2π)
        alpha = np.arctan2(sg * (ux * vy - uy * vx), ux * vx + uy * vy)
        alpha = np.where(alpha < 0.0, alpha + _TWO_PI, alpha)
        alpha = np.where(rho > 0.0, alpha, 0.0)
        inside = alpha <= self.abs_sweep[seg]
        dx, dy = px - c["sx"][seg], py - c["sy"][seg]
        d0 = np.sqrt(dx * dx + dy * dy)
        dx, dy = px - c["ex"][seg], py - c["ey"][seg]
        d1 = np.sqrt(dx * dx + dy * dy)
        to_end = d1 < d0
        L = self.length[seg]
        dist = np.where(inside, np.abs(rho - r), np.where(to_end, d1, d0))
        sigma = np.where(inside, np.minimum(r * alpha, L), np.where(to_end, L, 0.0))
        return dist, sigma

    def nearest(
        self,
        seg: np.ndarray,
        pt: np.ndarray,
        px: np.ndarray,
        py: np.ndarray,
        ub: np.ndarray,
        cap: float = math.inf,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distance and parameter of the nearest point for each (point, segment) pair.

        Parameters
        ----------
        seg, pt : numpy.ndarray of int
            Segment and point of each pair, shape (k,).
        px, py : numpy.ndarray
            The points' coordinates, shape (n,), m.
        ub : numpy.ndarray
            An upper bound of each point's distance to the path, shape (n,), m (inf if
            none is known); lowered here by the lines and arcs among the pairs.
        cap : float
            Distances above ``cap`` (m) are of no interest (the caller's grid cannot
            certify them): a curve pair may then return any distance above it.

        Returns
        -------
        dist, param : numpy.ndarray
            Shape (k,): m; local arc length (m) for lines and arcs, curve parameter u for
            curves. A curve pair that cannot come within the bound has a distance above
            it (inf if it was not searched).
        """
        kind = self.kind[seg]
        if self.bank is None and self.n_kinds == 1:  # one kind: no sorting out
            fn = self.line_pairs if kind.size and kind[0] == LINE else self.arc_pairs
            return fn(seg, px[pt], py[pt])
        dist = np.full(seg.size, np.inf)
        param = np.zeros(seg.size)
        for code, fn in ((LINE, self.line_pairs), (ARC, self.arc_pairs)):
            w = np.flatnonzero(kind == code)
            if w.size:
                dist[w], param[w] = fn(seg[w], px[pt[w]], py[pt[w]])
        w = np.flatnonzero(kind == CURVE)
        if w.size:
            assert self.bank is not None
            ub = np.minimum(ub, cap * (1.0 + 1e-9) + self.eps)
            np.minimum.at(ub, pt, dist)
            qx, qy = px[pt[w]], py[pt[w]]
            bound = ub[pt[w]] * (1.0 + 1e-9) + self.eps
            b = self.box[seg[w]]
            gx = np.maximum(np.maximum(b[:, 0] - qx, qx - b[:, 2]), 0.0)
            gy = np.maximum(np.maximum(b[:, 1] - qy, qy - b[:, 3]), 0.0)
            w = w[np.sqrt(gx * gx + gy * gy) <= bound]  # the box holds the curve
            if w.size:
                q = np.column_stack([px[pt[w]], py[pt[w]]])
                param[w], dist[w] = self.bank.nearest(seg[w], q, ub[pt[w]], self.curve_tol)
        return dist, param

    # ------------------------------------------------------------------ grids
    def _pieces(self, n_pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (k, 4) holding every segment cut into ``n_pieces[k]`` pieces; owner (k,)."""
        boxes, owners = [], []
        for code in (LINE, ARC):
            seg = np.flatnonzero(self.kind == code)
            if not seg.size:
                continue
            npc = n_pieces[seg]
            own = np.repeat(seg, npc)
            j = np.arange(own.size) - np.repeat(np.cumsum(npc) - npc, npc)
            per = np.repeat(npc, npc)
            f0, f1 = j / per, (j + 1) / per
            if code == LINE:
                a, b = np.take(self.start, own, axis=0), np.take(self.end, own, axis=0)
                q0 = a + f0[:, None] * (b - a)
                q1 = a + f1[:, None] * (b - a)
                grow = np.zeros(own.size)
            else:
                th0 = self.theta0[own] + f0 * self.sweep[own]
                th1 = self.theta0[own] + f1 * self.sweep[own]
                r = self.radius[own]
                c = np.take(self.a, own, axis=0)
                q0 = c + r[:, None] * np.column_stack([np.cos(th0), np.sin(th0)])
                q1 = c + r[:, None] * np.column_stack([np.cos(th1), np.sin(th1)])
                grow = r * (1.0 - np.cos(0.5 * (th1 - th0)))  # sagitta: arc within it of chord
            lo = np.minimum(q0, q1) - grow[:, None]
            hi = np.maximum(q0, q1) + grow[:, None]
            boxes.append(np.column_stack([lo, hi]))
            owners.append(own)
        if self.bank is not None:
            b, own = self.bank.piece_boxes(self.curve_idx, n_pieces[self.curve_idx])
            boxes.append(b)
            owners.append(own)
        return np.vstack(boxes), np.concatenate(owners)

    def _piece_counts(self, cell: float) -> np.ndarray:
        """Pieces per segment so that each is at most ``cell`` long (arcs: at most 90°)."""
        n = np.maximum(np.ceil(self.length / cell), 1.0)
        arc = self.kind == ARC
        n[arc] = np.maximum(n[arc], np.ceil(np.abs(self.sweep[arc]) / (0.5 * math.pi)))
        if self.bank is not None:
            ci = self.curve_idx
            m1 = np.ceil(self.bank.m1[ci] / cell)  # M1 bounds the speed
            n[ci] = np.clip(m1, 8, _MAX_CURVE_PIECES)
        return n.astype(np.int64)

    def n_levels(self) -> int:
        """Number of grid levels (cells up to the path's size); 0 when one cell holds all."""
        n = 0
        while self.n_seg > 1 and self.cell0 * _LEVEL_RATIO**n < self.size:
            n += 1
        return n

    def usable_levels(self) -> int:
        """Grid levels worth trying: up to the first whose lists are long, at least one.

        A coarse grid over a dense drawing lists hundreds of segments per cell, each an
        exact distance to compute per point: past `_MAX_MEAN_LIST` a k-d tree of samples
        finds the candidates for less. The levels are built here (once).
        """
        if self._usable is None:
            n = self.n_levels()
            use = min(n, 1)
            while use < n and not self._dense(self.level(use)):
                use += 1
            self._usable = use
        return self._usable

    @staticmethod
    def _dense(grid: GridLevel) -> bool:
        return grid.segs.size > _MAX_MEAN_LIST * grid.keys.size

    @property
    def cell0(self) -> float:
        """Cell of the finest grid, m: halved from the start until its lists are short.

        A dense drawing (many segments per median length) would give long lists: the
        cell is halved while the lists hold more than `_MEAN_LIST` segments on average,
        down to the floor. Built on first use, with the finest grid.
        """
        if self._cell0 is None:
            cell = self._cell_start
            grid = self._build(cell)
            while grid.segs.size > _MEAN_LIST * grid.keys.size and cell > self._cell_floor:
                # a list's length goes about as the cell: shrink by the excess at once
                excess = grid.segs.size / (_MEAN_LIST * grid.keys.size)
                cell = max(cell / 2.0 ** math.ceil(math.log2(excess)), self._cell_floor)
                grid = self._build(cell)
            self._cell0 = cell
            self._levels = [grid]
        return self._cell0

    def level(self, k: int) -> GridLevel:
        """Grid level ``k`` (cells ``cell0 * 4**k``), built on first use."""
        cell0 = self.cell0
        while len(self._levels) <= k:
            self._levels.append(self._build(cell0 * _LEVEL_RATIO ** len(self._levels)))
        return self._levels[k]

    def _build(self, cell: float) -> GridLevel:
        boxes, owner = self._pieces(self._piece_counts(cell))
        # registered in every cell that the box grown by ρ (plus rounding) touches
        grow = cell * (1.0 + 1e-9) + self.eps
        lo = boxes[:, :2] - grow
        hi = boxes[:, 2:] + grow
        x0, y0 = float(lo[:, 0].min()), float(lo[:, 1].min())
        nx = int(np.floor((hi[:, 0].max() - x0) / cell)) + 1
        ny = int(np.floor((hi[:, 1].max() - y0) / cell)) + 1
        # the same rounded formula as for the points: monotone in the coordinate, so a
        # point inside the grown box falls in one of the box's cells
        i0 = np.floor((lo[:, 0] - x0) / cell).astype(np.int64)
        j0 = np.floor((lo[:, 1] - y0) / cell).astype(np.int64)
        i1 = np.minimum(np.floor((hi[:, 0] - x0) / cell).astype(np.int64), nx - 1)
        j1 = np.minimum(np.floor((hi[:, 1] - y0) / cell).astype(np.int64), ny - 1)
        cx, cy = i1 - i0 + 1, j1 - j0 + 1
        cnt = cx * cy
        box_of = np.repeat(np.arange(cnt.size), cnt)
        j = np.arange(box_of.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        row, col = np.divmod(j, cx[box_of])
        cell_of = (i0[box_of] + col) * ny + (j0[box_of] + row)
        m = self.n_seg
        if nx * ny * m < 2**62:  # one integer per (cell, segment): one sort
            code = _sorted_unique(cell_of * m + owner[box_of])
            key, segs = code // m, code % m
        else:  # too many for one integer: by cell, then segment
            order = np.lexsort((owner[box_of], cell_of))
            key, segs = cell_of[order], owner[box_of][order]
            new = np.ones(key.size, dtype=bool)
            new[1:] = (key[1:] != key[:-1]) | (segs[1:] != segs[:-1])
            key, segs = key[new], segs[new]
        first = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
        keys = key[first]
        offsets = np.append(first, key.size)
        return GridLevel(cell, x0, y0, nx, ny, keys, offsets, segs)

    # ------------------------------------------------------------------ samples
    def sample_tree(self) -> tuple[cKDTree, np.ndarray, float]:
        """A k-d tree of path samples, each sample's segment, and their covering radius.

        The samples are the ends of the pieces of the finest grid (every segment's ends
        included). A point of a line or an arc is within half its piece's length of one
        of the piece's ends (a chord is no longer than its arc), a point of a curve within
        ``M1 Δu / 2``: the covering radius ``h`` (m) is the largest of these, so every
        point of a segment has a sample of that segment within ``h``.
        """
        if self._tree is None:
            n = self._piece_counts(self.cell0)
            own = np.repeat(np.arange(self.n_seg), n + 1)
            j = np.arange(own.size) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)
            f = j / np.repeat(n, n + 1)
            q = np.zeros((own.size, 2))
            k = self.kind[own]
            w = np.flatnonzero(k == LINE)
            a, b = np.take(self.start, own[w], axis=0), np.take(self.end, own[w], axis=0)
            q[w] = a + f[w, None] * (b - a)
            w = np.flatnonzero(k == ARC)
            th = self.theta0[own[w]] + f[w] * self.sweep[own[w]]
            r = self.radius[own[w], None]
            q[w] = np.take(self.a, own[w], axis=0) + r * np.column_stack([np.cos(th), np.sin(th)])
            reach = self.length / (2.0 * n)
            w = np.flatnonzero(k == CURVE)
            if w.size:
                assert self.bank is not None
                q[w] = self.bank.point(own[w], f[w])
                reach[self.curve_idx] = self.bank.m1[self.curve_idx] / (2.0 * n[self.curve_idx])
            h = float(reach.max()) * (1.0 + 1e-9) + self.eps
            self._tree = (cKDTree(q), own, h)
        return self._tree

    def tree_candidates(
        self, p: np.ndarray, ub: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every segment that may be nearest to each point, found with the sample tree.

        The nearest sample is a path point: its distance ``ds`` bounds the point's
        distance ``d*``. The nearest segment has a sample within ``d* + h <= ds + h``, so
        the segments owning a sample within that radius hold it (``ub`` lowers the
        radius further when smaller than ``ds``).

        Returns
        -------
        counts, cand, bound : numpy.ndarray
            The candidate count of each point; the candidates point after point
            (ascending); the bound of each point, m.
        """
        tree, owner, h = self.sample_tree()
        d1, _ = tree.query(p, k=1)
        bound = np.minimum(ub, d1 + self.eps)  # a sample is a path point, to rounding
        radius = bound * (1.0 + 1e-9) + h + self.eps
        found = tree.query_ball_point(p, radius, return_sorted=False)
        sizes = np.fromiter(map(len, found), dtype=np.int64, count=len(found))
        flat = np.fromiter(itertools.chain.from_iterable(found), np.int64, int(sizes.sum()))
        pt = np.repeat(np.arange(p.shape[0]), sizes)
        key = _sorted_unique(pt * self.n_seg + owner[flat])  # by point, then segment
        pt, cand = key // self.n_seg, key % self.n_seg
        return np.bincount(pt, minlength=p.shape[0]), cand, bound

    @property
    def chunk(self) -> int:
        """Points per batch when every segment is a candidate."""
        return max(1, _CHUNK_PAIRS // self.n_seg)
