"""Per-frame measurement of a shadowgraph: background, threshold, nozzle, liquid bodies.

Steps 2-6 of the analysis described in :mod:`microfab.measure.imaging`, for one frame at a
time: flattening of the background, the shadow level, the liquid mask, the nozzle exit,
and each liquid body's extent, sub-pixel tip and tail, volume, centroid and row radii; and
the measured bodies of a sequence as silhouettes (:func:`silhouettes`), for the
head-and-tail measures of :mod:`microfab.process.inkjet.head_tail`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from microfab.process.inkjet.silhouette import Silhouette

__all__ = [
    "MeasuredBody",
    "MeasuredFrame",
    "clean_mask",
    "detect_nozzle_row",
    "flatten",
    "measure_frame",
    "shadow_level",
    "silhouettes",
]

#: Pixels darker than this fraction of the current background estimate are left out of
#: the background fit.
_BG_FRACTION = 0.8
#: A width drop to below this fraction of the row above ends the nozzle (detection).
_NOZZLE_WIDTH_DROP = 0.75


def flatten(frame: np.ndarray, smooth_px: float) -> np.ndarray:
    """Smooth, then divide by a quadratic background surface (background -> 1)."""
    img = ndimage.gaussian_filter(frame, smooth_px, mode="nearest") if smooth_px > 0 else frame
    h, w = img.shape
    step = max(1, int(math.sqrt(h * w / 5000.0)))
    ys, xs = np.mgrid[0:h:step, 0:w:step]
    yn = ys.ravel() / max(h - 1, 1) * 2.0 - 1.0
    xn = xs.ravel() / max(w - 1, 1) * 2.0 - 1.0
    vals = img[::step, ::step].ravel()
    design = np.stack([np.ones_like(yn), yn, xn, yn * yn, xn * xn, yn * xn], axis=1)
    level = float(np.percentile(vals, 90))
    fitted = np.full_like(vals, level)
    coef: np.ndarray | None = None
    for _ in range(3):
        bright = vals > _BG_FRACTION * fitted
        if bright.sum() < 4 * design.shape[1]:
            break
        a = design[bright]
        # Normal equations: 6 unknowns on coordinates scaled to [-1, 1] (well conditioned),
        # much cheaper than an SVD-based lstsq.
        coef = np.linalg.solve(a.T @ a, a.T @ vals[bright])
        fitted = design @ coef
    if coef is None:
        background = np.full_like(img, max(level, 1e-6))
    else:
        yy = np.linspace(-1.0, 1.0, h)[:, None] if h > 1 else np.zeros((1, 1))
        xx = np.linspace(-1.0, 1.0, w)[None, :] if w > 1 else np.zeros((1, 1))
        background = (
            coef[0] + coef[1] * yy + coef[2] * xx + coef[3] * yy**2 + coef[4] * xx**2
        ) + coef[5] * yy * xx
        background = np.maximum(background, 1e-3 * max(level, 1e-6))
    return img / background


def shadow_level(flat: np.ndarray) -> float:
    """Median of the flattened pixels below the Otsu threshold of the sequence (nozzle, liquid).

    Parameters
    ----------
    flat : numpy.ndarray
        Flattened frames (background 1), any shape.
    """
    from skimage.filters import threshold_otsu

    sample = flat.ravel()
    if sample.size > 2_000_000:
        sample = sample[:: sample.size // 1_000_000]
    if np.ptp(sample) < 1e-6:  # flat images: no silhouette at all
        return 1.0
    otsu = float(threshold_otsu(sample))
    dark = sample[sample < otsu]
    return float(np.median(dark)) if dark.size else 1.0


def clean_mask(mask: np.ndarray, min_area_px: int) -> np.ndarray:
    """Fill holes and drop components smaller than ``min_area_px`` (8-connected)."""
    filled = ndimage.binary_fill_holes(mask)
    lab, n = ndimage.label(filled, structure=np.ones((3, 3), bool))
    if n == 0:
        return filled
    areas = np.bincount(lab.ravel())
    keep = areas >= min_area_px
    keep[0] = False
    return keep[lab]


def detect_nozzle_row(mask: np.ndarray) -> int:
    """Index of the last nozzle row in a liquid mask (module docstring of ``imaging``, step 5).

    Parameters
    ----------
    mask : numpy.ndarray of bool
        Liquid/nozzle mask of the first frame, shape (h, w).
    """
    lab, _ = ndimage.label(mask, structure=np.ones((3, 3), bool))
    top = np.unique(lab[0][lab[0] > 0])
    if top.size == 0:
        raise ValueError(
            "cannot find the nozzle: no dark region touches the top edge of the first "
            "frame; pass nozzle_row=<index of the last nozzle row> (or -1 if the exit "
            "plane is the top edge of the image)"
        )
    widths = np.isin(lab, top).sum(axis=1)
    for row in range(1, widths.size):
        if widths[row] < _NOZZLE_WIDTH_DROP * widths[row - 1]:
            return row - 1
    raise ValueError(
        "cannot find the nozzle exit: the dark region at the top spans the whole image "
        "height; pass nozzle_row=<index of the last nozzle row>"
    )


@dataclass(frozen=True, kw_only=True)
class MeasuredBody:
    """One liquid body of a frame.

    Rows, attachment to the nozzle, volume (m³), centroid, tip and tail z (m), and its row
    centres and radii (m).
    """

    top: int
    bottom: int
    attached: bool
    volume_m3: float
    centroid_z_m: float
    tip_z_m: float
    tail_z_m: float
    z_m: np.ndarray  # row centres, m from the exit plane
    r_m: np.ndarray  # half the edge-to-edge width of each row, m


@dataclass(frozen=True, kw_only=True)
class MeasuredFrame:
    """The bodies of one frame.

    Also the one that leads, whether it touches the bottom edge, and the gaps along z
    (empty rows, z of the middle in m).
    """

    bodies: tuple[MeasuredBody, ...]  # sorted by top row
    leading: MeasuredBody | None
    touches_bottom: bool
    gaps: tuple[tuple[int, float], ...]  # (empty rows, z of the middle, m)


def _crossing(outside: np.ndarray, inside: np.ndarray, thr: float) -> np.ndarray:
    """Fraction of the way from an outside to an inside sample where ``thr`` is crossed."""
    denom = outside - inside
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(denom > 0, (outside - thr) / denom, 0.5)
    return np.clip(frac, 0.0, 1.0)


def _axial_profile(flat: np.ndarray, col: int) -> np.ndarray:
    lo, hi = max(col - 1, 0), min(col + 2, flat.shape[1])
    return flat[:, lo:hi].mean(axis=1)


def measure_frame(
    flat: np.ndarray, mask: np.ndarray, thr: float, nozzle_row: int, px: float
) -> MeasuredFrame:
    """The liquid bodies below the nozzle in one frame, and the gaps between them.

    Parameters
    ----------
    flat : numpy.ndarray
        Flattened frame (background 1), shape (h, w).
    mask : numpy.ndarray of bool
        Its cleaned liquid mask, shape (h, w).
    thr : float
        Liquid threshold in flattened units.
    nozzle_row : int
        Index of the last nozzle row (the exit plane is its lower edge).
    px : float
        Pixel size, m.
    """
    h, w = flat.shape
    first = nozzle_row + 1  # first liquid row

    def z_of(y_index: float | np.ndarray) -> Any:
        # y_index: row index (pixel-centre coordinates); exit plane at edge ``first``.
        return (np.asarray(y_index) + 0.5 - first) * px

    liquid = np.zeros_like(mask)
    liquid[first:] = mask[first:]
    lab, _ = ndimage.label(liquid, structure=np.ones((3, 3), bool))
    bodies: list[MeasuredBody] = []
    for index, sl in enumerate(ndimage.find_objects(lab), start=1):
        if sl is None:
            continue
        sub = lab[sl] == index
        r0, c0 = sl[0].start, sl[1].start
        rows = np.arange(r0, sl[0].stop)
        left = c0 + np.argmax(sub, axis=1)
        right = c0 + sub.shape[1] - 1 - np.argmax(sub[:, ::-1], axis=1)
        xl = left.astype(float) - 0.5
        ok = left > 0
        xl[ok] = (
            left[ok] - 1 + _crossing(flat[rows[ok], left[ok] - 1], flat[rows[ok], left[ok]], thr)
        )
        xr = right.astype(float) + 0.5
        ok = right < w - 1
        xr[ok] = (
            right[ok] + 1 - _crossing(flat[rows[ok], right[ok] + 1], flat[rows[ok], right[ok]], thr)
        )
        radius_px = np.maximum(xr - xl, 0.0) / 2.0
        slab = math.pi * radius_px**2
        volume = float(slab.sum()) * px**3
        z_rows = z_of(rows)
        centroid = (
            float((slab * z_rows).sum() / slab.sum()) if slab.sum() > 0 else float(z_rows.mean())
        )
        top, bottom = int(rows[0]), int(rows[-1])
        # Tip (lower end) and tail (upper end), sub-pixel along the body's axis.
        col_b = round(float(xl[-1] + xr[-1]) / 2.0)
        prof = _axial_profile(flat, min(max(col_b, 0), w - 1))
        tip = (
            bottom + 0.5
            if bottom == h - 1
            else bottom + 1 - _crossing(np.array(prof[bottom + 1]), np.array(prof[bottom]), thr)
        )
        col_t = round(float(xl[0] + xr[0]) / 2.0)
        prof = _axial_profile(flat, min(max(col_t, 0), w - 1))
        tail = (
            top - 0.5
            if top == first
            else top - 1 + _crossing(np.array(prof[top - 1]), np.array(prof[top]), thr)
        )
        bodies.append(
            MeasuredBody(
                top=top,
                bottom=bottom,
                attached=top == first,
                volume_m3=volume,
                centroid_z_m=centroid,
                tip_z_m=float(z_of(tip)),
                tail_z_m=float(z_of(tail)),
                z_m=np.asarray(z_rows, dtype=float),
                r_m=radius_px * px,
            )
        )
    bodies.sort(key=lambda b: (b.top, b.bottom))
    leading = max(bodies, key=lambda b: (b.bottom, b.volume_m3)) if bodies else None
    # Gaps along z between the row extents (exit plane acts as the upper end).
    intervals: list[list[int]] = []
    if not any(b.attached for b in bodies):
        intervals.append([nozzle_row, nozzle_row])
    for b in bodies:
        if intervals and b.top <= intervals[-1][1] + 1:
            intervals[-1][1] = max(intervals[-1][1], b.bottom)
        else:
            intervals.append([b.top, b.bottom])
    gaps = tuple(
        (nxt[0] - prev[1] - 1, float(z_of((prev[1] + nxt[0]) / 2.0)))
        for prev, nxt in itertools.pairwise(intervals)
    )
    return MeasuredFrame(
        bodies=tuple(bodies),
        leading=leading,
        touches_bottom=leading is not None and leading.bottom == h - 1,
        gaps=gaps,
    )


def silhouettes(
    measured: Sequence[MeasuredFrame], times: np.ndarray, px: float
) -> list[Silhouette]:
    """The measured bodies of each frame as silhouettes (rows with free tips closed).

    A body joined to the nozzle starts at the exit plane (``z = 0``) with the radius of its
    first row; free ends get radius 0 at their sub-pixel tip. The silhouettes' nozzle
    radius is the largest first-row radius of an attached body in the sequence (an
    estimate: the orifice is hidden in the glass tip), or one pixel without one.
    """
    firsts = [b.r_m[0] for fr in measured for b in fr.bodies if b.attached and b.r_m.size]
    nozzle_r = max([float(v) for v in firsts if v > 0.0], default=px)
    out = []
    for t, fr in zip(times, measured, strict=True):
        bodies = []
        for b in fr.bodies:
            z, r = list(b.z_m), list(b.r_m)
            if b.attached:
                z, r = [0.0, *z], [r[0], *r]
            elif b.tail_z_m < z[0]:
                z, r = [b.tail_z_m, *z], [0.0, *r]
            if b.tip_z_m > z[-1]:
                z, r = [*z, b.tip_z_m], [*r, 0.0]
            if len(z) >= 2:
                bodies.append((np.asarray(z), np.asarray(r)))
        out.append(Silhouette(time_s=float(t), bodies=tuple(bodies), nozzle_radius_m=nozzle_r))
    return out
