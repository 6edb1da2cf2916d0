"""Tracking metrics of a circle-field job (seed 001 §4.2, Figs. 12-13), twin and hardware.

The same numbers come from a twin run (the nanomanipulator job) and from a measured
trace (``microfab nanomanipulator analyze``, `microfab.measure.circle_trace`); the table
that sets them beside the seed's is `microfab.report.circle_tracking.tracking_table`.

Definitions (ours; the seed states none):

* **Error**: the error the sensor shows, ``e = r − y`` (reference minus measured output),
  mm, per axis.
* **Circle run**: the ``periods`` whole periods of a circle from its first full-rate
  sample (`microfab.trajectory.circle_pattern.PatternReference.starts`); the moves,
  pauses, spin-up and spin-down between circles are left out of every metric.
* **Axial RMS** (seed 001 §4.2, Fig. 13a: x 485.8 nm, y 885.8 nm): RMS of ``e`` per axis
  over the runs of every circle.
* **Contour error**: the signed radial error of the output, ``‖y − c‖ − R`` (positive
  outside the circle), c the circle's centre; its RMS over the same samples is the
  contour RMS (seed 001 §4.2, Fig. 13b: 769.5 nm).
* **Phase**: the unwrapped angle of the reference about the centre, counted from the run's
  first sample (0 there, growing by 2π per period). Fig. 13b's curve (seed 001 §4.2:
  "the contour errors of the four circles are averaged"; it "starts from zero as there
  is a pause before every circle") is the contour error of each circle binned on this
  phase over its whole run, then averaged over the circles.
* **Period RMS**: RMS over one period of the error norm ``‖e‖`` (the RC's convergence and
  the gate's criterion, `microfab.control.gate`).
* **Gate period**: the 1-based period of a circle whose start is nearest the first sample
  with the laser on (with no warm-up lead this is the period in which the laser switched
  on; a lead shorter than half a period still names the exposed period); ``None`` when
  the laser never switched on for that circle. A circle's laser samples are those after
  the previous circle's run and up to the end of its own.
* **Exposed RMS**: RMS of ``‖e‖`` over the laser-on samples of a circle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.validate import check_int, check_positive
from microfab.trajectory.circle_pattern import PatternReference

__all__ = [
    "SEED_AXIAL_RMS_NM",
    "SEED_CONTOUR_RMS_NM",
    "SEED_GATE_PERIODS",
    "TrackingMetrics",
    "contour_error",
    "pattern_metrics",
    "period_rms",
    "phase_of",
    "tracking_metrics",
]

NM_PER_MM = 1e6
#: seed 001 §4.2 / Fig. 13a (``shared/seeds/001_44fdd8e8f587fd7f.txt``): axial tracking
#: errors, read as RMS (the contour RMS agrees: sqrt((485.8² + 885.8²)/2) = 714 nm).
SEED_AXIAL_RMS_NM = {"x": 485.8, "y": 885.8}
SEED_CONTOUR_RMS_NM = 769.5  # seed 001 §4.2 / Fig. 13b: contour error, RMS over phase
SEED_GATE_PERIODS = (3, 4)  # seed 001 §4.2: error reaches submicrons in 3-4 periods
#: Phase bins per period of the Fig. 13b curve (1°, assumed: finer than the seed's plot).
BINS_PER_PERIOD = 360


def _xy(name: str, value: np.ndarray, n: int | None = None) -> np.ndarray:
    """``value`` as a finite float array shaped (n, 2), else ValueError naming it."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or (n is not None and a.shape[0] != n):
        want = f"({'n' if n is None else n}, 2)"
        raise ValueError(f"{name} must be shaped {want} (x, y in mm), got {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        raise ValueError(f"{name} holds {a[k, j]} at sample {k}, axis {'xy'[j]}; give finite mm")
    return a


def contour_error(position: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """Signed radial error ``‖p − c‖ − R`` of positions about a circle.

    Parameters
    ----------
    position : numpy.ndarray
        Positions, mm, shape (n, 2).
    centre : numpy.ndarray
        Circle centre, mm, shape (2,).
    radius : float
        Circle radius, mm (> 0).

    Returns
    -------
    numpy.ndarray
        Contour error, mm, shape (n,); positive outside the circle.
    """
    p = _xy("position", position)
    c = np.asarray(centre, dtype=np.float64)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre must be a finite (x, y) in mm, got {centre!r}")
    check_positive("radius", radius, "mm")
    return np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - radius


def phase_of(reference: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Unwrapped angle of the reference about the centre, from its first sample.

    Parameters
    ----------
    reference : numpy.ndarray
        Reference positions, mm, shape (n >= 1, 2) (none at the centre).
    centre : numpy.ndarray
        Centre, mm, shape (2,).

    Returns
    -------
    numpy.ndarray
        Phase, rad, shape (n,): 0 at the first sample, counter-clockwise positive,
        unwrapped (a run of k periods ends near 2πk).
    """
    r = _xy("reference", reference)
    c = np.asarray(centre, dtype=np.float64)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError(f"centre must be a finite (x, y) in mm, got {centre!r}")
    if r.shape[0] == 0:
        raise ValueError("reference holds no samples")
    d = r - c
    if np.any(np.hypot(d[:, 0], d[:, 1]) == 0.0):
        raise ValueError("the reference passes through the centre: its phase is undefined there")
    ang = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return ang - ang[0]


def period_rms(error: np.ndarray, start: int, period_samples: int, periods: int) -> np.ndarray:
    """RMS of the error norm over each of ``periods`` periods from ``start``.

    Parameters
    ----------
    error : numpy.ndarray
        Error, any unit, shape (n,) or (n, n_axes).
    start : int
        First sample of the first period.
    period_samples : int
        Samples per period (>= 1).
    periods : int
        Periods (>= 1); the last must end within the error.

    Returns
    -------
    numpy.ndarray
        ``sqrt(mean over the period of ‖e‖²)`` per period, the error's unit, shape
        (periods,).
    """
    e = np.asarray(error, dtype=np.float64)
    e = e[:, None] if e.ndim == 1 else e
    if e.ndim != 2:
        raise ValueError(f"error must be shaped (n,) or (n, n_axes), got {np.shape(error)}")
    s = check_int("start", start, 0, "samples")
    n = check_int("period_samples", period_samples, 1, "samples")
    k = check_int("periods", periods, 1, "periods")
    if s + k * n > e.shape[0]:
        raise ValueError(
            f"{k} periods of {n} samples from sample {s} end at {s + k * n}, past the "
            f"{e.shape[0]} samples of the error"
        )
    block = e[s : s + k * n].reshape(k, n, e.shape[1])
    return np.sqrt(np.mean(np.sum(block**2, axis=2), axis=1))


def _bin_mean(values: np.ndarray, index: np.ndarray, n_bins: int) -> np.ndarray:
    """Mean of ``values`` per bin ``index`` (NaN for an empty bin)."""
    count = np.bincount(index, minlength=n_bins)
    total = np.bincount(index, weights=values, minlength=n_bins)
    out = np.full(n_bins, np.nan)
    np.divide(total, count, out=out, where=count > 0)
    return out


def _mean_over_circles(curves: np.ndarray) -> np.ndarray:
    """Mean over axis 0 of the bins that hold samples (NaN where no circle has any)."""
    have = np.isfinite(curves)
    count = have.sum(axis=0)
    total = np.where(have, curves, 0.0).sum(axis=0)
    out = np.full(curves.shape[1], np.nan)
    np.divide(total, count, out=out, where=count > 0)
    return out


@dataclass(frozen=True, kw_only=True, eq=False)
class TrackingMetrics:
    """The seed 001 §4.2 metrics of one job (definitions: module docstring).

    Attributes
    ----------
    axial_rms_nm : numpy.ndarray
        RMS error per axis (x, y), nm, shape (2,).
    contour_rms_nm : float
        RMS contour error, nm.
    period_rms_nm : numpy.ndarray
        RMS error norm per period, nm, shape (n_circles, periods).
    phase_rad : numpy.ndarray
        Bin centres of the phase grid, rad, shape (bins_per_period * periods,).
    contour_vs_phase_nm : numpy.ndarray
        Contour error binned on phase, mean over circles, nm, shape like ``phase_rad``.
    gate_period : tuple of (int or None)
        Per circle, the 1-based period the laser switched on for (None: never).
    gate_sample : tuple of (int or None)
        Per circle, the first sample with the laser on (None: never).
    exposed_rms_nm : tuple of (float or None)
        Per circle, RMS error norm over its laser-on samples, nm (None: never on).
    starts : tuple of int
        First sample of each circle's run.
    period_samples : int
        Samples per period.
    dt : float
        Sample time, s.
    """

    axial_rms_nm: np.ndarray
    contour_rms_nm: float
    period_rms_nm: np.ndarray
    phase_rad: np.ndarray
    contour_vs_phase_nm: np.ndarray
    gate_period: tuple[int | None, ...]
    gate_sample: tuple[int | None, ...]
    exposed_rms_nm: tuple[float | None, ...]
    starts: tuple[int, ...]
    period_samples: int
    dt: float

    @property
    def n_circles(self) -> int:
        """Circles in the job."""
        return len(self.starts)

    @property
    def periods(self) -> int:
        """Periods per circle."""
        return int(self.period_rms_nm.shape[1])

    def summary(self) -> dict[str, Any]:
        """JSON-ready numbers (no arrays longer than the periods), seed values beside."""
        return {
            "axial_rms_nm": {"x": float(self.axial_rms_nm[0]), "y": float(self.axial_rms_nm[1])},
            "contour_rms_nm": float(self.contour_rms_nm),
            "period_rms_nm": self.period_rms_nm.tolist(),
            "gate_period": list(self.gate_period),
            "gate_time_s": [None if k is None else k * self.dt for k in self.gate_sample],
            "exposed_rms_nm": list(self.exposed_rms_nm),
            "periods": self.periods,
            "period_samples": self.period_samples,
            "dt_s": self.dt,
            "seed": {
                "axial_rms_nm": dict(SEED_AXIAL_RMS_NM),
                "contour_rms_nm": SEED_CONTOUR_RMS_NM,
                "gate_periods": list(SEED_GATE_PERIODS),
            },
        }


def tracking_metrics(
    reference: np.ndarray,
    output: np.ndarray,
    laser: np.ndarray,
    *,
    starts: tuple[int, ...],
    period_samples: int,
    periods: int,
    centres: np.ndarray,
    radius: float,
    dt: float = 1e-4,
    bins_per_period: int | None = None,
) -> TrackingMetrics:
    """The seed 001 §4.2 metrics of a job (definitions: module docstring).

    Parameters
    ----------
    reference, output : numpy.ndarray
        Reference and measured output, mm, shape (n, 2).
    laser : numpy.ndarray
        Laser on per sample, bool, shape (n,).
    starts : tuple of int
        First sample of each circle's run, increasing, runs not overlapping.
    period_samples : int
        Samples per period (>= 2).
    periods : int
        Periods per circle run (>= 1).
    centres : numpy.ndarray
        Circle centres, mm, shape (len(starts), 2).
    radius : float
        Circle radius, mm.
    dt : float
        Sample time, s (for the gate times of `TrackingMetrics.summary`; default the
        twin's assumed 10 kHz).
    bins_per_period : int, optional
        Phase bins per period of the contour-vs-phase curve, <= period_samples (default
        `BINS_PER_PERIOD`, or one per sample when the period is shorter).

    Returns
    -------
    TrackingMetrics
    """
    r = _xy("reference", reference)
    n = r.shape[0]
    y = _xy("output", output, n)
    on = np.asarray(laser)
    if on.shape != (n,) or on.dtype != np.bool_:
        raise ValueError(f"laser must be bool shaped ({n},), got {on.dtype} {on.shape}")
    N = check_int("period_samples", period_samples, 2, "samples")
    k = check_int("periods", periods, 1, "periods")
    check_positive("dt", dt, "s")
    bins = min(BINS_PER_PERIOD, N) if bins_per_period is None else bins_per_period
    bins = check_int("bins_per_period", bins, 1, "bins")
    if bins > N:
        raise ValueError(f"bins_per_period ({bins}) must not exceed period_samples ({N})")
    c = np.asarray(centres, dtype=np.float64)
    st = tuple(check_int(f"start {i}", s, 0, "samples") for i, s in enumerate(starts))
    if not st or c.shape != (len(st), 2) or not np.all(np.isfinite(c)):
        raise ValueError(
            f"centres must be finite and shaped ({len(st)}, 2), one per start (at least "
            f"one), got {c.shape}"
        )
    check_positive("radius", radius, "mm")
    span = k * N
    for i, s in enumerate(st):
        if (i and s < st[i - 1] + span) or s + span > n:
            raise ValueError(
                f"circle {i} run [{s}, {s + span}) overlaps the previous one or ends past "
                f"the {n} samples: starts must increase by at least periods x period_samples"
            )
    e = r - y
    runs = np.concatenate([np.arange(s, s + span) for s in st])
    axial = np.sqrt(np.mean(e[runs] ** 2, axis=0)) * NM_PER_MM
    n_bins = bins * k
    width = 2.0 * np.pi / bins
    curves, contour_all, per_period = [], [], []
    gate_p: list[int | None] = []
    gate_k: list[int | None] = []
    exposed: list[float | None] = []
    for i, s in enumerate(st):
        sl = slice(s, s + span)
        ce = contour_error(y[sl], c[i], radius)
        contour_all.append(ce)
        ph = phase_of(r[sl], c[i])
        # a sample on a bin's lower edge (bins dividing the period) belongs to that bin
        idx = np.clip(np.floor(ph / width + 1e-6).astype(np.int64), 0, n_bins - 1)
        curves.append(_bin_mean(ce, idx, n_bins))
        per_period.append(period_rms(e, s, N, k))
        lo = st[i - 1] + span if i else 0
        hits = np.flatnonzero(on[lo : s + span])
        if hits.size:
            first = lo + int(hits[0])
            gate_k.append(first)
            gate_p.append(max(int(np.floor((first - s) / N + 0.5)), 0) + 1)
            e_on = e[lo : s + span][hits]
            exposed.append(float(np.sqrt(np.mean(np.sum(e_on**2, axis=1)))) * NM_PER_MM)
        else:
            gate_k.append(None)
            gate_p.append(None)
            exposed.append(None)
    contour = np.concatenate(contour_all)
    return TrackingMetrics(
        axial_rms_nm=axial,
        contour_rms_nm=float(np.sqrt(np.mean(contour**2))) * NM_PER_MM,
        period_rms_nm=np.array(per_period) * NM_PER_MM,
        phase_rad=(np.arange(n_bins) + 0.5) * width,
        contour_vs_phase_nm=_mean_over_circles(np.array(curves)) * NM_PER_MM,
        gate_period=tuple(gate_p),
        gate_sample=tuple(gate_k),
        exposed_rms_nm=tuple(exposed),
        starts=st,
        period_samples=N,
        dt=float(dt),
    )


def pattern_metrics(
    pattern: PatternReference,
    output: np.ndarray,
    laser: np.ndarray,
    *,
    reference: np.ndarray | None = None,
) -> TrackingMetrics:
    """`tracking_metrics` of a job of the §4.2 pattern (circle runs, centres from it).

    Parameters
    ----------
    pattern : PatternReference
        The job's pattern.
    output : numpy.ndarray
        Measured output, mm, shape (pattern.n_samples, 2).
    laser : numpy.ndarray
        Laser on per sample, bool, shape (pattern.n_samples,).
    reference : numpy.ndarray, optional
        The reference the sensor's error is taken against (default the pattern's).
    """
    return tracking_metrics(
        pattern.position if reference is None else reference,
        output,
        laser,
        starts=pattern.starts,
        period_samples=pattern.period_samples,
        periods=pattern.periods,
        centres=pattern.centres,
        radius=pattern.radius_mm,
        dt=pattern.dt,
    )
