"""The laser-micromachining stage of seed 004 as a machine: XY twin, focus twin, their loops.

Each data file is parsed once and each twin built once per distinct settings
(`microfab.machines.twins`): the contour runs, the sweep, the margins, the calibration and
the hardware export of one process share them.

The surface every job, study and command uses:

`twin`, `controller`
    The stage twin of `TwinSettings` and the controller of `ControlSettings` for it.
`play`
    Plays a sampled reference through the stage's loop from rest at its first point and
    returns what the stage measures and what moved it (`StageTrace`).
`play_contour`
    A `ContourJob` end to end: the drawing's closed contour, its time-based spline
    (`microfab.trajectory.contour_laps`), refused beyond the stage's limits, then `play`.
`check_job`
    Refuses a contour job before it runs: a drawing without its contour, an unstable loop,
    a reference beyond the stage's limits at the job's speed or at any sweep speed.
`axis_loop`, `axis_margins`, `law_margins`
    Each axis loop broken at the current reference, and its margins.

What a contour run measures is `microfab.machines.laser_stage.contour`'s (`run_contour`);
the focus search on the focus twin (`focus`) is `microfab.machines.laser_stage.focus`'s.

Controller laws (`ControlSettings.law`; the seed gives no gains):

``"preview-dob"``
    Preview control with disturbance observer on each axis (seed 004 eqs. 3-4), without
    the contour correction: Fig. 7's "Response1".
``"contour"``
    The same with the task-space contour compensator on top (eqs. 5-15): "Response2".
``"preview"``
    Preview control without DOB.
``"pd"``
    PD only (``K_a = 0``, no DOB).
``"cross-coupled"``
    Koren's cross-coupled controller on the preview + DOB axes, at the compensator's
    bandwidth.

The controllers are given the twin's nominal model (``M_n``, ``K_fn``); the twin uses the
true values, 10 % off (data file). Encoder noise is drawn from ``TwinSettings.seed``, so a
run is reproducible to the bit. `play` returns the signals, the true positions, motor
force and disturbance force per sample (replayed from the run's commands: the twin is
deterministic given them, `microfab.sim.replay.replay_plant`).

Axis margins: the loop is broken at the plant input (the current reference), ``L = −C_fb
P`` with ``P`` the twin's linear axis (true mass and force constant, amplifier lag, ZOH at
the sample time: `LMWStage.linear_model`) and ``C_fb`` the controller's path from the
measured position to the current (`PreviewDOB.linear_model`, input ``x_fb``: position and
velocity feedback and the disturbance observer together); `microfab.control.margins`
reads margins and sensitivity peak off the frequency response. The contour compensator
adds its normal gains on top (`microfab.control.contour.check_normal_gains`); these are
the axis loops alone.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.control.contour import ContourCompensator, ContourConfig
from microfab.control.cross_coupled import CrossCoupled, CrossCoupledConfig
from microfab.control.margins import AxisMargins, feedback_loop, loop_axis_margins
from microfab.control.preview_dob import PreviewDOB
from microfab.control.preview_dob_model import PreviewDOBConfig
from microfab.core.limits import MachineLimits
from microfab.core.validate import check_int, check_positive
from microfab.geometry.path import Path
from microfab.machines.twins import TwinCache
from microfab.measure.contour import AxisErrors, axis_errors
from microfab.plants import lmw_focus, lmw_stage_params
from microfab.plants.lmw_focus import LMWFocus, LMWFocusParams, lmw_focus_twin
from microfab.plants.lmw_stage import LMWStage, lmw_stage_twin
from microfab.plants.lmw_stage_params import LMWStageParams
from microfab.plants.lti import DiscreteLTI
from microfab.sim.loop import LoopState, simulate
from microfab.sim.replay import replay_plant
from microfab.trajectory.base import Trajectory
from microfab.trajectory.contour_laps import (
    ContourMotion,
    ContourReference,
    check_reference,
    contour_path,
    contour_reference,
)

__all__ = [
    "DATA_FILES",
    "LAWS",
    "PAPER_MASS_KG",
    "ContourJob",
    "ContourPlay",
    "ControlSettings",
    "StageTrace",
    "TwinSettings",
    "axis_loop",
    "axis_margins",
    "check_job",
    "controller",
    "focus",
    "law_margins",
    "limits",
    "play",
    "play_contour",
    "stage",
    "twin",
]

#: The packaged data files the twins are built from (every value with its source).
DATA_FILES = ("lmw_stage.toml", "lmw_focus.toml")

#: Seed 004 Table I: single stage mass 0.6 kg, the ``M_n`` of eq. (2) on both axes of the
#: paper's own simulation (`TwinSettings.paper_model`).
PAPER_MASS_KG = 0.6

#: Controller laws `ControlSettings.law` may name (module notes).
LAWS = ("preview-dob", "contour", "preview", "pd", "cross-coupled")

_STAGES: TwinCache[LMWStageParams, LMWStage] = TwinCache(
    lmw_stage_params.load_params, lambda cfg, **s: lmw_stage_twin(params=cfg, **s), DATA_FILES[0]
)
_FOCUS: TwinCache[LMWFocusParams, LMWFocus] = TwinCache(
    lmw_focus.load_params, lambda cfg, **s: lmw_focus_twin(params=cfg, **s), DATA_FILES[1]
)


def stage(
    path: str | os.PathLike[str] | None = None, *, ideal: bool = False, **overrides: Any
) -> LMWStage:
    """`lmw_stage_twin` (same arguments), parsed and built once per distinct settings."""
    return _STAGES(path, ideal=ideal, **overrides)


def focus(path: str | os.PathLike[str] | None = None, **overrides: Any) -> LMWFocus:
    """`lmw_focus_twin` (same arguments), parsed and built once per distinct settings."""
    return _FOCUS(path, **overrides)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 004 Table I)."""
    return MachineLimits.seed004_stage()


