"""Which polygons contain which points, without testing every pair.

A drawing's nesting (outer boundary, hole, island; :attr:`Layer.depth
<microfab.geometry.layer.Layer.depth>`) asks, for one probe point of each closed contour,
which other contours contain it. Testing every point against every polygon is quadratic:
5 000 circles are 25 million point-in-polygon tests, minutes. :func:`containers` gives
the same answers from far fewer tests:

1. the candidates of a probe are the polygons whose vertex bounding box holds it (a point
   outside a polygon's vertex box cannot be inside the polygon), found through a uniform
   grid of about one cell per polygon: each box is registered in the cells it overlaps,
   each probe looks only at its own cell's boxes;
2. each polygon then tests its candidates in one call of matplotlib's
   :meth:`~matplotlib.path.Path.contains_points`, the same point-in-polygon routine (and
   so the same answer, to the bit) as :meth:`~matplotlib.path.Path.contains_point` on one
   point.

A polygon whose box spans many grid cells (a plate around thousands of holes) or holds
a non-finite vertex is tested against every probe in its box, or every probe, directly;
so is a probe with a non-finite coordinate against every polygon. The answer is always
that of the exhaustive test; only its cost depends on the layout (small, scattered
contours: about linear; thousands of contours nested in one another: quadratic, as the
answer itself is).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.path import Path as MplPath

__all__ = ["containers"]

#: Most grid cells along one axis.
_MAX_CELLS = 2048


def containers(
    polygons: Sequence[np.ndarray],
    probes: np.ndarray,
    *,
    own: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """For each probe point, the polygons that contain it.

    Parameters
    ----------
    polygons : sequence of numpy.ndarray
        Polygon vertices, each shape (m, 2) (any unit, the probes' unit), implicitly
        closed, as :class:`matplotlib.path.Path` takes them.
    probes : numpy.ndarray
        Points, shape (n, 2).
    own : numpy.ndarray, optional
        Shape (n,): the polygon each probe belongs to, never counted as containing it
        (``-1``: none); by default none.

    Returns
    -------
    ptr : numpy.ndarray
        Shape (n + 1,), int: probe ``i``'s containers are ``idx[ptr[i]:ptr[i + 1]]``.
    idx : numpy.ndarray
        Polygon indices, int, ascending for each probe.

    Notes
    -----
    Polygon ``j`` contains probe ``i`` exactly when
    ``matplotlib.path.Path(polygons[j]).contains_point(probes[i])`` is true (points on
    an edge: as matplotlib decides).
    """
    pts = np.asarray(probes, dtype=float).reshape(-1, 2)
    n, n_poly = pts.shape[0], len(polygons)
    own_of = np.full(n, -1, dtype=np.int64) if own is None else np.asarray(own, dtype=np.int64)
    if own_of.shape != (n,):
        raise ValueError(f"own must have shape ({n},), got {own_of.shape}")
    if n == 0 or n_poly == 0:
        return np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    lo, hi = _boxes(polygons)
    pi, pj = _candidates(lo, hi, pts)
    keep = pj != own_of[pi]
    pi, pj = pi[keep], pj[keep]
    # one contains_points call per polygon, over its candidates
    order = np.lexsort((pi, pj))
    pi, pj = pi[order], pj[order]
    inside = np.zeros(pi.size, dtype=bool)
    cut = np.flatnonzero(np.diff(pj)) + 1
    for a, b in zip(np.r_[0, cut], np.r_[cut, pj.size], strict=True):
        if b > a:
            poly = MplPath(polygons[int(pj[a])])
            inside[a:b] = poly.contains_points(pts[pi[a:b]])
    pi, pj = pi[inside], pj[inside]
    order = np.lexsort((pj, pi))
    pi, pj = pi[order], pj[order]
    ptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(pi, minlength=n), out=ptr[1:])
    return ptr, pj.astype(np.int64, copy=False)


def _boxes(polygons: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Vertex bounding boxes, shapes (p, 2) each; ±inf for one with a non-finite vertex.

    An empty polygon gets an empty box (``lo = +inf``, ``hi = -inf``): it contains
    nothing.
    """
    arrays = [np.asarray(p, dtype=float).reshape(-1, 2) for p in polygons]
    sizes = np.array([a.shape[0] for a in arrays], dtype=np.int64)
    lo = np.full((len(arrays), 2), np.inf)
    hi = np.full((len(arrays), 2), -np.inf)
    full = np.flatnonzero(sizes > 0)
    if full.size:
        verts = np.concatenate([arrays[i] for i in full])
        starts = np.r_[0, np.cumsum(sizes[full])[:-1]]
        with np.errstate(invalid="ignore"):
            lo[full] = np.minimum.reduceat(verts, starts, axis=0)
            hi[full] = np.maximum.reduceat(verts, starts, axis=0)
        bad = np.add.reduceat(~np.isfinite(verts), starts, axis=0).any(axis=1)
        lo[full[bad]] = -np.inf
        hi[full[bad]] = np.inf
    return lo, hi


def _candidates(lo: np.ndarray, hi: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (probe, polygon) with the probe in the polygon's box (or not finite), unique."""
    finite_pt = np.all(np.isfinite(pts), axis=1)
    finite_box = np.all(np.isfinite(lo) & np.isfinite(hi), axis=1)
    empty = np.any(lo > hi, axis=1)
    gridded = finite_box & ~empty
    out_i: list[np.ndarray] = []
    out_j: list[np.ndarray] = []
    # a probe with a non-finite coordinate: every polygon is a candidate
    some = np.flatnonzero(~empty)
    for i in np.flatnonzero(~finite_pt):
        out_i.append(np.full(some.size, i, dtype=np.int64))
        out_j.append(some)
    fin = np.flatnonzero(finite_pt)
    wide = list(np.flatnonzero(~finite_box & ~empty))
    if np.any(gridded):
        x0, y0 = lo[gridded].min(axis=0)
        x1, y1 = hi[gridded].max(axis=0)
        g = int(min(max(np.ceil(np.sqrt(np.count_nonzero(gridded))), 1), _MAX_CELLS))
        wx = (x1 - x0) / g if x1 > x0 else 1.0
        wy = (y1 - y0) / g if y1 > y0 else 1.0

        def cell(v: np.ndarray, v0: float, w: float) -> np.ndarray:
            return np.clip(np.floor((v - v0) / w), 0, g - 1).astype(np.int64)

        ix0, ix1 = cell(lo[:, 0], x0, wx), cell(hi[:, 0], x0, wx)
        iy0, iy1 = cell(lo[:, 1], y0, wy), cell(hi[:, 1], y0, wy)
        nx, ny = ix1 - ix0 + 1, iy1 - iy0 + 1
        # a box over many cells is cheaper tested against every probe than registered
        big = gridded & (nx * ny > max(64, g * g // 16))
        wide.extend(np.flatnonzero(big))
        reg = np.flatnonzero(gridded & ~big)
        k = nx[reg] * ny[reg]
        owner = np.repeat(reg, k)
        off = np.arange(owner.size) - np.repeat(np.cumsum(k) - k, k)
        cells = (iy0[owner] + off // nx[owner]) * g + ix0[owner] + off % nx[owner]
        order = np.argsort(cells, kind="stable")
        members = owner[order]
        first = np.searchsorted(cells[order], np.arange(g * g + 1))
        # the probes inside the grid's extent, in their cells
        p = pts[fin]
        inside = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
        q = fin[inside]
        c = cell(pts[q, 1], y0, wy) * g + cell(pts[q, 0], x0, wx)
        count = first[c + 1] - first[c]
        qi = np.repeat(q, count)
        at = np.arange(qi.size) - np.repeat(np.cumsum(count) - count, count)
        qj = members[np.repeat(first[c], count) + at]
        hit = _in_box(pts[qi], lo[qj], hi[qj])
        out_i.append(qi[hit])
        out_j.append(qj[hit])
    for j in wide:
        if np.all(np.isfinite(lo[j])) and np.all(np.isfinite(hi[j])):
            i = fin[_in_box(pts[fin], lo[j], hi[j])]
        else:
            i = fin
        out_i.append(i)
        out_j.append(np.full(i.size, j, dtype=np.int64))
    if not out_i:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(out_i).astype(np.int64), np.concatenate(out_j).astype(np.int64)


def _in_box(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Whether each point lies in its box, edges included (broadcast over rows)."""
    return np.all((p >= lo) & (p <= hi), axis=-1)
