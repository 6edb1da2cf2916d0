"""Cured line of a dose map: width across a path, closure and gap of a closed contour.

Measures for :mod:`microfab.process.dose` (seed 001 Figs. 14-15: a ~2.5 µm line on a
0.15 mm circle, some circles left open at the closing point). The reference contour is
resampled at uniform arc length; at each point the dose is read (bilinear) along the
normal and the cured run at or nearest the contour is measured between its interpolated
threshold crossings. A contour point is cured when anything along its normal window is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from microfab.core.validate import check_int, check_positive
from microfab.process.dose import DoseMap

__all__ = ["LineWidths", "LoopMeasures", "line_widths", "measure_loop"]


@njit(cache=True)
def _runs(d: np.ndarray, th: float, du: float, u0: float) -> tuple[np.ndarray, np.ndarray]:
    """Edges (m) of the cured run at or nearest the centre of each row of ``d`` (nan: none)."""
    n, m = d.shape
    left = np.full(n, np.nan)
    right = np.full(n, np.nan)
    c = m // 2
    for k in range(n):
        start = -1
        for off in range(m):
            if c - off >= 0 and d[k, c - off] > th:
                start = c - off
                break
            if c + off < m and d[k, c + off] > th:
                start = c + off
                break
        if start < 0:
            continue
        a = start
        while a > 0 and d[k, a - 1] > th:
            a -= 1
        b = start
        while b < m - 1 and d[k, b + 1] > th:
            b += 1
        fa = 0.0 if a == 0 else (th - d[k, a - 1]) / (d[k, a] - d[k, a - 1]) - 1.0
        fb = 0.0 if b == m - 1 else (d[k, b] - th) / (d[k, b] - d[k, b + 1])
        left[k] = u0 + (a + fa) * du
        right[k] = u0 + (b + fb) * du
    return left, right


@dataclass(frozen=True)
class LineWidths:
    """Cured width measured across a path, normal to it.

    Attributes
    ----------
    arc_m : numpy.ndarray, shape (n,)
        Arc length of each measuring point from the path's first point, m.
    points_m : numpy.ndarray, shape (n, 2)
        Measuring points (x, y) on the path, m.
    normals : numpy.ndarray, shape (n, 2)
        Unit normals (left of the direction of travel).
    width_m : numpy.ndarray, shape (n,)
        Width of the cured run at (or nearest) the path along the normal, m; 0 where
        nothing within the window is cured.
    offset_m : numpy.ndarray, shape (n,)
        Centre of that run from the path along the normal, m (nan where uncured).
    peak_j_m2 : numpy.ndarray, shape (n,)
        Largest dose along the normal within the window, J/m².
    """

    arc_m: np.ndarray
    points_m: np.ndarray
    normals: np.ndarray
    width_m: np.ndarray
    offset_m: np.ndarray
    peak_j_m2: np.ndarray


def line_widths(
    dmap: DoseMap,
    path_xy_m: np.ndarray,
    threshold_j_m2: float,
    *,
    closed: bool,
    spacing_m: float | None = None,
    half_window_m: float | None = None,
) -> LineWidths:
    """Cured width along a path (the reference contour), measured normal to it.

    The path is resampled at uniform arc length; at each point the dose is interpolated
    (bilinear) along the normal at a quarter cell, and the run above the threshold at or
    nearest the path is measured between its linearly interpolated crossings.

    Parameters
    ----------
    dmap : DoseMap
        The dose.
    path_xy_m : numpy.ndarray, shape (n, 2)
        Path in m (at least 2 distinct points; repeated points are dropped).
    threshold_j_m2 : float
        Cure threshold in J/m², > 0 (:func:`calibrate_threshold`).
    closed : bool
        Whether the path closes from its last point back to its first.
    spacing_m : float, optional
        Arc-length step in m, > 0; default half a cell.
    half_window_m : float, optional
        How far along each normal to look, m, > 0; default three spot radii (4.5 µm for
        the seed's spot): wide enough for a line of up to twice the nominal width or a
        placement error of about one spot radius.

    Returns
    -------
    LineWidths
    """
    th = check_positive("threshold_j_m2", threshold_j_m2, "J/m²")
    ds0 = dmap.cell_m / 2 if spacing_m is None else check_positive("spacing_m", spacing_m, "m")
    half = 3 * dmap.spot_radius_m if half_window_m is None else half_window_m
    half = check_positive("half_window_m", half, "m")
    pts = np.asarray(path_xy_m, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
        raise ValueError(f"path_xy_m must have shape (n >= 2, 2) in m, got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError("path_xy_m must be finite (m)")
    if closed:
        pts = np.vstack((pts, pts[:1]))
    seg = np.hypot(*np.diff(pts, axis=0).T)
    keep = np.concatenate(([True], seg > 0))
    pts = pts[keep]
    s = np.concatenate(([0.0], np.cumsum(seg[seg > 0])))
    length = float(s[-1]) if s.size else 0.0
    if length <= 0:
        raise ValueError("path_xy_m must hold at least 2 distinct points")
    n = max(2, math.ceil(length / ds0))
    arc = np.arange(n) * (length / n) if closed else np.linspace(0.0, length, n + 1)
    px = np.interp(arc, s, pts[:, 0])
    py = np.interp(arc, s, pts[:, 1])
    if closed:
        tx = np.roll(px, -1) - np.roll(px, 1)
        ty = np.roll(py, -1) - np.roll(py, 1)
    else:
        tx, ty = np.gradient(px), np.gradient(py)
    norm = np.hypot(tx, ty)
    nx, ny = -ty / norm, tx / norm
    du = dmap.cell_m / 4
    mh = math.ceil(half / du)
    u = du * np.arange(-mh, mh + 1)
    left = np.empty(arc.size)
    right = np.empty(arc.size)
    peak = np.empty(arc.size)
    for b in range(0, arc.size, 2048):  # bounded memory
        sl = slice(b, b + 2048)
        d = dmap.sample(px[sl, None] + u * nx[sl, None], py[sl, None] + u * ny[sl, None])
        peak[sl] = d.max(axis=1)
        left[sl], right[sl] = _runs(d, th, du, float(u[0]))
    width = np.where(np.isnan(left), 0.0, right - left)
    return LineWidths(
        arc_m=arc,
        points_m=np.column_stack((px, py)),
        normals=np.column_stack((nx, ny)),
        width_m=width,
        offset_m=0.5 * (left + right),
        peak_j_m2=peak,
    )


@dataclass(frozen=True)
class LoopMeasures:
    """The cured line of one closed contour.

    Attributes
    ----------
    widths : LineWidths
        Width along the contour; ``arc_m`` starts at the closing point.
    threshold_j_m2 : float
        Cure threshold used, J/m².
    closed : bool
        True when every measuring point has cured resin across it.
    gap_m : float
        Uncured arc length at (or nearest) the closing point, m (0 when closed), its ends
        interpolated on ``peak_j_m2``.
    uncured_m : float
        Total uncured arc length, m (to the measuring step).
    mean_width_m, std_width_m, min_width_m, max_width_m : float
        Width statistics over the cured points, m (nan if none).
    closing_width_m : float
        Width at the closing point, m.
    closing_min_width_m, closing_max_width_m : float
        Extremes of the width within ``neighbourhood_m`` of the closing point, m.
    """

    widths: LineWidths
    threshold_j_m2: float
    closed: bool
    gap_m: float
    uncured_m: float
    mean_width_m: float
    std_width_m: float
    min_width_m: float
    max_width_m: float
    closing_width_m: float
    closing_min_width_m: float
    closing_max_width_m: float


def _closing_gap(peak: np.ndarray, th: float, ds: float) -> float:
    """Length of the uncured circular run at or nearest index 0 (m); ends interpolated."""
    bad = peak <= th
    n = bad.size
    if not bad.any():
        return 0.0
    if bad.all():
        return n * ds
    r = int(np.flatnonzero(~bad)[0])  # roll so that a cured point comes first
    pk = np.roll(peak, -r)
    rb = np.roll(bad, -r)
    q = (-r) % n  # index of the closing point after the roll
    edges = np.diff(np.concatenate(([0], rb.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    dist = [
        0 if a <= q <= b else min((a - q) % n, (q - b) % n)
        for a, b in zip(starts, ends, strict=True)
    ]
    k = int(np.argmin(dist))
    a, b = int(starts[k]), int(ends[k])
    left = (a - 1) + (pk[a - 1] - th) / (pk[a - 1] - pk[a])
    nxt = pk[(b + 1) % n]
    right = b + (th - pk[b]) / (nxt - pk[b])
    return float((right - left) * ds)


def measure_loop(
    dmap: DoseMap,
    contour_xy_m: np.ndarray,
    threshold_j_m2: float,
    *,
    closing_index: int = 0,
    neighbourhood_m: float | None = None,
    spacing_m: float | None = None,
    half_window_m: float | None = None,
) -> LoopMeasures:
    """Width, closure and closing gap of the cured line of one closed contour.

    Parameters
    ----------
    dmap : DoseMap
        The dose.
    contour_xy_m : numpy.ndarray, shape (n, 2)
        The closed contour in m (e.g. the reference over one period), without repeating
        its first point at the end.
    threshold_j_m2 : float
        Cure threshold in J/m², > 0.
    closing_index : int, optional
        Index of the closing point in ``contour_xy_m`` (where the gate opens), >= 0.
    neighbourhood_m : float, optional
        Half-length of the arc around the closing point whose width extremes are
        reported, m, > 0; default two spot diameters (6 µm for the seed's spot).
    spacing_m, half_window_m : float, optional
        As in :func:`line_widths`.

    Returns
    -------
    LoopMeasures
    """
    pts = np.asarray(contour_xy_m, dtype=float)
    ci = check_int("closing_index", closing_index, 0)
    if pts.ndim != 2 or ci >= pts.shape[0]:
        raise ValueError(
            f"closing_index must index contour_xy_m (shape {pts.shape}), got {closing_index}"
        )
    lw = line_widths(
        dmap,
        np.roll(pts, -ci, axis=0),
        threshold_j_m2,
        closed=True,
        spacing_m=spacing_m,
        half_window_m=half_window_m,
    )
    nb = 4 * dmap.spot_radius_m if neighbourhood_m is None else neighbourhood_m
    nb = check_positive("neighbourhood_m", nb, "m")
    th = float(threshold_j_m2)
    ds = float(lw.arc_m[1] - lw.arc_m[0])
    length = ds * lw.arc_m.size
    dist = np.minimum(lw.arc_m, length - lw.arc_m)
    near = lw.width_m[dist <= nb]
    cured = lw.width_m[lw.width_m > 0]
    nan = float("nan")
    return LoopMeasures(
        widths=lw,
        threshold_j_m2=th,
        closed=bool((lw.width_m > 0).all()),
        gap_m=_closing_gap(lw.peak_j_m2, th, ds),
        uncured_m=float(np.count_nonzero(lw.width_m == 0) * ds),
        mean_width_m=float(cured.mean()) if cured.size else nan,
        std_width_m=float(cured.std()) if cured.size else nan,
        min_width_m=float(cured.min()) if cured.size else nan,
        max_width_m=float(cured.max()) if cured.size else nan,
        closing_width_m=float(lw.width_m[0]),
        closing_min_width_m=float(near.min()),
        closing_max_width_m=float(near.max()),
    )
