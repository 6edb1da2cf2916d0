"""Contour runs on the seed 004 stage twin: drawing → spline → controller → twin → errors.

`run_contour` plays a `microfab.machines.laser_stage.ContourJob` on the stage
(`laser_stage.play_contour`: the drawing's closed contour, its time-based spline, refused
beyond Table I, then the loop under one of the controllers of seed 004 or a baseline) and
measures what the seed's figures show (`microfab.measure.contour`): the axis errors over
the full-speed laps (Fig. 3) and the contour error per lap of the true and of the measured
positions (Figs. 4, 7). For a ``preview-dob`` run it also keeps the DOB's estimate of the
load force (`dob_estimate`).

`speed_sweep` runs one job at several speeds under several laws, each point saved as it
finishes and skipped when found again (`microfab.io.sweep.run_sweep`): the contour error
against speed of a ``laser-micromachining`` job.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.control.preview_dob import PreviewDOB
from microfab.io.sweep import SweepResult, run_sweep
from microfab.machines.laser_stage.machine import ContourJob, play_contour
from microfab.measure.contour import AxisErrors, ContourErrors, contour_errors
from microfab.sim.loop import reference_array
from microfab.trajectory.contour_laps import ContourReference

__all__ = ["ContourRun", "SpeedPoint", "dob_estimate", "run_contour", "speed_point", "speed_sweep"]


@dataclass(frozen=True, kw_only=True, eq=False)
class ContourRun:
    """A finished contour run.

    Attributes
    ----------
    job : ContourJob
        What ran.
    reference : ContourReference
        The reference (spline, samples, laps).
    output : numpy.ndarray
        True positions, m, shape (n, 2) (replayed from the twin's state).
    encoder : numpy.ndarray
        Encoder counts as positions (10 nm steps), m, shape (n, 2).
    measured : numpy.ndarray
        What the controller saw: encoder plus interpolation noise, m, shape (n, 2).
    command : numpy.ndarray
        Current references, A, shape (n, 2).
    force : numpy.ndarray
        Motor force ``K_f i`` after each sample, N, shape (n, 2).
    disturbance : numpy.ndarray
        True ``F_l`` over each sample, N, shape (n, 2).
    axis : AxisErrors
        Axis tracking errors (reference − measured) over the full-speed laps.
    contour : ContourErrors
        Contour error of the true positions against the exact contour, per lap.
    contour_measured : ContourErrors
        The same of the measured positions (what a ballbar on the encoder shows).
    dob : numpy.ndarray or None
        For a ``preview-dob`` run, the DOB's estimate of ``F_l`` at each sample, N, shape
        (n, 2) (`dob_estimate`; compare with ``disturbance``); ``None`` for other laws.
    """

    job: ContourJob
    reference: ContourReference
    output: np.ndarray
    encoder: np.ndarray
    measured: np.ndarray
    command: np.ndarray
    force: np.ndarray
    disturbance: np.ndarray
    axis: AxisErrors
    contour: ContourErrors
    contour_measured: ContourErrors
    dob: np.ndarray | None = None

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return self.reference.dt

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, shape (n,)."""
        return np.arange(self.output.shape[0]) * self.dt

    @property
    def span(self) -> tuple[float, float]:
        """Start and end of the full-speed laps, s."""
        ref = self.reference
        return ref.lap_starts[0] * self.dt, ref.lap_ends[-1] * self.dt


def run_contour(job: ContourJob | None = None) -> ContourRun:
    """Run a contour job on the stage twin and measure it (module notes).

    Raises
    ------
    ValueError
        On a drawing without the closed contour asked for, or bad settings.
    LimitViolation
        When the reference exceeds the stage's limits (seed 004 Table I, travel):
        naming axis, time, value and limit; nothing is run.
    """
    p = play_contour(job)
    job, ref, tr = p.job, p.reference, p.trace
    laps = [ref.lap(i) for i in range(job.motion.laps)]
    return ContourRun(
        job=job,
        reference=ref,
        output=tr.output,
        encoder=tr.encoder,
        measured=tr.measured,
        command=tr.command,
        force=tr.force,
        disturbance=tr.disturbance,
        axis=p.axis_errors(),
        contour=contour_errors(p.path, tr.output, laps),
        contour_measured=contour_errors(p.path, tr.measured, laps),
        dob=(
            dob_estimate(tr.controller, ref.trajectory, tr.measured, tr.command)
            if job.control.law == "preview-dob"
            else None
        ),
    )


def dob_estimate(
    ctrl: PreviewDOB, traj: Any, measured: np.ndarray, command: np.ndarray
) -> np.ndarray:
    """The DOB's estimate of ``F_l`` at each sample of a ``preview-dob`` run, N, shape (n, 2).

    The run's controller is replayed on its recorded measurements
    (`microfab.control.preview_dob.PreviewDOB.replay`); the replayed currents equal the
    recorded ones (checked to 1e-9 A), so the estimate is the one the loop used.
    `run_contour` calls it with the run's own controller and keeps it as ``ContourRun.dob``.

    Parameters
    ----------
    ctrl : PreviewDOB
        The run's controller.
    traj : Trajectory
        The run's reference (position, velocity, acceleration), m.
    measured, command : numpy.ndarray
        The run's measurements, m, and currents, A, shape (n, 2).

    Raises
    ------
    ValueError
        When the replay does not match the recorded currents.
    """
    ref = reference_array(
        np.asarray(traj.position),
        (np.asarray(traj.velocity), np.asarray(traj.acceleration)),
        ctrl.preview,
    )
    log = ctrl.replay(ref, measured)
    gap = float(np.max(np.abs(log.command - command)))
    if gap > 1e-9:
        raise ValueError(f"the replayed currents differ from the run's by {gap:.3g} A")
    return log.disturbance


# ---------------------------------------------------------------------------- speed sweep
@dataclass(frozen=True)
class SpeedPoint:
    """One point of the speed sweep: the job's contour at one speed under one law."""

    law: str
    speed_mm_s: float


def speed_point(job: ContourJob, point: SpeedPoint) -> dict[str, Any]:
    """Run ``job`` at ``point``'s speed and law; the row of the sweep (JSON values).

    Returns
    -------
    dict
        ``law``, ``speed_mm_s``, ``contour_max_nm`` (largest contour error after lap 1),
        ``contour_rms_nm`` (RMS over the laps' RMS), ``axis_peak_um`` (larger axis peak)
        and ``force_peak_n``.
    """
    run = run_contour(
        job.with_(
            motion=dataclasses.replace(job.motion, speed_m_s=point.speed_mm_s * 1e-3),
            control=dataclasses.replace(job.control, law=point.law),
        )
    )
    return {
        "law": point.law,
        "speed_mm_s": point.speed_mm_s,
        "contour_max_nm": run.contour.steady_max() * 1e9,
        "contour_rms_nm": run.contour.rms() * 1e9,
        "axis_peak_um": max(run.axis.peak_m) * 1e6,
        "force_peak_n": float(np.abs(run.force).max()),
    }


class _SpeedTask:
    """Picklable sweep task: `speed_point` of one job."""

    def __init__(self, job: ContourJob) -> None:
        self.job = job

    def __call__(self, point: SpeedPoint) -> dict[str, Any]:
        return speed_point(self.job, point)


def speed_sweep(
    job: ContourJob,
    laws: Sequence[str],
    speeds_mm_s: Sequence[float],
    *,
    results_dir: str | Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    raise_on_failure: bool = True,
) -> SweepResult[SpeedPoint]:
    """`speed_point` of ``job`` at every speed under every law, saved and resumed.

    Parameters
    ----------
    job : ContourJob
        The job (its speed and law are replaced point by point).
    laws : sequence of str
        Controller laws (`microfab.machines.laser_stage.LAWS`), outer loop.
    speeds_mm_s : sequence of float
        Tangential speeds, mm/s, inner loop.
    results_dir : path-like, optional
        Folder of the saved points (`microfab.io.sweep`): a rerun of the same job skips
        the points found there.
    progress : callable, optional
        ``progress(done, total)`` as points finish.
    raise_on_failure : bool
        Raise `microfab.io.sweep.SweepError` if a point failed (default), or return the
        failures in the result.

    Returns
    -------
    SweepResult
        Rows (`speed_point`) of the finished points in point order, and the failures.
    """
    return run_sweep(
        _SpeedTask(job),
        [SpeedPoint(law=law, speed_mm_s=v) for law in laws for v in speeds_mm_s],
        results_dir=results_dir,
        settings={"job": repr(job)},
        progress=None if progress is None else lambda done, total, _p, _l: progress(done, total),
        raise_on_failure=raise_on_failure,
    )
