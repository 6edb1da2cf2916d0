"""Seed 004 contour runs on the stage twin: drawing → spline → controller → twin → errors.

`run_contour` takes a closed contour of a drawing (`microfab.geometry.load.load_drawing`),
builds its time-based spline reference (`reference.contour_reference`), refuses it if the
stage cannot follow it (Table I: speed, acceleration, peak and RMS force; travel), and
runs it on the XY stage twin (`microfab.plants.lmw_stage`) under one of the controllers
of seed 004 or a baseline (`ControlSettings.law`):

``"preview-dob"``
    Preview control with disturbance observer on each axis (eqs. 3-4), without the
    contour correction: Fig. 7's "Response1".
``"contour"``
    The same with the task-space contour compensator on top (eqs. 5-15): "Response2".
``"preview"``
    Preview control without DOB.
``"pd"``
    PD only (``K_a = 0``, no DOB).
``"cross-coupled"``
    Koren's cross-coupled controller on the preview + DOB axes, at the compensator's
    bandwidth.

The controllers are given the twin's nominal model (``M_n``, ``K_fn``); the twin uses
the true values, 10 % off (data file). Encoder noise is drawn from ``twin.seed``, so a
run is reproducible to the bit. The run returns the signals, the true positions, motor
force and disturbance force per sample (replayed from the run's commands: the twin is
deterministic given them, `microfab.sim.replay.replay_plant`), and the errors of
`metrics`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.control.contour import ContourCompensator, ContourConfig
from microfab.control.cross_coupled import CrossCoupled, CrossCoupledConfig
from microfab.control.preview_dob import PreviewDOB
from microfab.control.preview_dob_model import PreviewDOBConfig
from microfab.core.limits import MachineLimits
from microfab.core.validate import check_int, check_positive
from microfab.experiments.seed004_laser.metrics import (
    AxisErrors,
    ContourErrors,
    axis_errors,
    contour_errors,
)
from microfab.experiments.seed004_laser.reference import (
    ContourMotion,
    ContourReference,
    check_reference,
    contour_reference,
)
from microfab.geometry.path import Path
from microfab.machines import laser_stage
from microfab.plants.lmw_stage import LMWStage
from microfab.sim.loop import LoopState, reference_array, simulate
from microfab.sim.replay import replay_plant

__all__ = [
    "LAWS",
    "ContourJob",
    "ContourRun",
    "ControlSettings",
    "TwinSettings",
    "contour_path",
    "dob_estimate",
    "make_controller",
    "make_stage",
    "run_contour",
]

#: Controller laws `ControlSettings.law` may name (module notes).
LAWS = ("preview-dob", "contour", "preview", "pd", "cross-coupled")


@dataclass(frozen=True, kw_only=True)
class TwinSettings:
    """Which stage twin runs (defaults: the data file's, noise and nonlinear parts on).

    Parameters
    ----------
    seed : int
        Seed of the encoder noise.
    noise : bool
        Encoder interpolation noise on (``noise_rms_m`` of the data file).
    nonlinear : bool
        Friction, cogging, cable, saturation and quantisation on (off: the linear twin).
    disturbance_scale : float or None
        Scale of friction + cogging + cable (default: the data file's).
    mass_error : float
        Relative error of the controller's nominal mass against the twin's own nominal
        (0: the data file's nominal; 0.3: the controller believes 30 % more), for the
        robustness check.
    params_file : str or None
        Another twin data file.
    """

    seed: int = 0
    noise: bool = True
    nonlinear: bool = True
    disturbance_scale: float | None = None
    mass_error: float = 0.0
    params_file: str | None = None

    def __post_init__(self) -> None:
        check_int("seed", self.seed, 0)
        if self.disturbance_scale is not None:
            check_positive("disturbance_scale", self.disturbance_scale)
        if not -0.9 <= self.mass_error <= 10.0:
            raise ValueError(
                f"mass_error must lie in [-0.9, 10] (a relative error), got {self.mass_error!r}"
            )


@dataclass(frozen=True, kw_only=True)
class ControlSettings:
    """The controller law and its bandwidths (all assumed; the seed gives no gains).

    Parameters
    ----------
    law : str
        One of `LAWS`.
    bandwidth_hz : float
        Axis position loop ``ω_c / 2π`` (`PreviewDOBConfig`, default 50 Hz).
    dob_bandwidth_hz : float
        DOB filter ``ω_q / 2π`` (default 500 Hz).
    k_a : float
        Acceleration feedforward gain of eq. 3 (default 1).
    contour_bandwidth_hz : float
        Contour compensator (or cross-coupled) ``ω_cc / 2π`` (default 100 Hz).
    """

    law: str = "contour"
    bandwidth_hz: float = 50.0
    dob_bandwidth_hz: float = 500.0
    k_a: float = 1.0
    contour_bandwidth_hz: float = 100.0

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise ValueError(f"law must be one of {', '.join(LAWS)}; got {self.law!r}")
        check_positive("bandwidth_hz", self.bandwidth_hz, "Hz")
        check_positive("dob_bandwidth_hz", self.dob_bandwidth_hz, "Hz")
        check_positive("contour_bandwidth_hz", self.contour_bandwidth_hz, "Hz")


@dataclass(frozen=True, kw_only=True)
class ContourJob:
    """One contour run: the drawing, how it is run, the controller and the twin.

    Parameters
    ----------
    drawing : str
        A drawing source for `microfab.geometry.load.load_drawing` (default the seed's
        Fig. 3 circle, ``circle:radius=30e-6``), in m.
    contour : int
        Which closed contour of the drawing (in the drawing's order).
    motion : ContourMotion
        Speed, laps, ramps, knots, sample rate.
    control : ControlSettings
        The controller.
    twin : TwinSettings
        The stage twin.
    """

    drawing: str = "circle:radius=30e-6"
    contour: int = 0
    motion: ContourMotion = field(default_factory=ContourMotion)
    control: ControlSettings = field(default_factory=ControlSettings)
    twin: TwinSettings = field(default_factory=TwinSettings)

    def with_(self, **changes: Any) -> ContourJob:
        """A copy with fields replaced (``motion=``, ``control=``, ``twin=``, ...)."""
        return dataclasses.replace(self, **changes)


def contour_path(drawing: str, contour: int = 0) -> Path:
    """Closed contour number ``contour`` of a drawing source (m).

    Raises
    ------
    ValueError
        When the drawing has no closed contour, or fewer than ``contour + 1``.
    """
    from microfab.geometry.load import load_drawing

    closed = load_drawing(drawing).closed
    if not closed:
        raise ValueError(f"the drawing {drawing!r} has no closed contour to run")
    check_int("contour", contour, 0)
    if contour >= len(closed):
        raise ValueError(
            f"the drawing {drawing!r} has {len(closed)} closed contour(s); contour = "
            f"{contour} does not exist (count from 0)"
        )
    return closed[contour]


def make_stage(tw: TwinSettings) -> LMWStage:
    """The stage twin of ``tw``."""
    over: dict[str, Any] = {}
    if tw.disturbance_scale is not None:
        over["disturbance_scale"] = tw.disturbance_scale
    return laser_stage.stage(tw.params_file, ideal=not tw.nonlinear, **over)


def make_controller(cs: ControlSettings, stage: LMWStage, mass_error: float = 0.0) -> Any:
    """The controller of ``cs`` for ``stage``'s nominal model (mass off by ``mass_error``)."""
    nom = stage.nominal()
    inner = PreviewDOBConfig(
        mass_kg=tuple(m * (1.0 + mass_error) for m in nom.mass_kg),
        force_constant_n_per_a=tuple(nom.force_constant_n_per_a),
        dt=stage.dt,
        bandwidth_hz=cs.bandwidth_hz,
        dob_bandwidth_hz=cs.dob_bandwidth_hz,
        k_a=0.0 if cs.law == "pd" else cs.k_a,
        dob=cs.law not in ("preview", "pd"),
    )
    if cs.law == "contour":
        return ContourCompensator(ContourConfig(inner=inner, bandwidth_hz=cs.contour_bandwidth_hz))
    if cs.law == "cross-coupled":
        return CrossCoupled(CrossCoupledConfig(inner=inner, bandwidth_hz=cs.contour_bandwidth_hz))
    return PreviewDOB(inner)


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


def run_contour(job: ContourJob | None = None) -> ContourRun:
    """Run a contour job on the stage twin (module notes).

    Raises
    ------
    ValueError
        On a drawing without the closed contour asked for, or bad settings.
    LimitViolation
        When the reference exceeds the stage's limits (seed 004 Table I, travel):
        naming axis, time, value and limit; nothing is run.
    """
    job = job or ContourJob()
    path = contour_path(job.drawing, job.contour)
    stage = make_stage(job.twin)
    if abs(stage.dt - 1.0 / job.motion.sample_rate_hz) > 1e-12 * stage.dt:
        raise ValueError(
            f"the motion's sample rate {job.motion.sample_rate_hz:g} Hz differs from the "
            f"twin's {1.0 / stage.dt:g} Hz; use {1.0 / stage.dt:g}"
        )
    ref = contour_reference(path, job.motion)
    check_reference(ref, MachineLimits.seed004_stage(), tuple(stage.config.mass_kg))  # type: ignore[arg-type]
    traj = ref.trajectory
    pos = np.asarray(traj.position)
    n = pos.shape[0]
    noise = stage.noise(n, job.twin.seed) if job.twin.noise else np.zeros((n, 2))
    ctrl = make_controller(job.control, stage, job.twin.mass_error)
    s0 = stage.state_at((float(pos[0, 0]), float(pos[0, 1])))
    start = LoopState(plant=s0, controller=ctrl.init(), observer=np.zeros(0), command=np.zeros(2))
    res = simulate(stage, ctrl, pos, noise, start, derivatives=(traj.velocity, traj.acceleration))
    states = replay_plant(stage, res.command, s0)  # the twin's state after each sample
    force = stage.force(states)
    dist = stage.disturbance(states)
    # the true position at sample k is the state after sample k - 1 (the simulator's
    # output is the quantised encoder)
    true = stage.linear_state(np.vstack([s0[None, :], states[:-1]]))[:, [0, 3]]
    laps = [ref.lap(i) for i in range(job.motion.laps)]
    full = slice(int(ref.lap_starts[0]), int(ref.lap_starts[-1]) + ref.lap_samples)
    return ContourRun(
        job=job,
        reference=ref,
        output=true,
        encoder=res.output,
        measured=res.measured,
        command=res.command,
        force=force,
        disturbance=dist,
        axis=axis_errors(pos[full], res.measured[full]),
        contour=contour_errors(path, true, laps),
        contour_measured=contour_errors(path, res.measured, laps),
        dob=(
            dob_estimate(ctrl, traj, res.measured, res.command)
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
