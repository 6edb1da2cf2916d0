"""Per-sample closed-loop simulation of any plant and control `Loop` written as state machines.

`simulate` runs the compiled numba loop (`microfab.sim.kernels.compiled_loop`) when every part
derives from `microfab.core.compiled.Compiled` (`is_compiled`), and the plain Python loop
`simulate_python` otherwise; both give the same numbers. The order of operations within a
sample is that of `microfab.control.base.Loop`. Successive calls continue from the
``final_state`` of the previous one, so a run may be split into pieces (settling periods,
hold after a one-shot command) without changing a sample.

The reference seen by a preview controller beyond the end of the given samples wraps
around when ``periodic`` (the command repeats) and otherwise holds the last position with
zero derivatives (the machine holds the last command).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.control.base import (
    CompiledController,
    CompiledObserver,
    Controller,
    Feedforward,
    Loop,
    ReferenceWindow,
    as_loop,
)
from microfab.core.validate import check_int
from microfab.plants.base import CompiledPlant, Plant
from microfab.sim.kernels import compiled_loop, passthrough_step
from microfab.sim.result import SimResult
from microfab.trajectory.base import Trajectory

__all__ = [
    "LoopState",
    "LoopStepper",
    "filter_reference",
    "is_compiled",
    "reference_array",
    "simulate",
    "simulate_python",
]

_EMPTY = np.zeros(0)
_DERIVATIVES = ("velocity", "acceleration", "jerk")


@dataclass(kw_only=True, eq=False)
class LoopState:
    """Where a per-sample loop stands between two calls.

    Attributes
    ----------
    plant, controller, observer : Any
        Component states (flat ``float64`` arrays for compiled components; the
        observer's is an empty array when the loop has none).
    command : numpy.ndarray
        Command applied over the last sample, shape (n_inputs,) (what an observer sees
        next).
    """

    plant: Any
    controller: Any
    observer: Any
    command: np.ndarray

    @classmethod
    def at_rest(cls, plant: Plant, loop: Loop) -> LoopState:
        """Every component at rest, no command applied yet."""
        return cls(
            plant=plant.init(),
            controller=loop.controller.init(),
            observer=_EMPTY if loop.observer is None else loop.observer.init(),
            command=np.zeros(plant.n_inputs),
        )

    def copy(self) -> LoopState:
        """A copy whose arrays the compiled loop may modify in place."""

        def cp(s: Any) -> Any:
            return s.copy() if isinstance(s, np.ndarray) else s

        return LoopState(
            plant=cp(self.plant),
            controller=cp(self.controller),
            observer=cp(self.observer),
            command=self.command.copy(),
        )


def is_compiled(plant: Plant, controller: Controller | Loop) -> bool:
    """True when plant, controller and observer all run in the compiled loop."""
    loop = as_loop(controller)
    return (
        isinstance(plant, CompiledPlant)
        and isinstance(loop.controller, CompiledController)
        and (loop.observer is None or isinstance(loop.observer, CompiledObserver))
    )


def _as_2d(a: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] == 0:
        raise ValueError(f"{name} must be shaped (n_samples >= 1, n_axes), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} holds NaN or inf")
    return arr


def reference_array(
    position: np.ndarray,
    derivatives: Sequence[np.ndarray] = (),
    preview: int = 1,
    periodic: bool = False,
) -> np.ndarray:
    """Stack a reference for the loops: shape (n + preview - 1, 1 + len(derivatives), n_axes).

    Parameters
    ----------
    position : numpy.ndarray
        Reference positions, shape (n, n_axes).
    derivatives : sequence of numpy.ndarray
        Velocity, then acceleration, then jerk (a prefix of them), each (n, n_axes).
    preview : int
        Samples a controller sees at each step (>= 1).
    periodic : bool
        The extra ``preview - 1`` samples wrap around when true; otherwise they hold the
        last position with zero derivatives.

    Returns
    -------
    numpy.ndarray
        Read-only, C-contiguous.
    """
    pos = _as_2d(position, "reference")
    if len(derivatives) > len(_DERIVATIVES):
        raise ValueError(f"at most {len(_DERIVATIVES)} derivatives (velocity, acceleration, jerk)")
    orders = [pos]
    for name, d in zip(_DERIVATIVES, derivatives, strict=False):
        arr = _as_2d(d, name)
        if arr.shape != pos.shape:
            raise ValueError(
                f"{name} must be shaped like the reference {pos.shape}, got {arr.shape}"
            )
        orders.append(arr)
    check_int("preview", preview, 1, "samples")
    n = pos.shape[0]
    R = np.empty((n + preview - 1, len(orders), pos.shape[1]))
    for d, arr in enumerate(orders):
        R[:n, d] = arr
        if preview > 1:
            if periodic:
                R[n:, d] = arr[np.arange(preview - 1) % n]
            else:
                R[n:, d] = arr[-1] if d == 0 else 0.0
    R.setflags(write=False)
    return R


def filter_reference(
    feedforward: Feedforward,
    position: np.ndarray,
    dt: float,
    derivatives: Sequence[np.ndarray] = (),
    axes: tuple[str, ...] = (),
    periodic: bool = False,
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The loop reference a feedforward makes of a command.

    A periodic command is filtered as three periods and the middle one is kept (for a
    filter whose memory is shorter than a period, its periodic steady state); a one-shot
    command is filtered as it is and may come out longer.

    Parameters
    ----------
    feedforward : Feedforward
        The command filter.
    position : numpy.ndarray
        Command, shape (n, n_axes).
    dt : float
        Sample time, s.
    derivatives : sequence of numpy.ndarray
        Velocity, acceleration, jerk of the command (a prefix), each (n, n_axes).
    axes : tuple of str
        Axis names (generated when empty).
    periodic : bool
        Whether the command is one period of a repeated signal.

    Returns
    -------
    position : numpy.ndarray
        Loop reference, shape (m, n_axes); ``m = n`` when periodic.
    derivatives : tuple of numpy.ndarray
        Its derivatives (a prefix of velocity, acceleration, jerk).
    """
    pos = _as_2d(position, "reference")
    n, na = pos.shape
    names = axes or tuple(f"a{i}" for i in range(na))
    reps = 3 if periodic else 1
    kw = {
        name: np.tile(np.asarray(d, float).reshape(n, na), (reps, 1))
        for name, d in zip(_DERIVATIVES, derivatives, strict=False)
    }
    traj = Trajectory(
        dt=dt, position=np.tile(pos, (reps, 1)), axes=names, at_rest=not periodic, **kw
    )
    out = feedforward.apply(traj)
    if abs(out.dt - dt) > 1e-12 * dt or out.axes != names:
        raise ValueError(
            f"{type(feedforward).__name__} changed the sample time or the axes "
            f"({out.dt} s, {out.axes}); a feedforward keeps dt = {dt} s and axes {names}"
        )
    sl = slice(n, 2 * n) if periodic else slice(0, out.n_samples)
    if out.n_samples < (2 * n if periodic else n):
        raise ValueError(
            f"{type(feedforward).__name__} shortened the command to {out.n_samples} samples"
        )
    derivs = []
    for name in _DERIVATIVES:
        arr = getattr(out, name)
        if arr is None:
            break
        derivs.append(np.array(arr[sl]))
    return np.array(out.position[sl]), tuple(derivs)


def _prepare(
    plant: Plant,
    loop: Loop,
    reference: np.ndarray,
    noise: np.ndarray | None,
    derivatives: Sequence[np.ndarray],
    periodic: bool,
    axes: tuple[str, ...],
) -> tuple[Loop, np.ndarray, np.ndarray]:
    """``(loop without feedforward, stacked reference, noise)``, all checked."""
    pos = _as_2d(reference, "reference")
    if loop.feedforward is not None:
        pos, derivatives = filter_reference(
            loop.feedforward, pos, plant.dt, derivatives, axes, periodic
        )
        loop = Loop(controller=loop.controller, observer=loop.observer)
    R = reference_array(pos, derivatives, loop.preview, periodic)
    n, ny = pos.shape[0], plant.n_outputs
    if noise is None:
        nz = np.zeros((n, ny))
    else:
        nz = np.ascontiguousarray(np.asarray(noise, dtype=float))
        if nz.ndim == 1:
            nz = nz[:, None]
        if nz.shape != (n, ny):
            raise ValueError(
                f"noise must be shaped {(n, ny)} (samples of the loop reference, outputs), "
                f"got {nz.shape}"
            )
    return loop, R, nz


def simulate(
    plant: Plant,
    controller: Controller | Loop,
    reference: np.ndarray,
    noise: np.ndarray | None = None,
    state: LoopState | None = None,
    axes: tuple[str, ...] = (),
    *,
    derivatives: Sequence[np.ndarray] = (),
    periodic: bool = False,
) -> SimResult:
    """Simulate the sampled feedback loop, one sample at a time (compiled when possible).

    Parameters
    ----------
    plant : Plant
        Plant state machine with ``n_outputs`` measured outputs.
    controller : Controller or Loop
        The controller, or a `Loop` (controller, feedforward, observer).
    reference : numpy.ndarray
        Command, shape (n_samples, n_axes), in the measurement's unit.
    noise : numpy.ndarray, optional
        Measurement noise added to the plant output, shape (n_samples, n_outputs), where
        ``n_samples`` is that of the loop reference (a feedforward may lengthen a one-shot
        command).
    state : LoopState, optional
        Where to continue from (``final_state`` of an earlier result); at rest if omitted.
    axes : tuple of str
        Axis names for the result.
    derivatives : sequence of numpy.ndarray
        Velocity, acceleration, jerk of the reference (a prefix), each (n_samples, n_axes),
        for a controller's reference window.
    periodic : bool
        Whether the reference repeats (window beyond the end wraps; feedforward filters
        it as periodic), or is held at its last value after the end.

    Returns
    -------
    SimResult
        Signals and the final `LoopState` (``final_state``).
    """
    loop = as_loop(controller)
    if not is_compiled(plant, loop):
        return simulate_python(
            plant, loop, reference, noise, state, axes, derivatives=derivatives, periodic=periodic
        )
    stepper = LoopStepper(
        plant, loop, reference, noise, state, axes, derivatives=derivatives, periodic=periodic
    )
    stepper.advance()
    return stepper.result()


class LoopStepper:
    """A compiled closed loop run in pieces: checked and allocated once, then `advance`.

    `simulate` checks its inputs, copies the state and allocates its outputs at every
    call, some 0.1 ms; a job that stops every few hundred samples (to log a controller's
    internals, to checkpoint) pays that many times. A stepper does it once for the whole
    reference and then runs the compiled loop from where it stopped: ``advance(m)`` runs
    the next ``m`` samples in place. The samples are those of one `simulate` call over
    the whole reference (a preview controller sees the true next samples at a stop).

    Parameters
    ----------
    plant, controller, reference, noise, state, axes, derivatives, periodic
        As for `simulate`; every part must run in the compiled loop (`is_compiled`).

    Attributes
    ----------
    n_samples : int
        Samples of the loop reference.
    position : int
        Samples run so far.

    Raises
    ------
    TypeError
        When a part of the loop has no compiled kernels (use `simulate`).

    Examples
    --------
    >>> from microfab.control.base import LTIController
    >>> from microfab.plants.base import LTIPlant
    >>> from microfab.plants.lti import DiscreteLTI
    >>> plant = LTIPlant(DiscreteLTI([[0.9]], [[0.1]], [[1.0]], [[0.0]], 1e-3))
    >>> gain = LTIController(DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)),
    ...                                  np.zeros((1, 0)), [[2.0]], 1e-3))
    >>> stepper = LoopStepper(plant, gain, np.ones((100, 1)))
    >>> stepper.advance(40), stepper.advance(), stepper.position
    (40, 100, 100)
    >>> whole = simulate(plant, gain, np.ones((100, 1)))
    >>> bool(np.array_equal(stepper.result().output, whole.output))
    True
    """

    def __init__(
        self,
        plant: Plant,
        controller: Controller | Loop,
        reference: np.ndarray,
        noise: np.ndarray | None = None,
        state: LoopState | None = None,
        axes: tuple[str, ...] = (),
        *,
        derivatives: Sequence[np.ndarray] = (),
        periodic: bool = False,
    ) -> None:
        loop = as_loop(controller)
        if not is_compiled(plant, loop):
            raise TypeError(
                "LoopStepper runs the compiled loop only; a part of this loop has no "
                "compiled kernels: use simulate (it falls back to the Python loop)"
            )
        loop, R, nz = _prepare(plant, loop, reference, noise, derivatives, periodic, axes)
        self.plant, self.axes = plant, axes
        self._st = LoopState.at_rest(plant, loop) if state is None else state.copy()
        ctrl = loop.controller
        if loop.observer is None:
            obs_step, op, n_est = passthrough_step, _EMPTY, plant.n_outputs
        else:
            (obs_step,) = loop.observer.kernels()  # type: ignore[attr-defined]
            op, n_est = loop.observer.packed_params(), loop.observer.n_outputs  # type: ignore[attr-defined]
        out_k, upd_k = plant.kernels()  # type: ignore[attr-defined]
        (step_k,) = ctrl.kernels()  # type: ignore[attr-defined]
        self._run = compiled_loop(out_k, upd_k, step_k, obs_step)
        self._pp = plant.packed_params()  # type: ignore[attr-defined]
        self._cp = ctrl.packed_params()  # type: ignore[attr-defined]
        self._op = op
        self._R, self._noise = R, nz
        self.n_samples = nz.shape[0]
        self.position = 0
        self._est = np.empty(n_est)
        self._y = np.empty((self.n_samples, plant.n_outputs))
        self._ym = np.empty_like(self._y)
        self._u = np.empty((self.n_samples, plant.n_inputs))

    def advance(self, n_samples: int | None = None) -> int:
        """Run the next ``n_samples`` samples (default: to the end); return `position`.

        Stops at the end of the reference; advancing there does nothing.
        """
        p = self.position
        q = self.n_samples
        if n_samples is not None:
            q = min(p + check_int("n_samples", n_samples, 0, "samples"), q)
        if q > p:
            st = self._st
            self._run(
                self._pp,
                st.plant,
                self._cp,
                st.controller,
                self._op,
                st.observer,
                self._R[p:],
                self._noise[p:q],
                st.command,
                self._est,
                self._y[p:q],
                self._ym[p:q],
                self._u[p:q],
            )
            self.position = q
        return self.position

    @property
    def state(self) -> LoopState:
        """The loop state after the samples run so far (live: `advance` changes it).

        Take ``state.copy()`` to keep it.
        """
        return self._st

    def result(self) -> SimResult:
        """Signals of the samples run so far and a copy of the state after them."""
        n = self.position
        return SimResult(
            dt=self.plant.dt,
            reference=np.array(self._R[:n, 0]),
            output=self._y[:n],
            measured=self._ym[:n],
            command=self._u[:n],
            axes=self.axes,
            final_state=self._st.copy() if n < self.n_samples else self._st,
        )


def simulate_python(
    plant: Plant,
    controller: Controller | Loop,
    reference: np.ndarray,
    noise: np.ndarray | None = None,
    state: LoopState | None = None,
    axes: tuple[str, ...] = (),
    *,
    derivatives: Sequence[np.ndarray] = (),
    periodic: bool = False,
) -> SimResult:
    """The loop of `simulate` in plain Python, for any components (reference, slower).

    Parameters and result as for `simulate`.
    """
    loop, R, nz = _prepare(
        plant, as_loop(controller), reference, noise, derivatives, periodic, axes
    )
    st = LoopState.at_rest(plant, loop) if state is None else state
    px, cx, ox, u_prev = st.plant, st.controller, st.observer, st.command
    ctrl, obs, P = loop.controller, loop.observer, loop.preview
    n = nz.shape[0]
    y = np.empty((n, plant.n_outputs))
    ym = np.empty_like(y)
    u = np.empty((n, plant.n_inputs))
    window = ReferenceWindow.from_array
    for k in range(n):
        yk = plant.output(px)
        ymk = yk + nz[k]
        if obs is None:
            est = ymk
        else:
            est, ox = obs.step(ox, u_prev, ymk)
        uk, cx = ctrl.step(cx, window(R[k : k + P]), est)
        px = plant.update(px, uk)
        y[k], ym[k], u[k] = yk, ymk, uk
        u_prev = u[k]  # a row no later sample writes: safe to share
    return SimResult(
        dt=plant.dt,
        reference=np.array(R[:n, 0]),
        output=y,
        measured=ym,
        command=u,
        axes=axes,
        final_state=LoopState(plant=px, controller=cx, observer=ox, command=np.array(u_prev)),
    )
