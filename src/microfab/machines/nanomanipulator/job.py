"""Seed 001 §4.2 on the twin: a circle field, RBF + plug-in RC, gated laser, resumable.

The nanomanipulator-msl job's machinery (`microfab run`, `microfab calibrate
nanomanipulator`): `run_job` runs the whole pattern of
`microfab.trajectory.circle_pattern.pattern_reference` on the nanomanipulator twin
(`microfab.machines.nanomanipulator.twin`), one sample at a time in period-long chunks
(`microfab.machines.nanomanipulator.chunks`):

* **Transfers** between circles (the move and the final hold) run under the PID of
  seed 001 Fig. 8 (`PID.tuned`, crossover ``pid_bandwidth_hz``): the seed does not say
  how its stage moves between circles, and the RBF network fitted to one circle is not
  active far from it (assumed).
* **Each circle** (its pause, spin-up, periods and spin-down) runs under a fresh RBF
  controller (`RBFAdaptive.for_reference` on one period of that circle) inside the plug-in
  RC (`PluginRC`, active over the circle's periods), handed over bumplessly from the PID
  (`microfab.control.rbf_handover`). With ``rc.carry`` the RC memory of one circle seeds
  the next.
* **The laser gate** (`LaserGate`) of each circle watches the measured error
  ``r − y_m`` and exposes one loop after a period under the threshold.

Sensor noise is drawn once for the whole job from ``twin.seed`` (the disturbance phases
use the same seed), so a run is reproducible to the bit.

Interruption: with an ``out`` directory `run_job` saves the chunks run since the last save
and the loop state after them (plant, RBF weights, RC memory, gate state) in one file
``run/chunks/NNNNN.npz``, atomically (`microfab.machines.nanomanipulator.chunks.save_chunks`),
at most once per ``checkpoint_s`` of wall time and always when interrupted, on a worker
thread while the next chunks run (`BackgroundWriter`; an interruption waits for the
files handed over). Running the same config again resumes after the last saved chunk
and gives bit-identical results; a different config refuses to touch the saved run.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.control.rbf import RBFAdaptive, RBFConfig
from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import PluginRC
from microfab.core.limits import check_trajectory
from microfab.core.validate import check_int, check_nonnegative, check_positive
from microfab.io.background import BackgroundWriter
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.machines.nanomanipulator.chunks import (
    Chunk,
    ChunkRunner,
    load_chunks,
    save_chunks,
)
from microfab.measure.circle_tracking import TrackingMetrics, pattern_metrics
from microfab.plants.nanomanipulator import NanomanipulatorPlant
from microfab.process.dose import DoseSettings
from microfab.process.laser import LaserDiode
from microfab.sim.loop import LoopState
from microfab.trajectory.circle_pattern import (
    PatternConfig,
    PatternReference,
    pattern_reference,
)

__all__ = [
    "CircleRun",
    "JobConfig",
    "JobRun",
    "Progress",
    "RCSettings",
    "TwinSettings",
    "job_reference",
    "make_twin",
    "run_job",
]

#: ``progress(task, done, total)``: called per chunk.
Progress = Callable[[str, int, int | None], None]


@dataclass(frozen=True, kw_only=True)
class TwinSettings:
    """Which twin runs the job.

    Parameters
    ----------
    seed : int
        Seed of the disturbance phases and of the sensor noise.
    nonlinear : bool
        The §4.1 terms on (seed 001 eq. 1).
    disturbance : bool
        ``d(t)`` on.
    noise : bool
        Sensor noise on (``noise_rms_mm`` of the twin).
    noise_rms_mm : tuple of float, optional
        Sensor noise per axis, mm, replacing the data file's (e.g. the values
        `microfab calibrate nanomanipulator` fitted).
    disturbance_mm_s2 : tuple of float, optional
        Disturbance bound ``d0`` per axis, mm/s², replacing the data file's.
    noise_time_constant_s : tuple of float, optional
        Sensor noise colour per axis (first-order low-pass time constant, s; 0 white),
        replacing the data file's.
    params_file : str, optional
        Another twin data file (default ``data/nanomanipulator_twin.toml``).
    """

    seed: int = 0
    nonlinear: bool = True
    disturbance: bool = True
    noise: bool = True
    noise_rms_mm: tuple[float, float] | None = None
    disturbance_mm_s2: tuple[float, float] | None = None
    noise_time_constant_s: tuple[float, float] | None = None
    params_file: str | None = None

    def __post_init__(self) -> None:
        check_int("seed", self.seed, 0)
        for name in ("nonlinear", "disturbance", "noise"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        for name, unit in (
            ("noise_rms_mm", "mm"),
            ("disturbance_mm_s2", "mm/s²"),
            ("noise_time_constant_s", "s"),
        ):
            v = getattr(self, name)
            if v is not None:
                if len(v) != 2:
                    raise ValueError(f"{name} must give x and y, got {v!r}")
                for a, x in zip("xy", v, strict=True):
                    check_nonnegative(f"{name} ({a})", x, unit)
                object.__setattr__(self, name, (float(v[0]), float(v[1])))


@dataclass(frozen=True, kw_only=True)
class RCSettings:
    """The plug-in RC of each circle (seed 001 §3.3, Figs. 6-7).

    Parameters
    ----------
    enabled : bool
        RC on (False: the RBF alone, seed Fig. 8-9).
    tau_s : float
        ``Q(s) = 1/(τs + 1)``, s (seed gives the form only; default a 100 Hz cutoff,
        assumed as in `RCConfig`).
    gain : float
        Learning gain in (0, 2] (seed: none; 1 taken).
    lead_samples : int
        Phase lead, samples (assumed 20: the RBF loop lags; as the seed 001 Fig. 10
        comparison).
    carry : bool
        The memory of one circle seeds the next (same pattern phase); default False.
    """

    enabled: bool = True
    tau_s: float = 1.0 / (2.0 * math.pi * 100.0)  # assumed: Q cutoff 100 Hz
    gain: float = 1.0  # seed 001 §3.3 gives no gain; 1 taken
    lead_samples: int = 20  # assumed (as the Fig. 10 comparison)
    carry: bool = False

    def __post_init__(self) -> None:
        check_positive("tau_s (RC low-pass Q time constant)", self.tau_s, "s")
        check_int("lead_samples", self.lead_samples, 0, "samples")
        for name in ("enabled", "carry"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")


@dataclass(frozen=True, kw_only=True)
class JobConfig:
    """A nanomanipulator MSL job (seed 001 §4.2).

    Parameters
    ----------
    pattern : PatternConfig
        Circles, period, pauses.
    rbf : RBFConfig
        RBF settings (centres from each circle, `RBFAdaptive.for_reference`).
    rc : RCSettings
        Plug-in RC.
    gate_threshold_mm : float
        Laser gate threshold on the RMS error norm over a period, mm (default 1 µm, our
        reading of seed 001's "reaches submicrons").
    laser : LaserDiode
        Dead time, warm-up and power (defaults assumed, see there).
    dose : DoseSettings
        Spot and grid of the cured-line maps (seed 001 §2: 3 µm spot).
    twin : TwinSettings
        The twin.
    pid_bandwidth_hz : float
        Crossover of the transfer PID, Hz (assumed 200 Hz, as the seed 001 Fig. 8
        comparison).
    handover_damping : float
        Damping ratio the RBF's hand-over weights inject (`rbf_handover`; assumed 1).
    log_every : int
        Samples between logged ‖Ŵ‖ and ``s`` values (default 500: 20 Hz at 10 kHz;
        each log point costs a return from the compiled loop, ~0.5 ms).
    """

    pattern: PatternConfig = field(default_factory=PatternConfig)
    rbf: RBFConfig = field(default_factory=RBFConfig)
    rc: RCSettings = field(default_factory=RCSettings)
    gate_threshold_mm: float = 1e-3  # our reading of seed 001 "reaches submicrons"
    laser: LaserDiode = field(default_factory=LaserDiode)
    dose: DoseSettings = field(default_factory=DoseSettings)
    twin: TwinSettings = field(default_factory=TwinSettings)
    pid_bandwidth_hz: float = 200.0  # assumed (as the Fig. 8 comparison)
    handover_damping: float = 1.0  # assumed (rbf_handover)
    log_every: int = 500

    def __post_init__(self) -> None:
        check_positive("gate threshold_mm", self.gate_threshold_mm, "mm")
        check_positive("pid_bandwidth_hz", self.pid_bandwidth_hz, "Hz")
        check_positive("handover_damping", self.handover_damping, "")
        check_int("log_every", self.log_every, 1, "samples")
        if self.laser.warmup_s >= self.pattern.period_s:
            raise ValueError(
                f"laser warm-up longer than a period: delay + rise = {self.laser.warmup_s:g} s "
                f">= period {self.pattern.period_s:g} s; shorten the warm-up or lengthen the "
                "period"
            )

    def fingerprint(self) -> str:
        """A hash of every setting (a saved run resumes only under the same one)."""
        return hashlib.sha256(repr(self).encode()).hexdigest()[:16]


def make_twin(settings: TwinSettings) -> NanomanipulatorPlant:
    """The twin of ``settings`` (β checked against β_min by the plant)."""
    over: dict[str, Any] = {}
    if settings.noise_rms_mm is not None:
        over["noise_rms_mm"] = settings.noise_rms_mm
    if settings.disturbance_mm_s2 is not None:
        over["disturbance_mm_s2"] = settings.disturbance_mm_s2
    if settings.noise_time_constant_s is not None:
        over["noise_time_constant_s"] = settings.noise_time_constant_s
    return nanomanipulator.twin(
        settings.params_file,
        seed=settings.seed,
        nonlinear=settings.nonlinear,
        disturbance=settings.disturbance,
        **over,
    )  # built once per distinct settings (machines.nanomanipulator)


def job_reference(config: JobConfig, plant: NanomanipulatorPlant) -> PatternReference:
    """The job's reference at the twin's rate, checked against the stage.

    Raises
    ------
    ValueError
        When the period is not a whole number of samples, or the path goes beyond the
        stage's travel or limits (`microfab.machines.nanomanipulator.limits`).
    """
    ref = pattern_reference(config.pattern, plant.dt)
    check_trajectory(ref.trajectory(), nanomanipulator.limits())
    return ref


@dataclass(frozen=True, kw_only=True, eq=False)
class CircleRun:
    """What happened on one circle.

    Attributes
    ----------
    index : int
        Circle number (0-based).
    start : int
        First sample of the first period.
    gate_opened, gate_closed : int or None
        Sample (job index) of the laser switch-on and of the first sample after the
        exposure; None when the gate never opened.
    gate_period : int or None
        1-based period in which the laser switched on.
    weights : numpy.ndarray
        Final RBF weights, V, shape (2, l).
    rc_memory : RCMemory or None
        Final RC state (None without RC).
    rbf : RBFAdaptive
        The circle's controller (centres, widths, scaling).
    """

    index: int
    start: int
    gate_opened: int | None
    gate_closed: int | None
    gate_period: int | None
    weights: np.ndarray
    rc_memory: RCMemory | None
    rbf: RBFAdaptive


@dataclass(frozen=True, kw_only=True, eq=False)
class JobRun:
    """Signals of a whole job, shape (n, 2) unless noted, mm / V.

    Attributes
    ----------
    config : JobConfig
    reference : PatternReference
    output, measured, command : numpy.ndarray
        True and measured position (mm), command (V).
    laser : numpy.ndarray
        Gate output per sample, bool, shape (n,).
    circles : tuple of CircleRun
    log_index : numpy.ndarray
        Samples at which ‖Ŵ‖ and ``s`` were logged (inside circles), shape (m,).
    weight_norm : numpy.ndarray
        ‖Ŵ‖ per axis at those samples, V, shape (m, 2).
    s : numpy.ndarray
        ``s = λe + ė`` per axis at those samples, mm/s, shape (m, 2).
    noise_rms_mm : numpy.ndarray
        Sensor noise per axis used, mm, shape (2,).
    resumed_from : int
        Chunks loaded from a saved run (0: ran from the start).
    """

    config: JobConfig
    reference: PatternReference
    output: np.ndarray
    measured: np.ndarray
    command: np.ndarray
    laser: np.ndarray
    circles: tuple[CircleRun, ...]
    log_index: np.ndarray
    weight_norm: np.ndarray
    s: np.ndarray
    noise_rms_mm: np.ndarray
    resumed_from: int = 0

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return self.reference.dt

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, shape (n,)."""
        return np.arange(self.reference.n_samples) * self.dt

    @property
    def error(self) -> np.ndarray:
        """Measured tracking error ``r − y_m`` (what the sensor shows), mm."""
        return self.reference.position - self.measured

    @property
    def true_error(self) -> np.ndarray:
        """True tracking error ``r − y``, mm."""
        return self.reference.position - self.output

    def metrics(self) -> TrackingMetrics:
        """Seed 001 §4.2 metrics of the measured signals (`microfab.measure.circle_tracking`)."""
        return pattern_metrics(self.reference, self.measured, self.laser)


def run_job(
    config: JobConfig | None = None,
    out: str | Path | None = None,
    progress: Progress | None = None,
    *,
    checkpoint_s: float = 1.0,
) -> JobRun:
    """Run a nanomanipulator MSL job on the twin (module notes).

    Parameters
    ----------
    config : JobConfig, optional
        The job (defaults: seed 001 §4.2 with the assumed values documented there).
    out : path-like, optional
        Folder for the resumable run (``out/run``); None runs in memory.
    progress : callable, optional
        ``progress(task, done, total)`` per chunk.
    checkpoint_s : float
        With ``out``: save the chunks run at most once per this many wall seconds
        (assumed 1 s: at most a second of work is redone after a hard kill), and always
        at the end and when interrupted by an exception (``KeyboardInterrupt``
        included). 0 saves every chunk.

    Returns
    -------
    JobRun

    Raises
    ------
    ValueError
        On a path beyond the stage's travel or limits, a β below β_min (from the twin),
        or a saved run of another configuration in ``out``.
    """
    cfg = config or JobConfig()
    check_nonnegative("checkpoint_s", checkpoint_s, "s")
    plant = make_twin(cfg.twin)
    run = ChunkRunner(cfg, plant, job_reference(cfg, plant))
    ref = run.ref
    n = ref.n_samples
    Y, YM, U = (np.zeros((n, 2)) for _ in range(3))
    laser = np.zeros(n, dtype=bool)
    log_i: list[int] = []
    log_w: list[np.ndarray] = []
    log_s: list[np.ndarray] = []
    finals: dict[int, np.ndarray] = {}  # circle -> controller state at its end
    fp = cfg.fingerprint()
    run_dir = None if out is None else Path(out) / "run"
    saved = [] if run_dir is None else load_chunks(run_dir, fp, len(run.chunks))
    state: LoopState | None = None
    gate_state: np.ndarray | None = None  # of the circle being run (kept over a transfer)
    for c, ch in enumerate(saved):
        _, a, b = run.chunks[c]
        Y[a:b], YM[a:b], U[a:b], laser[a:b] = ch.output, ch.measured, ch.command, ch.laser
    resumed = len(saved)
    task = "nanomanipulator job"
    total = len(run.chunks)
    if progress:
        progress(task, resumed, total)
    pending: list[Chunk] = []  # chunks run and not yet handed to the writer
    first_pending = resumed  # number of the first of them
    last_save = time.monotonic()

    def flush(writer: BackgroundWriter) -> None:
        nonlocal pending, first_pending, last_save
        assert run_dir is not None
        writer.submit(save_chunks, run_dir, first_pending, pending, fp)
        first_pending += len(pending)
        pending, last_save = [], time.monotonic()

    writer = BackgroundWriter() if run_dir is not None else contextlib.nullcontext()
    with writer:  # checkpoints are written while the next chunks run
        try:
            for c in range(total):
                if c < resumed:
                    ch = saved[c]
                else:
                    ch = run.run_chunk(c, state, gate_state, (Y, YM, U, laser), finals)
                    if isinstance(writer, BackgroundWriter):
                        pending.append(ch)
                        if time.monotonic() - last_save >= checkpoint_s or c == total - 1:
                            flush(writer)
                if ch.loop is not None:
                    state, gate_state = ch.loop, ch.gate
                log_i += ch.log_index.tolist()
                log_w += list(ch.log_w)
                log_s += list(ch.log_s)
                if ch.final_circle is not None:
                    assert ch.final_controller is not None
                    finals[ch.final_circle] = ch.final_controller
                if progress and c >= resumed:
                    progress(task, c + 1, total)
        finally:  # interrupted: save the chunks run (leaving the block waits for it)
            if pending and isinstance(writer, BackgroundWriter):
                flush(writer)
    circles = _circle_runs(run, laser, YM, U, finals)
    return JobRun(
        config=cfg,
        reference=ref,
        output=Y,
        measured=YM,
        command=U,
        laser=laser,
        circles=circles,
        log_index=np.asarray(log_i, dtype=np.int64),
        weight_norm=np.asarray(log_w).reshape(-1, 2),
        s=np.asarray(log_s).reshape(-1, 2),
        noise_rms_mm=run.noise_rms,
        resumed_from=resumed,
    )


def _circle_runs(
    run: ChunkRunner,
    laser: np.ndarray,
    measured: np.ndarray,
    command: np.ndarray,
    finals: dict[int, np.ndarray],
) -> tuple[CircleRun, ...]:
    out = []
    for k, seg in enumerate(run.segs):
        if seg.circle is None:
            continue
        i = seg.circle
        on = np.flatnonzero(laser[seg.start : seg.stop])
        s0 = run.ref.starts[i]
        opened = int(on[0]) + seg.start if on.size else None
        closed = int(on[-1]) + seg.start + 1 if on.size else None
        period = None if opened is None else (opened - s0) // run.N + 1
        ctrl = run.controller(k, measured, command)
        rbf = run.rbf_of(ctrl)
        final = finals.get(i)
        inner = None if final is None else run.inner_state(ctrl, final)
        out.append(
            CircleRun(
                index=i,
                start=s0,
                gate_opened=opened,
                gate_closed=closed,
                gate_period=period,
                weights=rbf.weights(rbf.init() if inner is None else inner),
                rc_memory=(
                    ctrl.memory_of(final)
                    if final is not None and isinstance(ctrl, PluginRC)
                    else None
                ),
                rbf=rbf,
            )
        )
    return tuple(out)
