"""The chunks of a nanomanipulator job: its segments, one chunk's run, the checkpoint files.

A job (`microfab.machines.nanomanipulator.job.run_job`) runs its circle field in
period-long chunks:

* `job_segments` cuts the pattern's samples into transfers (under the PID of seed 001
  Fig. 8) and circles (a fresh RBF inside the plug-in RC), and `chunk_spans` cuts those
  into chunks no longer than a period.
* `ChunkRunner` builds each segment's controller once (the RBF handed over bumplessly
  from the PID, `microfab.control.rbf_handover`; with ``rc.carry`` the RC memory of the
  last circle), runs one chunk through the twin's loop (`microfab.sim.loop.LoopStepper`,
  compiled), logs ‖Ŵ‖ and ``s`` every ``log_every`` samples and runs the circle's laser
  gate (`microfab.control.gate.run_gate`) on the measured error.
* A checkpoint file ``run/chunks/NNNNN.npz`` (``NNNNN`` its first chunk, `save_chunks`)
  holds one or more consecutive chunks: their signals and log points, concatenated, the
  circles they end (with those circles' final controller states), and the loop state
  after its last chunk (plant, controller with its RBF weights and RC memory, last
  command, gate state). Each file is a run-store state file (`microfab.io.checkpoint`):
  written atomically, complete or absent, stamped with its kind, format version and the
  job's fingerprint, and refused on one line when cut short, damaged or of another job.
  `load_chunks` reads the unbroken sequence from chunk 0; how many chunks a file holds is
  the writer's choice (`run_job` saves at most once per ``checkpoint_s`` of wall time,
  and always when interrupted).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from microfab.control.gate import GateConfig, run_gate
from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_handover import feedback_gain, handover
from microfab.control.repetitive import PluginRC, RCConfig
from microfab.io.checkpoint import read_state, save_state
from microfab.plants.nanomanipulator import NanomanipulatorPlant
from microfab.sim.loop import LoopState, LoopStepper
from microfab.trajectory.circle_pattern import PatternConfig, PatternReference

if TYPE_CHECKING:
    from microfab.machines.nanomanipulator.job import JobConfig

__all__ = [
    "FORMAT_VERSION",
    "Chunk",
    "ChunkRunner",
    "Segment",
    "chunk_path",
    "chunk_spans",
    "job_segments",
    "load_chunks",
    "save_chunks",
]

_HANDOVER_MEAN_S = 5e-3  # assumed: time averaged for the hand-over point (0.25 of the 50 Hz mode)


#: Format of the checkpoint files (4: a run-store state file; 3: several chunks per file;
#: 2 had one chunk per file; 1 kept a separate ``run/state.npz``).
FORMAT_VERSION = 4
#: What `microfab.io.checkpoint` calls these files.
KIND = "nanomanipulator job checkpoint"
_FIX = "rerun with --fresh, or use another output folder"
_OLD_STATE = "state.npz"  # format 1


@dataclass(frozen=True)
class Segment:
    """Samples ``[start, stop)`` under one controller: ``circle`` is None for a transfer."""

    start: int
    stop: int
    circle: int | None


def job_segments(ref: PatternReference, config: PatternConfig) -> tuple[Segment, ...]:
    """Transfer and circle segments of a pattern, in order, covering every sample."""
    n_move = max(round(config.move_s / ref.dt), 1)
    n_pause = max(round(config.pause_s / ref.dt), 1)
    n_ramp = max(round(config.ramp_s / ref.dt), 1)
    n_ring = 2 * n_ramp + ref.period_samples * ref.periods
    segs: list[Segment] = []
    pos = 0
    for i in range(len(ref.starts)):
        segs.append(Segment(pos, pos + n_move, None))
        pos += n_move
        segs.append(Segment(pos, pos + n_pause + n_ring, i))
        pos += n_pause + n_ring
    segs.append(Segment(pos, ref.n_samples, None))
    return tuple(segs)


@dataclass(frozen=True, kw_only=True, eq=False)
class Chunk:
    """One period-long chunk of a job: its signals and the loop state after it.

    Attributes
    ----------
    output, measured, command : numpy.ndarray
        True position (mm), measured position (mm), command (V) over the chunk, (n, 2).
    laser : numpy.ndarray
        Laser on per sample, bool, shape (n,).
    log_index : numpy.ndarray
        Samples (job index) of the log points, int, shape (m,).
    log_w, log_s : numpy.ndarray
        ‖Ŵ‖ (V) and ``s`` (mm/s) per axis at the log points, shape (m, 2).
    loop : LoopState or None
        Plant, controller and last command after the chunk (no observer). None for a
        chunk read back from inside a checkpoint file (only the last one's is saved).
    gate : numpy.ndarray or None
        Laser gate state after the chunk (None outside a circle, or with ``loop`` None).
    final_circle : int or None
        The circle this chunk ends, if it ends one.
    final_controller : numpy.ndarray or None
        That circle's final controller state (the RC memory a later circle may carry).
    """

    output: np.ndarray
    measured: np.ndarray
    command: np.ndarray
    laser: np.ndarray
    log_index: np.ndarray
    log_w: np.ndarray
    log_s: np.ndarray
    loop: LoopState | None
    gate: np.ndarray | None = None
    final_circle: int | None = None
    final_controller: np.ndarray | None = None


def chunk_spans(segs: tuple[Segment, ...], n_period: int) -> list[tuple[int, int, int]]:
    """``(segment index, start, stop)`` of every chunk: segments cut into periods."""
    out = []
    for k, sg in enumerate(segs):
        a = sg.start
        while a < sg.stop:
            b = min(a + n_period, sg.stop)
            out.append((k, a, b))
            a = b
    return out


class ChunkRunner:
    """Builds the controllers of a job and runs its chunks.

    Parameters
    ----------
    config : JobConfig
        The job.
    plant : NanomanipulatorPlant
        Its twin (`microfab.machines.nanomanipulator.job.make_twin` of ``config.twin``).
    reference : PatternReference
        The pattern at the twin's rate (`microfab.machines.nanomanipulator.job.job_reference`).
    """

    def __init__(
        self, config: JobConfig, plant: NanomanipulatorPlant, reference: PatternReference
    ) -> None:
        self.config = config
        self.plant = plant
        dt = self.plant.dt
        self.ref = reference
        self.segs = job_segments(self.ref, config.pattern)
        self.N = self.ref.period_samples
        self.chunks = chunk_spans(self.segs, self.N)
        rms = self.plant.noise_level.array() if config.twin.noise else np.zeros(2)
        self.noise_rms = np.asarray(rms, dtype=float)
        n = self.ref.position.shape[0]  # the twin's seeded noise, coloured as its file says
        self.noise = plant.noise(n, config.twin.seed) if config.twin.noise else np.zeros((n, 2))
        self.pid = PID.tuned(
            self.plant.continuous_models(), bandwidth_hz=config.pid_bandwidth_hz, dt=dt
        )
        p = self.plant.config
        self.ks = [
            feedback_gain(
                p.numerator_mm_per_v_s2[a], p.stiffness_per_s2[a], config.handover_damping
            )
            for a in range(2)
        ]
        self._ctrl: dict[int, Any] = {}

    # -- controllers
    def circle_rbf(self, i: int) -> RBFAdaptive:
        """A fresh RBF controller for circle ``i``, centred on one period of it."""
        s0, n = self.ref.starts[i], self.N
        one = slice(s0, s0 + n)
        r = self.ref
        return RBFAdaptive.for_reference(
            r.position[one], r.velocity[one], r.acceleration[one], r.dt, self.config.rbf
        )

    def rc_config(self, seg: Segment) -> RCConfig:
        """The plug-in RC of circle segment ``seg``, active over the circle's periods."""
        i = seg.circle
        assert i is not None
        rc = self.config.rc
        return RCConfig(
            period_s=self.config.pattern.period_s,
            dt=self.ref.dt,
            tau_s=rc.tau_s,
            gain=rc.gain,
            lead_samples=rc.lead_samples,
            carry=rc.carry,  # keep a memory loaded from the last circle at the window start
            windows=((self.ref.starts[i] - seg.start, self.ref.periods),),
        )

    def controller(self, k: int, measured: np.ndarray, command: np.ndarray) -> Any:
        """Controller of segment ``k`` (built once; hand-over from the signals before it)."""
        if k in self._ctrl:
            return self._ctrl[k]
        seg = self.segs[k]
        if seg.circle is None:
            ctrl: Any = self.pid
        else:
            rbf = self.circle_rbf(seg.circle)
            a = seg.start
            if a > 0:
                lo = max(a - max(round(_HANDOVER_MEAN_S / self.ref.dt), 1), 0)
                r = self.ref
                rbf = handover(
                    rbf,
                    measured=measured[lo:a].mean(axis=0),
                    reference=np.stack([r.position[a], r.velocity[a], r.acceleration[a]]),
                    command=command[lo:a].mean(axis=0),
                    gains=self.ks,
                )
            ctrl = PluginRC(rbf, self.rc_config(seg)) if self.config.rc.enabled else rbf
        self._ctrl[k] = ctrl
        return ctrl

    def gate_config(self, seg: Segment) -> GateConfig:
        """The laser gate of circle segment ``seg``: one window per period."""
        i = seg.circle
        assert i is not None
        s0 = self.ref.starts[i] - seg.start
        return GateConfig(
            period_samples=self.N,
            threshold_mm=self.config.gate_threshold_mm,
            starts=tuple(s0 + j * self.N for j in range(self.ref.periods)),
        )

    def carried_state(
        self,
        ctrl: PluginRC,
        k: int,
        previous: np.ndarray,
        measured: np.ndarray,
        command: np.ndarray,
    ) -> np.ndarray:
        """Start state of circle segment ``k`` whose RC memory is the last circle's final one.

        ``previous`` is the final controller state of the circle before; the memory keeps
        its phase (every circle starts at the same angle), the RBF starts afresh.
        """
        j = max(i for i in range(k) if self.segs[i].circle is not None)
        last = self.controller(j, measured, command)
        memory = last.memory_of(previous)
        return ctrl.state_from(
            dataclasses.replace(memory, config=ctrl.config, samples=0, inner=ctrl.inner.init())
        )

    def rbf_of(self, ctrl: Any) -> RBFAdaptive:
        """The RBF controller of a circle's controller (inside the RC, if any)."""
        return ctrl.inner if isinstance(ctrl, PluginRC) else ctrl

    def inner_state(self, ctrl: Any, state: np.ndarray) -> np.ndarray:
        """The RBF part of a circle controller's ``state``."""
        if isinstance(ctrl, PluginRC):
            return ctrl.inner_state(state)
        return state

    def run_chunk(
        self,
        c: int,
        state: LoopState | None,
        gate_state: np.ndarray | None,
        signals: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
        finals: dict[int, np.ndarray],
    ) -> Chunk:
        """Simulate chunk ``c`` from ``state``; fill ``signals`` ``(Y, YM, U, laser)``.

        ``finals`` maps each finished circle to its final controller state (for the RC
        memory a circle may carry). The returned `Chunk` holds views of ``signals`` and
        the loop state after the chunk.
        """
        Y, YM, U, laser = signals
        ref, cfg = self.ref, self.config
        k, a, b = self.chunks[c]
        seg = self.segs[k]
        ctrl = self.controller(k, YM, U)
        if state is None or a == seg.start:  # a new controller takes over the plant
            cst = ctrl.init()
            if seg.circle is not None:
                gate_state = None
                if cfg.rc.carry and seg.circle > 0 and isinstance(ctrl, PluginRC):
                    cst = self.carried_state(ctrl, k, finals[seg.circle - 1], YM, U)
            plant0, cmd0 = (
                (self.plant.init(), np.zeros(2)) if state is None else (state.plant, state.command)
            )
            state = LoopState(plant=plant0, controller=cst, observer=np.zeros(0), command=cmd0)
        stepper = LoopStepper(
            self.plant,
            ctrl,
            ref.position[a:b],
            self.noise[a:b],
            state,
            derivatives=(ref.velocity[a:b], ref.acceleration[a:b]),
        )
        li, lw, ls = [], [], []
        if seg.circle is None:
            stepper.advance()
        else:  # stop every log_every samples to log ‖Ŵ‖ and s
            rbf = self.rbf_of(ctrl)
            while stepper.position < stepper.n_samples:
                q = stepper.advance(cfg.log_every)
                inner = self.inner_state(ctrl, stepper.state.controller)
                li.append(a + q - 1)
                lw.append(np.linalg.norm(rbf.weights(inner), axis=1))
                ls.append(rbf.error_function(inner))
        res = stepper.result()
        Y[a:b], YM[a:b], U[a:b] = res.output, res.measured, res.command
        state = res.final_state
        ends = seg.circle is not None and b == seg.stop
        if seg.circle is not None:
            gr = run_gate(ref.position[a:b] - YM[a:b], self.gate_config(seg), gate_state)
            laser[a:b] = gr.laser
            gate_state = gr.state
        return Chunk(
            output=Y[a:b],
            measured=YM[a:b],
            command=U[a:b],
            laser=laser[a:b],
            log_index=np.asarray(li, dtype=np.int64),
            log_w=np.asarray(lw, dtype=float).reshape(-1, 2),
            log_s=np.asarray(ls, dtype=float).reshape(-1, 2),
            loop=state,
            gate=gate_state,
            final_circle=seg.circle if ends else None,
            final_controller=state.controller.copy() if ends else None,
        )


# ---------------------------------------------------------------------------- files
def chunk_path(run_dir: Path, first: int) -> Path:
    """``run_dir/chunks/NNNNN.npz``: the checkpoint whose first chunk is ``first``."""
    return run_dir / "chunks" / f"{first:05d}.npz"


def save_chunks(run_dir: Path, first: int, chunks: Sequence[Chunk], fingerprint: str) -> None:
    """Write chunks ``first, first + 1, ...`` and the state after the last, atomically.

    Parameters
    ----------
    run_dir : pathlib.Path
        The run folder (``out/run``).
    first : int
        Number of the first chunk, from 0.
    chunks : sequence of Chunk
        Consecutive chunks (at least one); the last must carry its ``loop`` state.
    fingerprint : str
        `JobConfig.fingerprint` of the job.
    """
    if not chunks:
        raise ValueError("save_chunks needs at least one chunk")
    last = chunks[-1]
    if last.loop is None:
        raise ValueError("the last chunk of a checkpoint must carry its loop state")
    ends = [c for c in chunks if c.final_circle is not None]
    arrays: dict[str, Any] = {
        "sizes": np.array([c.laser.shape[0] for c in chunks], dtype=np.int64),
        "log_sizes": np.array([c.log_index.shape[0] for c in chunks], dtype=np.int64),
        "output": np.concatenate([c.output for c in chunks]),
        "measured": np.concatenate([c.measured for c in chunks]),
        "command": np.concatenate([c.command for c in chunks]),
        "laser": np.concatenate([c.laser for c in chunks]),
        "log_index": np.concatenate([np.asarray(c.log_index, dtype=np.int64) for c in chunks]),
        "log_w": np.concatenate([np.reshape(c.log_w, (-1, 2)) for c in chunks]),
        "log_s": np.concatenate([np.reshape(c.log_s, (-1, 2)) for c in chunks]),
        "ends_at": np.array([i for i, c in enumerate(chunks) if c.final_circle is not None]),
        "final_circles": np.array([c.final_circle for c in ends], dtype=np.int64),
        "plant": last.loop.plant,
        "controller": last.loop.controller,
        "last_command": last.loop.command,
    }
    if ends:
        arrays["final_controllers"] = np.stack([c.final_controller for c in ends])
    if last.gate is not None:
        arrays["gate"] = last.gate
    save_state(chunk_path(run_dir, first), kind=KIND, version=FORMAT_VERSION,
               settings={"job": fingerprint}, arrays=arrays)  # fmt: skip


def _split(a: np.ndarray, sizes: np.ndarray) -> list[np.ndarray]:
    return np.split(a, np.cumsum(sizes)[:-1])


def _load(path: Path, fingerprint: str) -> list[Chunk]:
    saved = read_state(path, kind=KIND, versions=(FORMAT_VERSION,),
                       settings={"job": fingerprint}, fix=_FIX)  # fmt: skip
    if saved is None:
        return []
    z = saved.arrays
    sizes, log_sizes = z["sizes"], z["log_sizes"]
    sig = {k: _split(z[k], sizes) for k in ("output", "measured", "command", "laser")}
    logs = {k: _split(z[k], log_sizes) for k in ("log_index", "log_w", "log_s")}
    # chunk (within the file) -> (circle it ends, that circle's final controller state)
    ends = {
        int(i): (int(c), z["final_controllers"][j])
        for j, (i, c) in enumerate(zip(z["ends_at"], z["final_circles"], strict=True))
    }
    loop = LoopState(
        plant=z["plant"],
        controller=z["controller"],
        observer=np.zeros(0),
        command=z["last_command"],
    )
    gate = z["gate"] if "gate" in z else None
    out = []
    n = sizes.shape[0]
    for i in range(n):
        circle, final = ends.get(i, (None, None))
        out.append(
            Chunk(
                **{k: v[i] for k, v in sig.items()},
                **{k: v[i] for k, v in logs.items()},
                loop=loop if i == n - 1 else None,
                gate=gate if i == n - 1 else None,
                final_circle=circle,
                final_controller=final,
            )
        )
    return out


def load_chunks(run_dir: Path, fingerprint: str, total: int) -> list[Chunk]:
    """The saved chunks 0, 1, ... up to the first missing checkpoint (at most ``total``).

    Raises
    ------
    ValueError
        When a checkpoint belongs to another job configuration or format (including
        the format-1 ``state.npz``), or holds more chunks than the job; nothing is
        changed then.
    """
    if (run_dir / _OLD_STATE).exists():
        raise ValueError(
            f"{run_dir} holds a run saved in format 1 ({_OLD_STATE}); this microfab reads "
            f"format {FORMAT_VERSION}; {_FIX}"
        )
    out: list[Chunk] = []
    while len(out) < total:
        path = chunk_path(run_dir, len(out))
        if not path.exists():
            break
        out += _load(path, fingerprint)
    if len(out) > total:
        raise ValueError(f"{run_dir} holds more chunks than this job; {_FIX}")
    return out
