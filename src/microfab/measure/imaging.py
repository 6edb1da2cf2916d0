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

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.core.validate import (
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
)
from microfab.measure.frame_bodies import (
    clean_mask,
    detect_nozzle_row,
    flatten,
    measure_frame,
    shadow_level,
    silhouettes,
)
from microfab.measure.frames import (
    IMAGE_SUFFIXES,
    SIDECAR_NAME,
    MissingSettingError,
    as_frames,
    load_frames,
    natural_key,
    read_sidecar,
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

    flat = np.stack([flatten(f, smooth_px) for f in data])
    shadow = shadow_level(flat)
    if shadow > 0.9:
        raise ValueError(
            f"no dark silhouette found: shadow level {shadow:.3f} of the background "
            "(need liquid darker than the background)"
        )
    thr = 1.0 - threshold_fraction * (1.0 - shadow)
    masks = np.stack([clean_mask(f < thr, min_area_px) for f in flat])

    if nozzle_row is None:
        nozzle_row = detect_nozzle_row(masks[0])
    elif isinstance(nozzle_row, bool) or not isinstance(nozzle_row, int | np.integer):
        raise ValueError(f"nozzle_row must be an integer row index, got {nozzle_row!r}")
    if not -1 <= nozzle_row < h - 1:
        raise ValueError(f"nozzle_row must be in [-1, {h - 2}] px, got {nozzle_row} px")
    nozzle_row = int(nozzle_row)

    measured = [measure_frame(f, m, thr, nozzle_row, px) for f, m in zip(flat, masks, strict=True)]
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

    sils = silhouettes(measured, times, px)
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
    meta = read_sidecar(folder)
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
