"""Measured runs of the black-box XY stage (seed 002) and the errors of a model on them.

What both stage models read (`microfab.identify.stage_data` for the linear model,
`microfab.identify.stage_ann` for the networks), below both:

* `stage_record`: one run read from a trace (``time``, ``input_x``, ``input_y``,
  ``output_x``, ``output_y``, m), checked: a rate that is a multiple of 400 Hz (the ANN's
  rate, seed 002 §III-B, so the same files serve both models; `check_rate`), at least
  500 ms (the ANN's input history, §III-B), every input inside Table I's workspace, every
  output within 1 m. The trace itself has already refused NaN and a non-uniform or
  non-increasing time (`Trace.from_columns`).
* `record_trace`: a run as such a trace (what ``microfab stage play`` writes).
* `RunErrors`: the simulation error ``y - y_model`` of a model per axis, pooled over runs
  (Table II's μ, σ), as both models report it.

`microfab.identify.stage_data` re-exports these names.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.limits import MachineLimits
from microfab.core.signals import Trace
from microfab.core.validate import check_positive

__all__ = [
    "AXES",
    "BASE_RATE_HZ",
    "COLUMNS",
    "MIN_RUN_S",
    "RunErrors",
    "StageRecord",
    "check_rate",
    "record_trace",
    "stage_record",
]

AXES = ("x", "y")
#: Columns of a measured run besides ``time`` (as ``microfab ilc step`` names them).
COLUMNS = ("input_x", "input_y", "output_x", "output_y")
#: The ANN's sample rate, Hz (seed 002 §III-B: "a sample frequency of 400 Hz"); a run's rate
#: must be a whole multiple of it.
BASE_RATE_HZ = 400.0
#: Shortest run, s (seed 002 §III-B: the ANN reads "the most recent 500 ms").
MIN_RUN_S = 0.5
_WORKSPACE = MachineLimits.seed002_stage().workspace  # seed 002 Table I: [-0.19, 0.19]^2 m
#: Largest |output| accepted, m (assumed: the stage travels ±0.19 m; a metre or more is a
#: unit or column error, and 1e300 would overflow the fit).
_OUTPUT_BOUND_M = 1.0
_RATE_RTOL = 1e-6  # rate / 400 Hz within this of a whole number


@dataclass(frozen=True, eq=False)
class StageRecord:
    """One measured run: set-points and encoder positions of both axes, from rest.

    Attributes
    ----------
    name : str
        Where it came from (a file name), for messages.
    u : numpy.ndarray
        Set-points ``input_x``, ``input_y``, m, shape (n, 2), read-only.
    y : numpy.ndarray
        Positions ``output_x``, ``output_y``, m, shape (n, 2), read-only.
    """

    name: str
    u: np.ndarray
    y: np.ndarray

    def __post_init__(self) -> None:
        for attr in ("u", "y"):
            a = np.asarray(getattr(self, attr), dtype=np.float64)
            if a.ndim != 2 or a.shape[1] != 2:
                raise ValueError(f"{self.name}: {attr} must have shape (n, 2), got {a.shape}")
            bad = np.argwhere(~np.isfinite(a))
            if bad.size:
                k, c = (int(v) for v in bad[0])
                col = ("input_" if attr == "u" else "output_") + AXES[c]
                raise ValueError(f"{self.name}: {col} is {a[k, c]} at sample {k}")
            object.__setattr__(self, attr, readonly(a))
        if self.u.shape != self.y.shape:
            raise ValueError(
                f"{self.name}: inputs {self.u.shape} and outputs {self.y.shape} differ in length"
            )

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.u.shape[0])


def check_rate(dt: float, where: str = "the run") -> float:
    """The rate ``1 / dt`` (Hz), refused unless a whole multiple of `BASE_RATE_HZ`."""
    check_positive("dt", dt, "s")
    rate = 1.0 / dt
    k = rate / BASE_RATE_HZ
    if not math.isfinite(k) or k < 0.5 or abs(k - round(k)) > _RATE_RTOL * k:
        raise ValueError(
            f"{where} is sampled at {rate:.6g} Hz, not a whole multiple of "
            f"{BASE_RATE_HZ:g} Hz (seed 002: the ANN runs at 400 Hz; the stage's loop at "
            "10 kHz); record at 10 kHz"
        )
    return rate


def stage_record(trace: Trace, name: str = "run") -> StageRecord:
    """A measured run from a trace, checked (module docstring).

    Parameters
    ----------
    trace : Trace
        With axes `COLUMNS` (others ignored), unit ``"m"`` or none.
    name : str
        Named in the messages (the file).

    Returns
    -------
    StageRecord

    Raises
    ------
    ValueError
        A missing column, another unit, a rate that is no multiple of 400 Hz, a run
        shorter than 500 ms, an input outside the workspace.
    """
    missing = [c for c in COLUMNS if c not in trace.axes]
    if missing:
        hint = ""
        if set(missing) == {"output_x", "output_y"} and {"input_x", "input_y"} <= set(trace.axes):
            hint = (
                "; this file holds only the commands: play it first (`microfab stage play`, "
                "or on the machine, recording the encoders)"
            )
        raise ValueError(
            f"{name}: no column {missing[0]!r} (columns: time, {', '.join(trace.axes)}); a "
            f"stage run needs time, {', '.join(COLUMNS)} (m){hint}"
        )
    if trace.unit not in ("", "m"):
        raise ValueError(f"{name}: unit {trace.unit!r}; the stage's runs are in m")
    check_rate(trace.dt, name)
    duration = trace.n_samples * trace.dt
    if duration < MIN_RUN_S * (1.0 - 1e-9):
        raise ValueError(
            f"{name}: {trace.n_samples} samples ({duration:.4g} s) are shorter than "
            f"{MIN_RUN_S * 1e3:g} ms (seed 002 §III-B: the ANN reads 500 ms of history)"
        )
    idx = [trace.axes.index(c) for c in COLUMNS]
    rec = StageRecord(name=name, u=trace.values[:, idx[:2]], y=trace.values[:, idx[2:]])
    for a, (lo, hi) in enumerate(_WORKSPACE):
        col = rec.u[:, a]
        out = np.flatnonzero((col < lo) | (col > hi))
        if out.size:
            k = int(out[0])
            raise ValueError(
                f"{name}: input_{AXES[a]} = {col[k]:.6g} m at t = {trace.t0 + k * trace.dt:.6g} s "
                f"lies outside the workspace [{lo:g}, {hi:g}] m (seed 002 Table I)"
            )
    far = np.flatnonzero(np.abs(rec.y).max(axis=1) > _OUTPUT_BOUND_M)
    if far.size:
        k = int(far[0])
        raise ValueError(
            f"{name}: output ({rec.y[k, 0]:.6g}, {rec.y[k, 1]:.6g}) m at t = "
            f"{trace.t0 + k * trace.dt:.6g} s is beyond {_OUTPUT_BOUND_M:g} m: not a position "
            "of the stage in m (another unit or column?)"
        )
    return rec


def record_trace(record: StageRecord, dt: float) -> Trace:
    """A run as the trace `stage_record` reads back: ``time`` and `COLUMNS`, m, from t = 0.

    Parameters
    ----------
    record : StageRecord
        Set-points and positions, (n, 2) each, m.
    dt : float
        Sample time, s.
    """
    values = np.column_stack([record.u, record.y])
    return Trace(dt=dt, values=values, axes=COLUMNS, unit="m")


@dataclass(frozen=True, eq=False)
class RunErrors:
    """Simulation error ``y - y_model`` per axis over runs (seed 002 Table II μ, σ).

    Attributes
    ----------
    mean, std : numpy.ndarray
        Shape (len(axes),), m, over all runs' samples (population std about the mean).
    per_run : tuple of (str, numpy.ndarray, numpy.ndarray)
        ``(name, mean, std)`` of each run.
    n_samples : int
        Samples compared (at the model's rate).
    rate_hz : float
        Rate the comparison was made at (the model's own).
    axes : tuple of str
        The axes of ``mean``, ``std`` and each run's pair, in order (a network model may
        model one axis: `microfab.identify.stage_ann`).
    samples : numpy.ndarray or None
        Every error, shape (n_samples, len(axes)), m, runs one after another, when asked
        for (``keep``: histograms, pooling); else None.
    """

    mean: np.ndarray
    std: np.ndarray
    per_run: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    n_samples: int
    rate_hz: float
    axes: tuple[str, ...] = AXES
    samples: np.ndarray | None = None

    @classmethod
    def of(
        cls,
        errors: Iterable[tuple[str, np.ndarray]],
        rate_hz: float,
        axes: tuple[str, ...] = AXES,
        *,
        keep: bool = False,
    ) -> RunErrors:
        """Pool ``(name, e)`` of each run, ``e`` shape (n, len(axes)), m, into one result.

        The mean and (population) standard deviation are over every run's samples;
        each run keeps its own pair. ``keep`` keeps every sample (`samples`).
        """
        sums = np.zeros((2, len(axes)))
        n = 0
        per_run = []
        kept = []
        for name, e in errors:
            sums += (e.sum(axis=0), (e * e).sum(axis=0))
            n += e.shape[0]
            per_run.append((name, e.mean(axis=0), e.std(axis=0)))
            if keep:
                kept.append(e)
        if n == 0:
            raise ValueError("no error samples: give at least one run with samples")
        mean = sums[0] / n
        std = np.sqrt(np.maximum(sums[1] / n - mean**2, 0.0))
        return cls(
            mean=mean,
            std=std,
            per_run=tuple(per_run),
            n_samples=n,
            rate_hz=rate_hz,
            axes=axes,
            samples=readonly(np.concatenate(kept)) if keep else None,
        )

    @classmethod
    def pooled(cls, parts: Sequence[RunErrors]) -> RunErrors:
        """Several results kept with ``keep`` pooled into one (same rate and axes)."""
        if not parts or any(p.samples is None for p in parts):
            raise ValueError("pooling needs results made with keep=True")
        rates = {p.rate_hz for p in parts}
        axes = {p.axes for p in parts}
        if len(rates) != 1 or len(axes) != 1:
            raise ValueError(f"cannot pool errors at rates {rates} and axes {axes}")
        out = cls.of(
            ((str(k), p.samples) for k, p in enumerate(parts)),  # type: ignore[misc]
            parts[0].rate_hz,
            parts[0].axes,
            keep=True,
        )
        per_run = tuple(r for p in parts for r in p.per_run)
        return dataclasses.replace(out, per_run=per_run)
