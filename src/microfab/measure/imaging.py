"""Analyse time-resolved shadowgraph sequences of a forming inkjet droplet.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.) measures the
first breakup (pinch-off) time of alginate jets "from the captured pictures" of a JetXpert
strobed camera and names the pinch-off mode by where the jet first breaks (front- or
exit-pinching, seed Figs. 2 and 3). This module does that measurement automatically on a
folder of frames, real or rendered by :mod:`microfab.measure.shadowgraph`:

1. **Loading** (:func:`load_frames`): PNG/TIFF files (8/16-bit, gray or RGB(A), multi-page
   TIFF stacks) in natural order (``frame_2`` before ``frame_10``), as gray floats.
2. **Background** (per frame): the image is smoothed with a Gaussian of ``smooth_px``
   pixels, then divided by a quadratic surface fitted (three passes) to the pixels brighter
   than 80 % of the current background estimate. This flattens uneven illumination and
   makes the levels independent of bit depth and exposure: background -> 1.
3. **Threshold** (whole sequence): the shadow level ``S`` is the median of the flattened
   pixels below the Otsu threshold of the whole sequence (the nozzle and the liquid); the
   liquid/background threshold is ``T = 1 - threshold_fraction * (1 - S)`` (default
   fraction 0.5: half-way between background and shadow, where a blurred edge lies).
4. **Objects**: pixels below ``T``, holes filled (the bright lens spot at the centre of
   real drops), components smaller than ``min_area_px`` removed, 8-connected labelling.
5. **Nozzle exit**: unless ``nozzle_row`` is given, it is detected in the FIRST frame as the
   bottom row of the dark component touching the top edge (the nozzle). If liquid already
   hangs from the nozzle in that frame, the nozzle ends where the component's width first
   drops below 75 % of the width of the row above (the jet is much narrower than the glass
   tip). ``nozzle_row`` is the index of the last nozzle row; the exit plane (``z = 0``) is
   its lower edge, and every object below it is liquid. ``nozzle_row=-1`` puts the exit
   plane at the top edge of the image.
6. **Per frame**: liquid bodies, whether one is attached to the nozzle (touches the row
   below the exit plane), the number of detached bodies, their volume
   ``sum_rows pi r^2 * pixel`` with ``r`` half the distance between the outer edges of
   the row (sub-pixel: linear interpolation of the intensity at ``T``) and their
   volume-weighted centroid ``z``; the head position (tip of the body reaching farthest
   from the nozzle, sub-pixel along its axis) and the ligament length (head tip to the
   nozzle exit, or to the tail of the body carrying the head once it is detached).

The head is "in view" while its body does not touch the bottom edge of the image; once it
has touched it, a later frame whose leading body no longer touches it is taken to have
lost the head (it left the field of view), and the leading body there is a satellite.

Summary (:class:`DropletAnalysis`): breakup frame = first frame in which the liquid is
split into at least two bodies, counting the nozzle with the liquid attached to it as one
(so a ligament that pinches off at the exit plane counts, even if nothing stays attached);
the true breakup time lies between the previous frame and this one. Breakup position =
middle of the empty row run between two bodies (or between the exit plane and the first
detached body); when the breakup frame shows several gaps, the WIDEST is taken (a gap
widens by capillary retraction after pinch-off, so the widest is most likely the first;
ties go to the gap nearest the head). The mode comes from
:func:`microfab.process.inkjet.breakup.classify_pinch` with that position and the head tip.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from microfab.core.validate import (
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
)
from microfab.process.inkjet.breakup import BreakupMode, classify_pinch
from microfab.process.inkjet.head_tail import HeadTail, Thinning, head_and_tail, thinning_rate
from microfab.process.inkjet.silhouette import Silhouette

__all__ = [
    "IMAGE_SUFFIXES",
    "SIDECAR_NAME",
    "DropletAnalysis",
    "MissingSettingError",
    "analyze",
    "analyze_folder",
    "as_frames",
    "load_frames",
    "natural_key",
]

#: File suffixes read by :func:`load_frames` (case-insensitive).
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")
#: Sidecar with acquisition metadata (written by ``shadowgraph.write_frames``).
SIDECAR_NAME = "frames.json"

#: Pixels darker than this fraction of the current background estimate are left out of
#: the background fit.
_BG_FRACTION = 0.8
#: A width drop to below this fraction of the row above ends the nozzle (detection).
_NOZZLE_WIDTH_DROP = 0.75


# ---------------------------------------------------------------------------- loading


class MissingSettingError(ValueError):
    """A camera setting that was neither passed nor found in the frames' sidecar.

    Parameters
    ----------
    key : str
        The setting's name (``"pixel_size_m"`` or ``"frame_interval_s"``), so that a
        front end can name its own option for it.
    message : str
        The error message.
    """

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


def natural_key(name: str) -> list[int | str]:
    """Sort key that orders embedded numbers by value (``frame_2`` before ``frame_10``).

    Parameters
    ----------
    name : str
        File name.

    Returns
    -------
    list of int or str
        Alternating text (lower-cased) and integer parts.

    Examples
    --------
    >>> sorted(["f_10.png", "f_2.png", "f_1.png"], key=natural_key)
    ['f_1.png', 'f_2.png', 'f_10.png']
    """
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def _to_float(arr: np.ndarray) -> np.ndarray:
    if arr.dtype == bool:
        return arr.astype(float)
    if np.issubdtype(arr.dtype, np.integer):
        info = np.iinfo(arr.dtype)
        return np.clip(arr.astype(float) / info.max, 0.0, 1.0)
    out = np.asarray(arr, dtype=float)
    top = float(np.nanmax(out)) if out.size else 0.0
    return out / top if top > 1.0 else out


def _rgb_to_gray(arr: np.ndarray) -> np.ndarray:
    from skimage.color import rgb2gray

    return rgb2gray(arr[..., :3])


# tifffile logs what it finds wrong in a damaged file before it raises; without a handler
# Python prints that on stderr, beside the one-line error the file's refusal gives.
logging.getLogger("tifffile").addHandler(logging.NullHandler())


def _read_image(path: Path) -> list[np.ndarray]:
    """Read one file into a list of 2-D gray float frames (several for a TIFF stack)."""
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            import tifffile

            raw = tifffile.imread(path)
        else:
            import imageio.v3 as iio

            raw = iio.imread(path, plugin="pillow")
    except Exception as exc:
        raise ValueError(f"cannot read image file {path}: {exc}") from exc
    arr = _to_float(np.asarray(raw))
    if arr.ndim == 2:
        return [arr]
    if arr.ndim == 3 and arr.shape[-1] in (3, 4):
        return [_rgb_to_gray(arr)]
    if arr.ndim == 3 and arr.shape[-1] == 2:  # gray + alpha
        return [arr[..., 0]]
    if arr.ndim == 3:  # multi-page stack (n, h, w)
        return list(arr)
    if arr.ndim == 4 and arr.shape[-1] in (3, 4):  # stack of RGB pages
        return [_rgb_to_gray(page) for page in arr]
    raise ValueError(f"cannot use image file {path}: unsupported array shape {arr.shape}")


def load_frames(
    directory: str | Path, *, pattern: str | None = None
) -> tuple[np.ndarray, list[str]]:
    """Read a folder of PNG/TIFF frames into one gray float array.

    Parameters
    ----------
    directory : str or pathlib.Path
        Folder with the frames. Hidden files (names starting with ``.``) are skipped.
    pattern : str, optional
        Glob pattern of the files to read (e.g. ``"cam1_*.tif"``); default: every file
        with a suffix in :data:`IMAGE_SUFFIXES`.

    Returns
    -------
    frames : numpy.ndarray
        Shape ``(n, h, w)``, float in [0, 1] (integers scaled by their type's maximum,
        RGB converted to luminance, alpha ignored).
    names : list of str
        File name of each frame (``name[i]`` for page ``i`` of a multi-page TIFF), in
        natural order.

    Raises
    ------
    ValueError
        If the folder does not exist or holds no matching image, a file cannot be read,
        or the frames differ in size (both sizes and files are named).

    Examples
    --------
    >>> frames, names = load_frames("run_50V")  # doctest: +SKIP
    >>> frames.shape, names[:2]  # doctest: +SKIP
    ((16, 400, 120), ['frame_0000.png', 'frame_0001.png'])
    """
    folder = Path(directory)
    if not folder.is_dir():
        raise ValueError(f"frame folder not found (or not a folder): {folder}")
    if pattern is None:
        files = [
            p
            for p in folder.iterdir()
            if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")
        ]
    else:
        files = [p for p in folder.glob(pattern) if p.is_file() and not p.name.startswith(".")]
    if not files:
        wanted = pattern if pattern is not None else "/".join(IMAGE_SUFFIXES)
        raise ValueError(f"no image files ({wanted}) in folder {folder}")
    files.sort(key=lambda p: natural_key(p.name))
    frames: list[np.ndarray] = []
    names: list[str] = []
    for path in files:
        pages = _read_image(path)
        for i, page in enumerate(pages):
            name = path.name if len(pages) == 1 else f"{path.name}[{i}]"
            if frames and page.shape != frames[0].shape:
                h0, w0 = frames[0].shape
                h1, w1 = page.shape
                raise ValueError(
                    f"frames differ in size: {names[0]} is {w0} x {h0} px (w x h) but "
                    f"{name} is {w1} x {h1} px"
                )
            frames.append(page)
            names.append(name)
    return np.stack(frames), names


# ---------------------------------------------------------------------------- results


def _opt(value: float | None) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return float(value)


def _list(values: np.ndarray) -> list[Any]:
    out: list[Any] = []
    for v in np.asarray(values).tolist():
        out.append(None if isinstance(v, float) and not math.isfinite(v) else v)
    return out


@dataclass(frozen=True, kw_only=True, eq=False)
class DropletAnalysis:
    """Measured droplet formation of one shadowgraph sequence.

    Per-frame arrays have one entry per frame; NaN marks "not measurable" (no liquid,
    head out of view). Summary values are ``None`` when they cannot be measured.

    Attributes
    ----------
    times_s : numpy.ndarray
        Frame times, s (``t0_s + k * frame_interval_s``).
    head_z_m : numpy.ndarray
        Head tip position downstream of the nozzle exit plane, m (NaN if not in view).
    attached : numpy.ndarray of bool
        Whether liquid is attached to the nozzle (protrudes below the exit plane).
    n_bodies : numpy.ndarray of int
        Number of liquid bodies detached from the nozzle.
    ligament_lengths_m : numpy.ndarray
        Head tip to the nozzle exit (head body attached) or to the tail of the body
        carrying the head (detached), m.
    body_z_m, body_volume_m3 : tuple of numpy.ndarray
        Per frame, centroid ``z`` (m) and volume (m³) of each detached body, by ``z``.
    fit_frames : numpy.ndarray of bool
        Frames used for the head-speed fit.
    pixel_size_m, frame_interval_s : float
        Calibration, m per pixel and s per frame.
    nozzle_row : int
        Index of the last nozzle row (exit plane at its lower edge).
    threshold, shadow_level : float
        Liquid threshold and shadow level in flattened units (background = 1).
    breakup_frame : int or None
        First frame with the liquid split into >= 2 bodies (nozzle + attached liquid
        counting as one).
    breakup_time_s : float or None
        Time of that frame; the true breakup lies in ``breakup_window_s``.
    breakup_z_m : float or None
        Middle of the widest gap in the breakup frame, m from the exit plane.
    breakup_mode : {"front", "exit", "middle"} or None
        :func:`~microfab.process.inkjet.breakup.classify_pinch` of the gap and head tip.
    head_speed_m_s : float or None
        Least-squares slope of the head position over :attr:`fit_frames`, m/s.
    head_z0_m : float or None
        Intercept of that fit at ``t = 0``, m (fit line ``z = head_z0_m + v t``).
    satellites : int
        Detached bodies other than the head drop in the last frame.
    drop_volume_m3 : float or None
        Volume of the leading detached body (the head drop) in the last frame in which it
        is fully in view, m³.
    ligament_length_m : float or None
        Ligament length in the breakup frame, m.
    frame_names : tuple of str
        Source of each frame (file names), if known.
    silhouettes : tuple of Silhouette
        The measured bodies of each frame (row radii), for the head-and-tail measures.
    head_tail : HeadTail or None
        Head and tail (:func:`microfab.process.inkjet.head_tail.head_and_tail`) in the last
        frame before the breakup frame: head radius, tail length at pinch-off.
    thinning : Thinning or None
        Ligament thinning over the 40 µs before the breakup frame
        (:func:`microfab.process.inkjet.head_tail.thinning_rate`).
    """

    times_s: np.ndarray
    head_z_m: np.ndarray
    attached: np.ndarray
    n_bodies: np.ndarray
    ligament_lengths_m: np.ndarray
    body_z_m: tuple[np.ndarray, ...]
    body_volume_m3: tuple[np.ndarray, ...]
    fit_frames: np.ndarray
    pixel_size_m: float
    frame_interval_s: float
    nozzle_row: int
    threshold: float
    shadow_level: float
    breakup_frame: int | None
    breakup_time_s: float | None
    breakup_z_m: float | None
    breakup_mode: BreakupMode | None
    head_speed_m_s: float | None
    head_z0_m: float | None
    satellites: int
    drop_volume_m3: float | None
    ligament_length_m: float | None
    frame_names: tuple[str, ...] = field(default=())
    silhouettes: tuple[Silhouette, ...] = field(default=(), repr=False)
    head_tail: HeadTail | None = None
    thinning: Thinning | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames analysed."""
        return int(self.times_s.size)

    @property
    def breakup_window_s(self) -> tuple[float | None, float | None]:
        """Times of the frame before breakup and of the breakup frame, s."""
        k = self.breakup_frame
        if k is None:
            return (None, None)
        before = float(self.times_s[k - 1]) if k > 0 else None
        return (before, float(self.times_s[k]))

    @property
    def drop_diameter_m(self) -> float | None:
        """Diameter of the sphere with the drop volume, m."""
        if self.drop_volume_m3 is None:
            return None
        return (6.0 * self.drop_volume_m3 / math.pi) ** (1.0 / 3.0)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable summary and per-frame values, units in the key names.

        Returns
        -------
        dict
            ``None`` stands for values that could not be measured (NaN).

        Examples
        --------
        >>> json.dumps(result.to_dict())  # doctest: +SKIP
        """
        lo, hi = self.breakup_window_s
        return {
            "n_frames": self.n_frames,
            "pixel_size_m": float(self.pixel_size_m),
            "frame_interval_s": float(self.frame_interval_s),
            "nozzle_row_px": int(self.nozzle_row),
            "threshold_rel": float(self.threshold),
            "shadow_level_rel": float(self.shadow_level),
            "breakup_frame_index": self.breakup_frame,
            "breakup_time_s": _opt(self.breakup_time_s),
            "breakup_window_s": [_opt(lo), _opt(hi)],
            "breakup_z_m": _opt(self.breakup_z_m),
            "breakup_mode": self.breakup_mode,
            "head_speed_m_s": _opt(self.head_speed_m_s),
            "head_z0_m": _opt(self.head_z0_m),
            "satellites_count": int(self.satellites),
            "drop_volume_m3": _opt(self.drop_volume_m3),
            "drop_diameter_m": _opt(self.drop_diameter_m),
            "ligament_length_m": _opt(self.ligament_length_m),
            "head_tail": None if self.head_tail is None else self.head_tail.to_dict(),
            "ligament_thinning_m_s": None if self.thinning is None else self.thinning.speed_m_s,
            "ligament_thinning_rate_per_s": (
                None if self.thinning is None else self.thinning.rate_per_s
            ),
            "frames": {
                "name": list(self.frame_names),
                "time_s": _list(self.times_s),
                "head_z_m": _list(self.head_z_m),
                "attached": [bool(a) for a in self.attached],
                "n_detached_bodies": [int(n) for n in self.n_bodies],
                "ligament_length_m": _list(self.ligament_lengths_m),
                "body_z_m": [_list(z) for z in self.body_z_m],
                "body_volume_m3": [_list(v) for v in self.body_volume_m3],
                "used_for_speed_fit": [bool(f) for f in self.fit_frames],
            },
        }


# ---------------------------------------------------------------------------- analysis


def as_frames(frames: np.ndarray | Sequence[np.ndarray]) -> np.ndarray:
    """Frames as a validated gray float stack, as :func:`analyze` reads them.

    Parameters
    ----------
    frames : numpy.ndarray or sequence of numpy.ndarray
        Gray frames ``(n, h, w)`` or one ``(h, w)`` frame, or RGB(A) frames
        ``(n, h, w, 3 | 4)``; integer or float gray levels.

    Returns
    -------
    numpy.ndarray
        Float frames of shape ``(n, h, w)``: integers divided by their dtype's maximum,
        floats divided by their maximum if it exceeds 1, RGB(A) converted to gray.

    Raises
    ------
    ValueError
        For another shape, frames smaller than 3 x 3 px, or NaN/inf values.
    """
    arr = np.asarray(frames)
    if arr.ndim == 4 and arr.shape[-1] in (3, 4):
        arr = _rgb_to_gray(_to_float(arr))
    elif arr.ndim in (2, 3):
        arr = _to_float(arr)
    else:
        raise ValueError(f"frames must have shape (n, h, w) or (h, w), got {arr.shape}")
    if arr.ndim == 2:
        arr = arr[None]
    if arr.shape[0] == 0 or arr.shape[1] < 3 or arr.shape[2] < 3:
        raise ValueError(f"need at least one frame of at least 3 x 3 px, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("frames contain NaN or infinite values")
    return arr


def _flatten(frame: np.ndarray, smooth_px: float) -> np.ndarray:
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


def _shadow_level(flat: np.ndarray) -> float:
    from skimage.filters import threshold_otsu

    sample = flat.ravel()
    if sample.size > 2_000_000:
        sample = sample[:: sample.size // 1_000_000]
    if np.ptp(sample) < 1e-6:  # flat images: no silhouette at all
        return 1.0
    otsu = float(threshold_otsu(sample))
    dark = sample[sample < otsu]
    return float(np.median(dark)) if dark.size else 1.0


def _clean(mask: np.ndarray, min_area_px: int) -> np.ndarray:
    """Fill holes and drop components smaller than ``min_area_px`` (8-connected)."""
    filled = ndimage.binary_fill_holes(mask)
    lab, n = ndimage.label(filled, structure=np.ones((3, 3), bool))
    if n == 0:
        return filled
    areas = np.bincount(lab.ravel())
    keep = areas >= min_area_px
    keep[0] = False
    return keep[lab]


def _detect_nozzle_row(mask: np.ndarray) -> int:
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
class _Body:
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
class _Frame:
    bodies: tuple[_Body, ...]  # sorted by top row
    leading: _Body | None
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


def _measure_frame(
    flat: np.ndarray, mask: np.ndarray, thr: float, nozzle_row: int, px: float
) -> _Frame:
    h, w = flat.shape
    first = nozzle_row + 1  # first liquid row

    def z_of(y_index: float | np.ndarray) -> Any:
        # y_index: row index (pixel-centre coordinates); exit plane at edge ``first``.
        return (np.asarray(y_index) + 0.5 - first) * px

    liquid = np.zeros_like(mask)
    liquid[first:] = mask[first:]
    lab, _ = ndimage.label(liquid, structure=np.ones((3, 3), bool))
    bodies: list[_Body] = []
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
            _Body(
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
    return _Frame(
        bodies=tuple(bodies),
        leading=leading,
        touches_bottom=leading is not None and leading.bottom == h - 1,
        gaps=gaps,
    )


def analyze(
    frames: np.ndarray | Sequence[np.ndarray],
    *,
    pixel_size_m: float | None = None,
    frame_interval_s: float | None = None,
    nozzle_row: int | None = None,
    t0_s: float = 0.0,
    threshold_fraction: float = 0.5,
    min_area_px: int = 6,
    smooth_px: float = 1.0,
    frame_names: Sequence[str] | None = None,
) -> DropletAnalysis:
    """Measure head motion, breakup, pinch-off mode, satellites and drop volume.

    The method (background flattening, threshold, nozzle detection, per-frame bodies,
    choice of the breakup gap) is described in the module docstring.

    Parameters
    ----------
    frames : numpy.ndarray or sequence of numpy.ndarray
        Gray frames ``(n, h, w)`` (or RGB ``(n, h, w, 3|4)``, or one frame); any scale
        (integers, floats), dark liquid on a bright background, jet running down.
    pixel_size_m : float
        Object-plane pixel size, m (required, > 0).
    frame_interval_s : float
        Time between frames, s (required, > 0). With a strobed camera (one image per drop,
        delay stepped) this is the delay step.
    nozzle_row : int, optional
        Index of the last nozzle row (exit plane at its lower edge); ``-1`` for an exit
        plane at the top edge. Detected in the first frame if omitted.
    t0_s : float, optional
        Time of the first frame, s.
    threshold_fraction : float, optional
        Where between background (0) and shadow (1) the liquid edge lies (default 0.5).
    min_area_px : int, optional
        Smaller dark components are noise (default 6 px).
    smooth_px : float, optional
        Gaussian smoothing before thresholding, pixels (default 1; 0 = none).
    frame_names : sequence of str, optional
        Names of the frames, kept in the result.

    Returns
    -------
    DropletAnalysis
        Per-frame measurements and the summary.

    Raises
    ------
    ValueError
        If the pixel size or frame interval is missing or not positive, the frames are
        malformed, the nozzle cannot be found and ``nozzle_row`` is not given, or no frame
        shows a jet (liquid below the nozzle with its head in view: noise, a blank).

    Examples
    --------
    >>> res = analyze(frames, pixel_size_m=2e-6, frame_interval_s=10e-6)  # doctest: +SKIP
    >>> res.breakup_time_s, res.breakup_mode  # doctest: +SKIP
    (6e-05, 'front')
    """
    if pixel_size_m is None:
        raise MissingSettingError(
            "pixel_size_m",
            "pixel size is required: give pixel_size_m (m per pixel in the object plane)",
        )
    px = check_positive("pixel_size_m", pixel_size_m, "m")
    if frame_interval_s is None:
        raise MissingSettingError(
            "frame_interval_s",
            "frame interval is required: give frame_interval_s (s between frames)",
        )
    dt = check_positive("frame_interval_s", frame_interval_s, "s")
    check_finite("t0_s", t0_s, "s")
    check_in_range(
        "threshold_fraction", threshold_fraction, 0.0, 1.0, low_closed=False, high_closed=False
    )
    check_int("min_area_px", min_area_px, 1, "px")
    check_nonnegative("smooth_px", smooth_px, "px")
    data = as_frames(frames)
    n, h, _w = data.shape
    names = tuple(frame_names) if frame_names is not None else ()
    if names and len(names) != n:
        raise ValueError(f"got {len(names)} frame names for {n} frames")

    flat = np.stack([_flatten(f, smooth_px) for f in data])
    shadow = _shadow_level(flat)
    if shadow > 0.9:
        raise ValueError(
            f"no dark silhouette found: shadow level {shadow:.3f} of the background "
            "(need liquid darker than the background)"
        )
    thr = 1.0 - threshold_fraction * (1.0 - shadow)
    masks = np.stack([_clean(f < thr, min_area_px) for f in flat])

    if nozzle_row is None:
        nozzle_row = _detect_nozzle_row(masks[0])
    elif isinstance(nozzle_row, bool) or not isinstance(nozzle_row, int | np.integer):
        raise ValueError(f"nozzle_row must be an integer row index, got {nozzle_row!r}")
    if not -1 <= nozzle_row < h - 1:
        raise ValueError(f"nozzle_row must be in [-1, {h - 2}] px, got {nozzle_row} px")
    nozzle_row = int(nozzle_row)

    measured = [_measure_frame(f, m, thr, nozzle_row, px) for f, m in zip(flat, masks, strict=True)]
    times = t0_s + dt * np.arange(n)
    head = np.full(n, np.nan)
    lig = np.full(n, np.nan)
    attached = np.array([any(b.attached for b in fr.bodies) for fr in measured])
    detached = [[b for b in fr.bodies if not b.attached] for fr in measured]
    n_bodies = np.array([len(d) for d in detached], dtype=int)
    head_gone = np.zeros(n, dtype=bool)
    seen_edge = False
    for k, fr in enumerate(measured):
        head_gone[k] = (k > 0 and bool(head_gone[k - 1])) or (seen_edge and not fr.touches_bottom)
        seen_edge = seen_edge or fr.touches_bottom
        if fr.leading is None or fr.touches_bottom or head_gone[k]:
            continue
        head[k] = fr.leading.tip_z_m
        base = 0.0 if fr.leading.attached else fr.leading.tail_z_m
        lig[k] = fr.leading.tip_z_m - base

    if not np.isfinite(head).any():  # noise, a blank or a wrongly lit sequence
        raise ValueError(
            f"no jet found: in none of the {n} frames does liquid hang from the nozzle "
            f"(row {nozzle_row}) with its head inside the field of view (shadow level "
            f"{shadow:.3f} of the background); check that the liquid is darker than the "
            "background, the nozzle row and the threshold"
        )

    # Head speed: every frame with the head in view and out of the nozzle.
    fit = np.isfinite(head) & (head > 0.0)
    speed: float | None = None
    z0: float | None = None
    if fit.sum() >= 2:
        slope, intercept = np.polyfit(times[fit], head[fit], 1)
        speed, z0 = float(slope), float(intercept)
    else:
        fit[:] = False

    # Breakup.
    hits = np.flatnonzero(n_bodies >= 1)
    kb = int(hits[0]) if hits.size else None
    t_b = z_b = lig_b = None
    mode: BreakupMode | None = None
    if kb is not None:
        t_b = float(times[kb])
        gaps = measured[kb].gaps
        if gaps:
            z_b = max(gaps, key=lambda g: (g[0], g[1]))[1]
            tip = head[kb]
            if math.isfinite(tip) and tip > 0.0:
                mode = classify_pinch(min(max(z_b, 0.0), tip), tip)
        lig_b = _opt(lig[kb])

    # Last frame: satellites and drop volume.
    last = n - 1
    lead = measured[last].leading
    head_is_detached = lead is not None and not lead.attached and not head_gone[last]
    satellites = int(n_bodies[last]) - (1 if head_is_detached else 0)
    volume: float | None = None
    for k in range(n - 1, -1, -1):
        fr = measured[k]
        if fr.leading is None or head_gone[k]:
            continue
        if not fr.touches_bottom and not fr.leading.attached:
            volume = fr.leading.volume_m3
            break

    sils = _silhouettes(measured, times, px)
    before = kb - 1 if kb is not None and kb > 0 else None
    ht = head_and_tail(sils[before]) if before is not None else None
    thin = thinning_rate(sils, float(times[kb])) if kb is not None else None
    return DropletAnalysis(
        times_s=times,
        head_z_m=head,
        attached=attached,
        n_bodies=n_bodies,
        ligament_lengths_m=lig,
        body_z_m=tuple(np.array([b.centroid_z_m for b in d]) for d in detached),
        body_volume_m3=tuple(np.array([b.volume_m3 for b in d]) for d in detached),
        fit_frames=fit,
        pixel_size_m=px,
        frame_interval_s=dt,
        nozzle_row=nozzle_row,
        threshold=float(thr),
        shadow_level=float(shadow),
        breakup_frame=kb,
        breakup_time_s=t_b,
        breakup_z_m=z_b,
        breakup_mode=mode,
        head_speed_m_s=speed,
        head_z0_m=z0,
        satellites=satellites,
        drop_volume_m3=volume,
        ligament_length_m=lig_b,
        frame_names=names,
        silhouettes=tuple(sils),
        head_tail=ht,
        thinning=thin,
    )


def _silhouettes(measured: Sequence[_Frame], times: np.ndarray, px: float) -> list[Silhouette]:
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


def _read_sidecar(folder: Path) -> dict[str, Any]:
    path = folder / SIDECAR_NAME
    if not path.is_file():
        return {}
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read sidecar {path}: {exc}") from exc
    if not isinstance(meta, dict):
        raise ValueError(f"sidecar {path} must hold a JSON object, got {type(meta).__name__}")
    return meta


def analyze_folder(
    directory: str | Path,
    *,
    pixel_size_m: float | None = None,
    frame_interval_s: float | None = None,
    nozzle_row: int | None = None,
    t0_s: float | None = None,
    pattern: str | None = None,
    threshold_fraction: float = 0.5,
    min_area_px: int = 6,
    smooth_px: float = 1.0,
) -> DropletAnalysis:
    """Load a folder of frames and analyse it (see :func:`analyze`).

    Values not passed are taken from a ``frames.json`` sidecar in the folder if present
    (keys ``pixel_size_m``, ``frame_interval_s``, ``nozzle_row``, ``t0_s``); passed values
    win. Without a pixel size or frame interval from either source a ``ValueError`` says so.

    Parameters
    ----------
    directory : str or pathlib.Path
        Folder with the frames (see :func:`load_frames`).
    pixel_size_m, frame_interval_s, nozzle_row, t0_s : optional
        As for :func:`analyze`; ``None`` = from the sidecar (``t0_s`` default 0,
        ``nozzle_row`` detected).
    pattern : str, optional
        Glob pattern of the frame files.
    threshold_fraction, min_area_px, smooth_px : optional
        As for :func:`analyze`.

    Returns
    -------
    DropletAnalysis
        The analysis, with the file names as ``frame_names``.

    Examples
    --------
    >>> res = analyze_folder("run_50V", pixel_size_m=2e-6, frame_interval_s=5e-6)  # doctest: +SKIP
    >>> res.to_dict()["breakup_time_s"]  # doctest: +SKIP
    9.5e-05
    """
    folder = Path(directory)
    frames, names = load_frames(folder, pattern=pattern)
    meta = _read_sidecar(folder)
    for key in ("pixel_size_m", "frame_interval_s", "nozzle_row", "t0_s"):
        value = meta.get(key)
        if key not in meta or (value is None and key == "nozzle_row"):  # null: detect it
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{folder / SIDECAR_NAME}: {key} = {value!r} is not a number")
    if pixel_size_m is None:
        pixel_size_m = meta.get("pixel_size_m")
    if pixel_size_m is None:
        raise MissingSettingError(
            "pixel_size_m",
            "pixel size is required: give pixel_size_m (m per pixel) "
            f'or put "pixel_size_m" in {folder / SIDECAR_NAME}',
        )
    if frame_interval_s is None:
        frame_interval_s = meta.get("frame_interval_s")
    if frame_interval_s is None:
        raise MissingSettingError(
            "frame_interval_s",
            "frame interval is required: give frame_interval_s (s) "
            f'or put "frame_interval_s" in {folder / SIDECAR_NAME}',
        )
    if nozzle_row is None:
        nozzle_row = meta.get("nozzle_row")
    if t0_s is None:
        t0_s = meta.get("t0_s", 0.0)
    return analyze(
        frames,
        pixel_size_m=pixel_size_m,
        frame_interval_s=frame_interval_s,
        nozzle_row=nozzle_row,
        t0_s=t0_s,
        threshold_fraction=threshold_fraction,
        min_area_px=min_area_px,
        smooth_px=smooth_px,
        frame_names=names,
    )
