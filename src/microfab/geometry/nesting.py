"""Which polygons contain which points, without testing every pair.

A drawing's nesting (outer boundary, hole, island; :attr:`Layer.depth
<microfab.geometry.layer.Layer.depth>`) asks, for one probe point of each closed contour,
which other contours contain it. Testing every point against every polygon is quadratic:
5 000 circles are 25 million point-in-polygon tests, minutes. :func:`containers` gives
the same answers from far fewer tests:

1. the candidates of a probe are the polygons whose vertex bounding box holds it (a point
   outside a polygon's vertex box cannot be inside the polygon), found through a grid of
   about one cell per polygon, its cell edges at quantiles of the box centres (so that a
   dense cluster beside a far outlier still spreads over many cells): each box is
   registered in the cells it overlaps, each probe looks only at its own cell's boxes;
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
#: About how many candidate pairs are made at once, before the box test.
_CHUNK = 1 << 20


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
    out_i: list[np.ndarray] = []
    out_j: list[np.ndarray] = []
    # a probe with a non-finite coordinate: every polygon is a candidate
    some = np.flatnonzero(~empty)
    for i in np.flatnonzero(~finite_pt):
        out_i.append(np.full(some.size, i, dtype=np.int64))
        out_j.append(some)
    fin = np.flatnonzero(finite_pt)
    wide = np.flatnonzero(~finite_box & ~empty)
    gridded = np.flatnonzero(finite_box & ~empty)
    if gridded.size:
        big, pairs = _grid_pairs(lo, hi, gridded, pts, fin)
        wide = np.r_[wide, big]
        for qi, qj in pairs:
            out_i.append(qi)
            out_j.append(qj)
    for j in wide.tolist():
        i = fin[_in_box(pts[fin], lo[j], hi[j])] if finite_box[j] else fin
        out_i.append(i)
        out_j.append(np.full(i.size, j, dtype=np.int64))
    if not out_i:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(out_i).astype(np.int64), np.concatenate(out_j).astype(np.int64)


def _grid_pairs(
    lo: np.ndarray, hi: np.ndarray, boxes: np.ndarray, pts: np.ndarray, probes: np.ndarray
) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """Candidate pairs of the finite ``boxes`` (indices) and finite ``probes`` (indices).

    The grid's cell edges are quantiles of the box centres along each axis (about
    ``sqrt(len(boxes))`` cells a side), so that clustered contours spread over many
    cells; a box is registered in every cell it overlaps, a probe looks in its own cell.
    Cells are found by `numpy.searchsorted` on the edges, which is monotone: a probe in a
    box lies in one of the box's cells. The pairs are made a chunk of probes at a time,
    at most about `_CHUNK` before the box test, so memory stays bounded.

    Returns
    -------
    big : numpy.ndarray
        The boxes over too many cells, left out of the grid: test them directly.
    pairs : list of (numpy.ndarray, numpy.ndarray)
        Probe and box indices of the candidate pairs, chunk by chunk.
    """
    g = int(min(max(np.ceil(np.sqrt(boxes.size)), 1), _MAX_CELLS))
    centre = 0.5 * (lo[boxes] + hi[boxes])
    q = np.linspace(0.0, 1.0, g + 1)[1:-1]
    edges = [np.unique(np.quantile(centre[:, k], q)) for k in range(2)]
    gx, gy = edges[0].size + 1, edges[1].size + 1

    def cell(v: np.ndarray, k: int) -> np.ndarray:
        return np.searchsorted(edges[k], v, side="right").astype(np.int64)

    ix0, ix1 = cell(lo[boxes, 0], 0), cell(hi[boxes, 0], 0)
    iy0, iy1 = cell(lo[boxes, 1], 1), cell(hi[boxes, 1], 1)
    nx, ny = ix1 - ix0 + 1, iy1 - iy0 + 1
    # a box over many cells is cheaper tested against every probe than registered
    over = nx * ny > max(64, gx * gy // 16)
    reg = np.flatnonzero(~over)
    k = nx[reg] * ny[reg]
    row = np.repeat(reg, k)
    off = np.arange(row.size) - np.repeat(np.cumsum(k) - k, k)
    cells = (iy0[row] + off // nx[row]) * gx + ix0[row] + off % nx[row]
    order = np.argsort(cells, kind="stable")
    members = boxes[row[order]]
    first = np.searchsorted(cells[order], np.arange(gx * gy + 1))
    c = cell(pts[probes, 1], 1) * gx + cell(pts[probes, 0], 0)
    count = first[c + 1] - first[c]
    pairs = []
    cut = np.searchsorted(np.cumsum(count), np.arange(_CHUNK, int(count.sum()), _CHUNK))
    for sel in np.split(np.arange(probes.size), np.unique(cut + 1)):
        n_sel = count[sel]
        qi = np.repeat(probes[sel], n_sel)
        at = np.arange(qi.size) - np.repeat(np.cumsum(n_sel) - n_sel, n_sel)
        qj = members[np.repeat(first[c[sel]], n_sel) + at]
        hit = _in_box(pts[qi], lo[qj], hi[qj])
        pairs.append((qi[hit], qj[hit]))
    return boxes[over], pairs


def _in_box(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Whether each point lies in its box, edges included (broadcast over rows)."""
    return np.all((p >= lo) & (p <= hi), axis=-1)
