"""`SimulatedMachine`: a digital twin built from plant and control components, with noise.

The machine is one or more independent closed loops side by side, each a `Plant` with
its control `Loop` (controller, optional feedforward, optional observer), plus seeded
encoder noise. It picks the fastest simulator that can run all its parts
(`SimulatedMachine.path`):

* ``lifted``: every plant an `LTIPlant` and every loop an `LTIController` without
  observer: the closed loops are linear and run in lifted blocks (`LTILoop`, BLAS);
* ``compiled``: every part derives from `microfab.core.compiled.Compiled`: the numba
  per-sample loop (`microfab.sim.loop.simulate`);
* ``python``: anything else, the Python per-sample loop (`simulate_python`).

The three give the same numbers (to round-off); a path may be forced for checks.
Feedforward filters run before the loop on every path.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.control.base import Controller, Loop, LTIController, as_loop
from microfab.core.limits import AxisLimits, check_command
from microfab.core.threads import one_blas_thread
from microfab.core.validate import check_int, check_nonnegative, check_positive
from microfab.machines.base import Measurement
from microfab.plants.base import LTIPlant, Plant
from microfab.sim.loop import LoopState, filter_reference, is_compiled, simulate, simulate_python
from microfab.sim.lti_fast import LTILoop
from microfab.sim.noise import scaled_normal

__all__ = ["EncoderNoise", "Settling", "SimPath", "SimulatedMachine"]

Reference = tuple[np.ndarray, tuple[np.ndarray, ...]]  # positions, derivatives of one loop


class SimPath(enum.StrEnum):
    """Which simulator a `SimulatedMachine` runs (equal to its name as a string)."""

    LIFTED = "lifted"
    COMPILED = "compiled"
    PYTHON = "python"


@dataclass(frozen=True, kw_only=True)
class EncoderNoise:
    """White Gaussian measurement noise, seeded.

    Each run draws ``standard_normal((n_samples, n_axes)) * rms`` from one
    ``numpy.random.default_rng(seed)`` generator per machine, in the order the samples
    are simulated.

    Parameters
    ----------
    rms : tuple of float
        Standard deviation per output axis, in the output's unit (>= 0).
    seed : int
        Seed of the generator.
    """

    rms: tuple[float, ...]
    seed: int = 0

    def __post_init__(self) -> None:
        check_int("seed", self.seed, 0)
        rms = tuple(float(r) for r in self.rms)
        for i, r in enumerate(rms):
            check_nonnegative(f"noise rms of axis {i}", r, "(output unit)")
        object.__setattr__(self, "rms", rms)

    def draw(self, rng: np.random.Generator, n_samples: int) -> np.ndarray:
        """Noise for ``n_samples`` samples, shape (n_samples, n_axes).

        Compiled (`microfab.sim.noise.scaled_normal`), bit for bit the NumPy expression
        of the class docstring.
        """
        return scaled_normal(rng, n_samples, np.asarray(self.rms))


@dataclass(frozen=True, kw_only=True)
class Settling:
    """When a one-shot run (`SimulatedMachine.run_once`) stops holding the last command.

    The hold ends once every axis' noise-free output has stayed within ``tolerance`` of
    the last command for ``dwell_s``, or after ``max_hold_s`` (then the measurement says
    ``settled=False``).

    Parameters
    ----------
    tolerance : float
        Largest ``|output - final command|``, output unit (default 1e-3: 1 mV of encoder
        signal on the galvo twin).
    dwell_s : float
        How long the output must stay within the tolerance, s (default 1 ms); also the
        length of the hold steps between checks.
    max_hold_s : float
        Longest hold after the command, s (default 0.1 s).
    """

    tolerance: float = 1e-3
    dwell_s: float = 1e-3
    max_hold_s: float = 0.1

    def __post_init__(self) -> None:
        check_positive("tolerance", self.tolerance, "(output unit)")
        check_positive("dwell_s", self.dwell_s, "s")
        check_nonnegative("max_hold_s", self.max_hold_s, "s")


def _lifted_ok(plant: Plant, loop: Loop) -> bool:
    return (
        isinstance(plant, LTIPlant)
        and isinstance(loop.controller, LTIController)
        and loop.observer is None
    )


class SimulatedMachine:
    """A twin of a stabilised machine, from components, driven periodically or once.

    Parameters
    ----------
    plant : Plant or sequence of Plant
        The plant, or several independent plants side by side (e.g. one per axis); the
        plants take the command and output columns in order, ``n_outputs`` each.
    controller : Controller, Loop, or sequence of them
        The control side of each plant's loop (closed-loop injection: the command is the
        loop's reference, seed 000 Fig. 2); a sequence when ``plant`` is one.
    noise : EncoderNoise, optional
        Measurement noise and its seed; none when omitted.
    axes : tuple of str
        Axis names, one per output column.
    limits : mapping of str to AxisLimits
        Declared command limits; a command beyond them is refused before it runs.
    settle_periods : int
        Periods `run` plays before the recorded one.
    settling : Settling
        When `run_once` stops holding.
    path : SimPath, optional
        Force a simulator; the fastest one that runs every part when omitted.

    Attributes
    ----------
    path : SimPath
        The simulator chosen (``"lifted"``, ``"compiled"`` or ``"python"``).
    samples_simulated : int
        Samples simulated so far (settling periods and holds included).
    rng : numpy.random.Generator
        The noise generator (seeded by ``noise.seed``).

    Raises
    ------
    ValueError
        On inconsistent sizes or sample times, or a forced path that cannot run the parts.

    Notes
    -----
    Several axes are given either as one multi-input multi-output plant with one
    controller, or as independent (plant, controller) pairs, one per axis or group of
    axes. Pairs are cheaper on the lifted path (each closed loop is simulated on its own
    states) and let each axis have its own controller type; the galvo twin uses one SISO
    pair per axis.
    """

    def __init__(
        self,
        plant: Plant | Sequence[Plant],
        controller: Controller | Loop | Sequence[Controller | Loop],
        noise: EncoderNoise | None = None,
        *,
        axes: tuple[str, ...],
        limits: Mapping[str, AxisLimits],
        settle_periods: int = 1,
        settling: Settling | None = None,
        path: SimPath | None = None,
    ) -> None:
        plants = tuple(plant) if isinstance(plant, Sequence) else (plant,)
        ctrls = tuple(controller) if isinstance(controller, Sequence) else (controller,)
        if not plants or len(plants) != len(ctrls):
            raise ValueError(
                f"give one controller per plant, got {len(plants)} plants, {len(ctrls)} controllers"
            )
        for p in plants:
            if not isinstance(p, Plant):
                raise TypeError(
                    f"not a Plant (n_inputs, n_outputs, dt, init, output, update): {p!r}"
                )
        self.plants = plants
        self.loops = tuple(as_loop(c) for c in ctrls)
        self._plain = all(lp.feedforward is None for lp in self.loops)  # no feedforward
        # what the per-sample simulators run: the feedforward is applied before them
        self._bare = tuple(
            lp if lp.feedforward is None else Loop(controller=lp.controller, observer=lp.observer)
            for lp in self.loops
        )
        self.dt = float(plants[0].dt)
        if any(abs(p.dt - self.dt) > 1e-12 * self.dt for p in plants):
            raise ValueError(
                f"all plants must share one sample time, got {[p.dt for p in plants]} s"
            )
        n_out = sum(p.n_outputs for p in plants)
        if len(axes) != n_out:
            raise ValueError(f"give one axis name per plant output ({n_out}), got {axes}")
        if noise is not None and len(noise.rms) != n_out:
            raise ValueError(f"give one noise level per axis ({n_out}), got {len(noise.rms)}")
        check_int("settle_periods", settle_periods, 0, "periods")
        self.axes = tuple(axes)
        self.noise = noise
        self.limits = dict(limits)
        self.settle_periods = settle_periods
        self.settling = settling if settling is not None else Settling()
        self.rng = np.random.default_rng(noise.seed if noise is not None else 0)
        self.samples_simulated = 0
        self._cols: list[slice] = []
        start = 0
        for p in plants:
            self._cols.append(slice(start, start + p.n_outputs))
            start += p.n_outputs
        self.path = self._choose(path)
        self.lifted: LTILoop | None = None
        if self.path is SimPath.LIFTED:
            self.lifted = LTILoop(
                [p.sys for p in plants],  # type: ignore[attr-defined]
                [lp.controller.sys for lp in self.loops],  # type: ignore[attr-defined]
                self.axes,
            )
        self._states: list[LoopState | None] = [None] * len(plants)

    def _choose(self, forced: SimPath | None) -> SimPath:
        pairs = list(zip(self.plants, self.loops, strict=True))
        can = {
            SimPath.LIFTED: all(_lifted_ok(p, lp) for p, lp in pairs),
            SimPath.COMPILED: all(is_compiled(p, lp) for p, lp in pairs),
            SimPath.PYTHON: True,
        }
        if forced is None:  # the fastest that can: SimPath lists them fastest first
            return next(p for p in SimPath if can[p])
        forced = SimPath(forced)
        if not can[forced]:
            need = {
                SimPath.LIFTED: "an LTIPlant with an LTIController and no observer",
                SimPath.COMPILED: "Compiled plant, controller and observer",
            }[forced]
            raise ValueError(f"the {forced} path needs {need} in every loop")
        return forced

    @property
    def state(self) -> list[np.ndarray] | list[LoopState | None]:
        """A copy of where the loops stand (lifted: closed-loop states; else `LoopState`).

        ``None`` entries (per-sample paths) mean at rest.
        """
        if self.lifted is not None:
            return [lp.state.copy() for lp in self.lifted.loops]
        return [None if s is None else s.copy() for s in self._states]

    def snapshot(self) -> dict[str, Any] | None:
        """JSON-ready state of the loops and the noise generator (`Resumable`).

        None when a per-sample component keeps a state that is not an array.
        """
        loops: list[Any] = []
        if self.lifted is not None:
            loops = [lp.state.tolist() for lp in self.lifted.loops]
        else:
            for st in self._states:
                if st is None:
                    loops.append(None)
                    continue
                parts = (st.plant, st.controller, st.observer, st.command)
                if not all(isinstance(p, np.ndarray) for p in parts):
                    return None
                loops.append([np.asarray(p, dtype=float).tolist() for p in parts])
        return {"kind": "simulated", "rng": self.rng.bit_generator.state, "loops": loops}

    def restore(self, snapshot: dict[str, Any]) -> None:
        """Put the loops and the noise generator back where `snapshot` was taken.

        Raises
        ------
        ValueError
            A snapshot of another kind of machine or of another number of loops.
        """
        loops = snapshot.get("loops")
        n = len(self.lifted.loops) if self.lifted is not None else len(self._states)
        if snapshot.get("kind") != "simulated" or not isinstance(loops, list) or len(loops) != n:
            raise ValueError("the saved machine state belongs to another machine")
        self.rng.bit_generator.state = snapshot["rng"]
        if self.lifted is not None:
            for lp, st in zip(self.lifted.loops, loops, strict=True):
                lp.reset(np.asarray(st, dtype=float))
            return
        self._states = [
            None
            if v is None
            else LoopState(
                plant=np.asarray(v[0], dtype=float),
                controller=np.asarray(v[1], dtype=float),
                observer=np.asarray(v[2], dtype=float),
                command=np.asarray(v[3], dtype=float),
            )
            for v in loops
        ]

    def reset(self) -> None:
        """Bring every loop to rest (the noise generator goes on)."""
        if self.lifted is not None:
            self.lifted.reset()
        self._states = [None] * len(self.plants)

    def rest_output(self) -> np.ndarray:
        """The noise-free output at rest, shape (n_axes,)."""
        return np.concatenate([np.asarray(p.output(p.init()), float) for p in self.plants])

    def run(self, command: np.ndarray, with_actuator: bool = False) -> Measurement:
        """Play ``command`` periodically and measure its last period.

        The machine keeps running: the period is played ``settle_periods + 1`` times from
        wherever the previous run left the loops, and the last one is returned (the
        steady state, as an experimenter would record it). Noise is drawn per period.

        Parameters
        ----------
        command : numpy.ndarray
            One period of the command, shape (n_samples, n_axes), output unit.
        with_actuator : bool
            Also return the controllers' actuator signal (more work on the lifted path).

        Raises
        ------
        microfab.core.limits.LimitViolation
            When the command (or its feedforward-filtered reference) exceeds the declared
            limits; nothing is run and the noise generator does not move.
        """
        cmd = self._command(command)
        check_command(cmd, self.dt, self.limits, self.axes, periodic=True)
        refs = self._references(cmd, periodic=True)
        self._check_filtered(refs, None)
        n = cmd.shape[0]
        if self.lifted is not None:
            ym, u = self._run_lifted(cmd, refs, with_actuator)
        else:
            for _ in range(self.settle_periods):
                self._advance(refs, self._noise(n), periodic=True, with_command=False)
            _, ym, u = self._advance(
                refs, self._noise(n), periodic=True, with_command=with_actuator
            )
        self.samples_simulated += n * (self.settle_periods + 1)
        return Measurement(
            dt=self.dt,
            command=cmd,
            output=ym,
            axes=self.axes,
            actuator=u if with_actuator else None,
        )

    def run_once(
        self, command: np.ndarray, *, settle_s: float | None = None, with_actuator: bool = False
    ) -> Measurement:
        """Play ``command`` once from rest, then hold its last value until settled.

        The loops are brought to rest, the command is played (after its feedforward, if
        any), and its last sample is held in steps of ``settling.dwell_s`` until the
        noise-free output has stayed within ``settling.tolerance`` of it for
        ``settling.dwell_s`` on every axis, or ``settle_s`` has passed. The machine then
        stands where the record ends.

        Parameters
        ----------
        command : numpy.ndarray
            The command, shape (n_samples, n_axes), output unit. The machine starts at
            `rest_output`, so the step to the first sample is checked against the limits.
        settle_s : float, optional
            Longest hold, s; ``settling.max_hold_s`` when omitted.
        with_actuator : bool
            Also return the controllers' actuator signal.

        Returns
        -------
        Measurement
            The whole record: ``command`` is the command followed by its held last value,
            ``settled`` whether the output settled within the longest hold.

        Raises
        ------
        microfab.core.limits.LimitViolation
            When the command exceeds the declared limits (nothing is run).
        """
        cmd = self._command(command)
        max_hold = (
            self.settling.max_hold_s
            if settle_s is None
            else check_nonnegative("settle_s", settle_s, "s")
        )
        rest = self.rest_output()[None, :]
        check_command(np.vstack([rest, cmd]), self.dt, self.limits, self.axes, periodic=False)
        refs = self._references(cmd, periodic=False)
        self._check_filtered(refs, rest)
        self.reset()
        m = refs[0][0].shape[0]
        act = with_actuator
        parts = [self._advance(refs, self._noise(m), periodic=False, with_command=act)]
        final = cmd[-1]
        tol = self.settling.tolerance
        dwell = max(1, round(self.settling.dwell_s / self.dt))
        max_n = round(max_hold / self.dt)

        def inside_run(y: np.ndarray, previous: int) -> int:
            ok = np.all(np.abs(y - final) <= tol, axis=1)
            if ok.all():
                return previous + ok.size
            return ok.size - 1 - int(np.flatnonzero(~ok)[-1])

        trailing = inside_run(parts[0][0], 0)
        held = 0
        hold_refs = [(pos[-1:], tuple(np.zeros((1, pos.shape[1])) for _ in d)) for pos, d in refs]
        while trailing < dwell and held < max_n:
            c = min(dwell, max_n - held)
            step = [
                (np.repeat(p, c, 0), tuple(np.repeat(x, c, 0) for x in d)) for p, d in hold_refs
            ]
            parts.append(self._advance(step, self._noise(c), periodic=False, with_command=act))
            trailing = inside_run(parts[-1][0], trailing)
            held += c
        total = m + held
        self.samples_simulated += total
        command_rec = np.vstack([cmd, np.repeat(cmd[-1:], total - cmd.shape[0], axis=0)])
        return Measurement(
            dt=self.dt,
            command=command_rec,
            output=np.vstack([p[1] for p in parts]),
            axes=self.axes,
            actuator=np.vstack([p[2] for p in parts]) if with_actuator else None,
            settled=trailing >= dwell,
        )

    # ----------------------------------------------------------------- internals
    def _run_lifted(
        self, cmd: np.ndarray, refs: list[Reference], with_command: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """`run` on the lifted path: ``(measured, command)`` of the last period.

        The settling periods advance the state only (no output: the same state, to the
        bit). Without feedforward the loops' references are the command's columns in
        order, so the command is passed as it is; BLAS is limited to one thread once for
        the whole run rather than per product.
        """
        assert self.lifted is not None
        ref = cmd if self._plain else np.column_stack([pos for pos, _ in refs])
        n = cmd.shape[0]
        with one_blas_thread():
            for _ in range(self.settle_periods):
                self.lifted.advance(ref, self._noise(n))
            res = self.lifted.run(ref, self._noise(n), with_command=with_command)
        return res.measured, res.command

    def _command(self, command: np.ndarray) -> np.ndarray:
        cmd = np.asarray(command, dtype=float)
        if cmd.ndim == 1:
            cmd = cmd[:, None]
        if cmd.ndim != 2 or cmd.shape[1] != len(self.axes) or cmd.shape[0] < 1:
            raise ValueError(
                f"command needs {len(self.axes)} columns and >= 1 sample, got {cmd.shape}"
            )
        return cmd

    def _noise(self, n: int) -> np.ndarray:
        if self.noise is None:
            return np.zeros((n, len(self.axes)))
        return self.noise.draw(self.rng, n)

    def _references(self, cmd: np.ndarray, periodic: bool) -> list[Reference]:
        """Each loop's reference after its feedforward, all equally long."""
        refs: list[Reference] = []
        for lp, cols in zip(self.loops, self._cols, strict=True):
            if lp.feedforward is None:
                refs.append((cmd[:, cols], ()))
            else:
                names = self.axes[cols]
                refs.append(
                    filter_reference(lp.feedforward, cmd[:, cols], self.dt, (), names, periodic)
                )
        m = max(pos.shape[0] for pos, _ in refs)
        out: list[Reference] = []
        for pos, d in refs:  # one-shot feedforwards may lengthen: hold the shorter ones
            pad = m - pos.shape[0]
            if pad:
                pos = np.vstack([pos, np.repeat(pos[-1:], pad, axis=0)])
                d = tuple(np.vstack([x, np.zeros((pad, x.shape[1]))]) for x in d)
            out.append((pos, d))
        return out

    def _check_filtered(self, refs: list[Reference], rest: np.ndarray | None) -> None:
        """The loop reference after feedforward must respect the limits too."""
        if all(lp.feedforward is None for lp in self.loops):
            return
        r = np.column_stack([pos for pos, _ in refs])
        if rest is not None:
            r = np.vstack([rest, r])
        check_command(r, self.dt, self.limits, self.axes, periodic=rest is None)

    def _advance(
        self, refs: list[Reference], noise: np.ndarray, periodic: bool, with_command: bool
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Continue every loop over the given references; ``(output, measured, command)``."""
        if self.lifted is not None:
            ref = np.column_stack([pos for pos, _ in refs])
            res = self.lifted.run(ref, noise, with_command=with_command)
            return res.output, res.measured, res.command
        sim = simulate if self.path is SimPath.COMPILED else simulate_python
        ys, yms, us = [], [], []
        for i, (plant, ctrl, cols) in enumerate(
            zip(self.plants, self._bare, self._cols, strict=True)
        ):
            pos, d = refs[i]
            res = sim(
                plant, ctrl, pos, noise[:, cols], self._states[i], derivatives=d, periodic=periodic
            )
            self._states[i] = res.final_state
            ys.append(res.output)
            yms.append(res.measured)
            us.append(res.command)
        return np.column_stack(ys), np.column_stack(yms), np.column_stack(us)