# ---------------------------------------------------------------------------- settings
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
    friction : bool
        The LuGre friction on (the data file's ``[switches] friction``); off leaves the
        other nonlinear parts as ``nonlinear`` says (the friction-free runs of the Fig. 7
        study). Ignored when ``nonlinear`` is off.
    disturbance_scale : float or None
        Scale of friction + cogging + cable (default: the data file's).
    mass_error : float
        Relative error of the controller's nominal mass against the twin's own nominal
        (0: the data file's nominal; 0.3: the controller believes 30 % more), for the
        robustness check.
    params_file : str or None
        Another twin data file.
    paper_model : bool
        The model seed 004 states for its own simulation (§IV.D) instead of the twin:
        eq. (2) per axis with ``M = M_n`` = Table I's single stage mass (`PAPER_MASS_KG`)
        on both axes and ``K_f = K_fn`` (the data file's nominal), ``F_l = 0`` (the seed
        names no disturbance of its simulation and gives no value for one), no friction,
        cogging, cable or saturation. What stays of the twin: the data file's current
        amplifier lag (assumed; eq. (2) says "current controlled amplifiers", and the
        kernel needs a lag below Nyquist), its sample time, and with ``nonlinear`` on
        only Table I's 10 nm encoder resolution. ``friction`` and ``disturbance_scale``
        are ignored; ``mass_error`` still sets the controller's nominal apart.
    """

    seed: int = 0
    noise: bool = True
    nonlinear: bool = True
    friction: bool = True
    disturbance_scale: float | None = None
    mass_error: float = 0.0
    params_file: str | None = None
    paper_model: bool = False

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
    friction_ff : bool
        Friction feedforward on the preview + DOB axes (not in the seed; default off).
        Assumed: the controller knows the twin's LuGre friction law exactly, as a friction
        identification on the stage would give it (the data file's values, switch and
        disturbance scale), and runs it on the reference (`controller`); cogging and cable
        stay the DOB's. An upper bound of what a model-based friction feedforward does.
    normal_only : bool
        For the ``contour`` law: the normal row of eqs. 13/15 alone, without the
        tangential row and the ``J̇`` term (`microfab.control.contour.ContourConfig`); the
        law before issue 33, kept for the Fig. 7 study's comparison. Default off.
    """

    law: str = "contour"
    bandwidth_hz: float = 50.0
    dob_bandwidth_hz: float = 500.0
    k_a: float = 1.0
    contour_bandwidth_hz: float = 100.0
    friction_ff: bool = False
    normal_only: bool = False

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


def twin(settings: TwinSettings | None = None) -> LMWStage:
    """The stage twin of ``settings`` (`stage`: built once per distinct settings)."""
    tw = settings or TwinSettings()
    if tw.paper_model:
        k_fn = stage(tw.params_file, ideal=True).config.nominal_force_constant_n_per_a
        return stage(
            tw.params_file,
            ideal=True,
            quantisation=tw.nonlinear,
            mass_kg=(PAPER_MASS_KG, PAPER_MASS_KG),
            nominal_mass_kg=(PAPER_MASS_KG, PAPER_MASS_KG),
            force_constant_n_per_a=tuple(k_fn),
        )
    over: dict[str, Any] = {}
    if tw.disturbance_scale is not None:
        over["disturbance_scale"] = tw.disturbance_scale
    if tw.nonlinear and not tw.friction:
        over["friction"] = False
    return stage(tw.params_file, ideal=not tw.nonlinear, **over)


def controller(cs: ControlSettings, plant: LMWStage, mass_error: float = 0.0) -> Any:
    """The controller of ``cs`` for ``plant``'s nominal model (mass off by ``mass_error``).

    Returns
    -------
    PreviewDOB, ContourCompensator or CrossCoupled
        A fresh controller (module notes: laws).
    """
    nom = plant.nominal()
    inner = PreviewDOBConfig(
        mass_kg=tuple(m * (1.0 + mass_error) for m in nom.mass_kg),
        force_constant_n_per_a=tuple(nom.force_constant_n_per_a),
        dt=plant.dt,
        bandwidth_hz=cs.bandwidth_hz,
        dob_bandwidth_hz=cs.dob_bandwidth_hz,
        k_a=0.0 if cs.law == "pd" else cs.k_a,
        dob=cs.law not in ("preview", "pd"),
        friction_ff=(
            tuple(
                dataclasses.replace(law, cogging=False, cable=False)
                for law in plant.config.friction_laws
            )
            if cs.friction_ff
            else ()
        ),
        friction_ff_scale=plant.config.disturbance_scale,
    )
    if cs.law == "contour":
        return ContourCompensator(
            ContourConfig(
                inner=inner,
                bandwidth_hz=cs.contour_bandwidth_hz,
                tangential=not cs.normal_only,
                rotation=not cs.normal_only,
            )
        )
    if cs.law == "cross-coupled":
        return CrossCoupled(CrossCoupledConfig(inner=inner, bandwidth_hz=cs.contour_bandwidth_hz))
    return PreviewDOB(inner)


# ---------------------------------------------------------------------------- play
@dataclass(frozen=True, kw_only=True, eq=False)
class StageTrace:
    """What the stage did over a played reference (all shape (n, 2), x and y).

    Attributes
    ----------
    output : numpy.ndarray
        True positions, m (replayed from the twin's state).
    encoder : numpy.ndarray
        Encoder counts as positions (10 nm steps), m.
    measured : numpy.ndarray
        What the controller saw: encoder plus interpolation noise, m.
    command : numpy.ndarray
        Current references, A.
    force : numpy.ndarray
        Motor force ``K_f i`` after each sample, N.
    disturbance : numpy.ndarray
        True ``F_l`` over each sample, N.
    controller : object
        The controller that ran (for replays of its recorded measurements).
    dt : float
        Sample time, s.
    """

    output: np.ndarray
    encoder: np.ndarray
    measured: np.ndarray
    command: np.ndarray
    force: np.ndarray
    disturbance: np.ndarray
    controller: Any
    dt: float


def play(
    reference: Trajectory,
    control: ControlSettings | None = None,
    settings: TwinSettings | None = None,
) -> StageTrace:
    """Play a sampled reference through the stage's loop from rest at its first point.

    Parameters
    ----------
    reference : Trajectory
        Position (m), velocity (m/s) and acceleration (m/s²), shape (n, 2), at the twin's
        sample time (the preview controllers read the derivatives).
    control : ControlSettings, optional
        The controller (default `ControlSettings`).
    settings : TwinSettings, optional
        The twin (default `TwinSettings`).

    Returns
    -------
    StageTrace
    """
    tw = settings or TwinSettings()
    plant = twin(tw)
    pos = np.asarray(reference.position)
    n = pos.shape[0]
    noise = plant.noise(n, tw.seed) if tw.noise else np.zeros((n, 2))
    ctrl = controller(control or ControlSettings(), plant, tw.mass_error)
    s0 = plant.state_at((float(pos[0, 0]), float(pos[0, 1])))
    start = LoopState(plant=s0, controller=ctrl.init(), observer=np.zeros(0), command=np.zeros(2))
    der = (reference.velocity, reference.acceleration)
    res = simulate(plant, ctrl, pos, noise, start, derivatives=der)  # type: ignore[arg-type]
    states = replay_plant(plant, res.command, s0)  # the twin's state after each sample
    # the true position at sample k is the state after sample k - 1 (the simulator's
    # output is the quantised encoder)
    true = plant.linear_state(np.vstack([s0[None, :], states[:-1]]))[:, [0, 3]]
    return StageTrace(
        output=true,
        encoder=res.output,
        measured=res.measured,
        command=res.command,
        force=plant.force(states),
        disturbance=plant.disturbance(states),
        controller=ctrl,
        dt=plant.dt,
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class ContourPlay:
    """A `ContourJob` played: its contour, its reference and what the stage did.

    Attributes
    ----------
    job : ContourJob
    path : Path
        The exact contour, m.
    reference : ContourReference
        The reference (spline, samples, laps).
    trace : StageTrace
    """

    job: ContourJob
    path: Path
    reference: ContourReference
    trace: StageTrace

    @property
    def full_laps(self) -> slice:
        """Samples of the full-speed laps, first to last."""
        ref = self.reference
        return ref.laps

    def axis_errors(self) -> AxisErrors:
        """Axis errors (reference − measured) over the full-speed laps (seed 004 Fig. 3)."""
        full = self.full_laps
        return axis_errors(
            np.asarray(self.reference.trajectory.position)[full], self.trace.measured[full]
        )


def play_contour(job: ContourJob | None = None) -> ContourPlay:
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
    plant = twin(job.twin)
    if abs(plant.dt - 1.0 / job.motion.sample_rate_hz) > 1e-12 * plant.dt:
        raise ValueError(
            f"the motion's sample rate {job.motion.sample_rate_hz:g} Hz differs from the "
            f"twin's {1.0 / plant.dt:g} Hz; use {1.0 / plant.dt:g}"
        )
    masses = tuple(plant.config.mass_kg)
    ref = contour_reference(path, job.motion, masses)  # type: ignore[arg-type]
    check_reference(ref, limits(), masses)  # type: ignore[arg-type]
    return ContourPlay(
        job=job, path=path, reference=ref, trace=play(ref.trajectory, job.control, job.twin)
    )


def check_job(job: ContourJob, speeds_m_s: Sequence[float] = ()) -> None:
    """Refuse a contour job before anything runs (what a job file is checked with).

    Parameters
    ----------
    job : ContourJob
        The job.
    speeds_m_s : sequence of float
        Further tangential speeds its reference must also keep within the limits, m/s (a
        speed sweep's).

    Raises
    ------
    ValueError
        On a drawing without the closed contour asked for, or a law whose loop is unstable
        on the twin.
    LimitViolation
        When the reference at the job's speed or at one of ``speeds_m_s`` exceeds the
        stage's limits (seed 004 Table I).
    """
    path = contour_path(job.drawing, job.contour)  # refuses a drawing without it
    plant = twin(job.twin)
    controller(job.control, plant)  # refuses an unstable loop
    masses = tuple(plant.config.mass_kg)
    for v in (job.motion.speed_m_s, *speeds_m_s):
        motion = dataclasses.replace(job.motion, speed_m_s=v)
        ref = contour_reference(path, motion, masses)  # type: ignore[arg-type]
        check_reference(ref, limits(), masses)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------- margins
def axis_loop(plant: LMWStage, ctrl: PreviewDOB, axis: int) -> DiscreteLTI:
    """``L = −C_fb P`` of axis ``axis`` (0: x, 1: y), broken at the current reference."""
    return feedback_loop(
        plant.linear_model().channel(axis, axis), ctrl.linear_model(axis).channel(0, 3)
    )


def axis_margins(
    plant: LMWStage, ctrl: PreviewDOB, n_points: int = 20_000
) -> tuple[AxisMargins, ...]:
    """`AxisMargins` of both axis loops (module notes), x then y."""
    return tuple(
        loop_axis_margins(name, axis_loop(plant, ctrl, a), n_points=n_points)
        for a, name in enumerate("xy")
    )


def law_margins(
    control: ControlSettings, settings: TwinSettings | None = None
) -> tuple[AxisMargins, ...]:
    """`axis_margins` of the axis controllers of ``control``'s law on the twin of ``settings``.

    The contour compensator and the cross-coupled controller act on top of preview + DOB
    axes: for those laws the margins are the preview + DOB axes'.
    """
    plant = twin(settings)
    law = control.law if control.law in ("preview-dob", "preview", "pd") else "preview-dob"
    return axis_margins(plant, controller(dataclasses.replace(control, law=law), plant))
