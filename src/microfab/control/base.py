"""Control components as explicit state machines, and their composition as data.

* `Controller`: feedback (and preview) control, ``step(state, window, measurement) ->
  (command, state)``; the `ReferenceWindow` holds the next ``preview`` reference samples.
* `Feedforward`: a command filter ``Trajectory -> Trajectory`` applied before the loop
  (input shaper, model inverse, delay).
* `Observer`: ``step(state, command, measurement) -> (estimate, state)``; the controller
  then sees the estimate in place of the raw measurement.
* `Loop`: which controller, feedforward and observer make up one loop; the simulators of
  `microfab.sim` interpret it (see `Loop` for the order of operations within a sample).

Components that derive from `CompiledController` / `CompiledObserver` (and so from
`microfab.core.compiled.Compiled`) run in the compiled numba loop too; `LTIController` and
`LTIObserver` are such components, built from a `DiscreteLTI`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numba import njit

from microfab.core.compiled import Compiled, lti_dims, pack_lti
from microfab.core.validate import check_int
from microfab.plants.lti import DiscreteLTI
from microfab.trajectory.base import Trajectory

__all__ = [
    "CompiledController",
    "CompiledObserver",
    "Controller",
    "Delay",
    "Feedforward",
    "LTIController",
    "LTIObserver",
    "Loop",
    "Observer",
    "ReferenceWindow",
    "as_loop",
    "lti_error_step",
    "lti_observer_step",
]

_DERIVATIVES = ("velocity", "acceleration", "jerk")


@dataclass(frozen=True, kw_only=True, eq=False, slots=True)
class ReferenceWindow:
    """The reference a controller sees at one sample: this sample and the next ones.

    Row ``i`` is ``i`` samples ahead of the current sample (row 0 is the current one).
    Beyond the end of a periodic reference the window wraps around; beyond the end of a
    one-shot reference it holds the last position with zero derivatives.

    Parameters
    ----------
    position : numpy.ndarray
        Reference positions, shape (preview, n_axes), in the measurement's unit.
    velocity, acceleration, jerk : numpy.ndarray, optional
        Derivatives carried by the trajectory, same shape, unit/s, unit/s², unit/s³;
        ``None`` where the trajectory does not carry them (only a contiguous prefix of
        the three is carried: acceleration only with velocity, jerk only with both).
    """

    position: np.ndarray
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    jerk: np.ndarray | None = None

    def __post_init__(self) -> None:
        pos = self.position
        if not isinstance(pos, np.ndarray) or pos.ndim != 2 or pos.shape[0] < 1:
            shape = getattr(pos, "shape", None)
            raise ValueError(f"position must be shaped (preview >= 1, n_axes), got {shape}")
        for name in _DERIVATIVES:
            arr = getattr(self, name)
            if arr is not None and (not isinstance(arr, np.ndarray) or arr.shape != pos.shape):
                shape = getattr(arr, "shape", None)
                raise ValueError(f"{name} must be shaped like position {pos.shape}, got {shape}")

    @classmethod
    def from_array(cls, window: np.ndarray) -> ReferenceWindow:
        """Window from the simulators' stacked layout, shape (preview, n_orders, n_axes).

        ``window[:, d]`` is derivative ``d`` (0 position, 1 velocity, ...); no copy.
        """
        w = cls.__new__(cls)
        n_orders = window.shape[1]
        object.__setattr__(w, "position", window[:, 0])
        for d, name in enumerate(_DERIVATIVES, start=1):
            object.__setattr__(w, name, window[:, d] if d < n_orders else None)
        return w

    @property
    def preview(self) -> int:
        """Number of samples in the window."""
        return int(self.position.shape[0])

    @property
    def n_axes(self) -> int:
        """Number of reference axes."""
        return int(self.position.shape[1])


@runtime_checkable
class Controller(Protocol):
    """A discrete-time controller as an explicit state machine.

    Attributes
    ----------
    preview : int
        Samples of reference the controller sees at each step (>= 1; 1 is plain
        feedback on the current reference sample).

    Notes
    -----
    ``step`` returns a new state and must not modify the one it is given.
    """

    preview: int

    def init(self) -> Any:
        """The state at rest."""
        ...

    def step(
        self, state: Any, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, Any]:
        """One sample: ``(command, next_state)``; ``command`` shape (n_commands,)."""
        ...


@runtime_checkable
class Feedforward(Protocol):
    """A command filter applied to the whole command before the loop runs it."""

    def apply(self, trajectory: Trajectory) -> Trajectory:
        """The loop reference for ``trajectory`` (same ``dt`` and axes, at least as long)."""
        ...


@runtime_checkable
class Observer(Protocol):
    """A state (or disturbance) estimator as an explicit state machine.

    Attributes
    ----------
    n_outputs : int
        Length of the estimate, which the controller receives as its measurement.
    """

    n_outputs: int

    def init(self) -> Any:
        """The state at rest."""
        ...

    def step(
        self, state: Any, command: np.ndarray, measurement: np.ndarray
    ) -> tuple[np.ndarray, Any]:
        """``(estimate, next_state)`` from the previous command and this measurement."""
        ...


class CompiledController(Compiled):
    """A controller that also supplies a numba kernel for the compiled per-sample loop.

    Kernel (class attribute, ``@numba.njit``):
    ``kernel_step(params, state, reference, k, measurement, command_out)``, where
    ``reference`` is the whole reference of the run, shape (n_samples + preview - 1,
    n_orders, n_axes) (``reference[k + i, d, a]``: derivative ``d`` of axis ``a``, ``i``
    samples ahead; see `ReferenceWindow.from_array`), ``k`` the current sample, and the
    state is advanced in place.
    """

    kernel_names: ClassVar[tuple[str, ...]] = ("kernel_step",)
    preview: int


class CompiledObserver(Compiled):
    """An observer that also supplies a numba kernel for the compiled per-sample loop.

    Kernel (class attribute, ``@numba.njit``):
    ``kernel_step(params, state, command, measurement, estimate_out)``, advancing the
    state in place; ``command`` is the one applied over the previous sample.
    """

    kernel_names: ClassVar[tuple[str, ...]] = ("kernel_step",)
    n_outputs: int


@njit(cache=True)
def lti_error_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Error feedback: ``e = r_k - ym``, ``u = C x + D e``, ``x <- A x + B e``."""
    nx, nu, ny, ia, ib, ic, idd = lti_dims(p)
    e0 = 2 * nx
    for j in range(nu):
        x[e0 + j] = ref[k, 0, j] - ym[j]
    for i in range(ny):
        acc = 0.0
        for j in range(nx):
            acc += p[ic + i * nx + j] * x[j]
        for j in range(nu):
            acc += p[idd + i * nu + j] * x[e0 + j]
        u[i] = acc
    for i in range(nx):
        acc = 0.0
        for j in range(nx):
            acc += p[ia + i * nx + j] * x[j]
        for j in range(nu):
            acc += p[ib + i * nu + j] * x[e0 + j]
        x[nx + i] = acc
    for i in range(nx):
        x[i] = x[nx + i]


@njit(cache=True)
def lti_observer_step(
    p: np.ndarray, x: np.ndarray, u: np.ndarray, ym: np.ndarray, est: np.ndarray
) -> None:
    """LTI observer on ``v = [u, ym]``: ``est = C x + D v``, ``x <- A x + B v``."""
    nx, nv, ne, ia, ib, ic, idd = lti_dims(p)
    v0 = 2 * nx
    nc = nv - ym.shape[0]
    for j in range(nc):
        x[v0 + j] = u[j]
    for j in range(nv - nc):
        x[v0 + nc + j] = ym[j]
    for i in range(ne):
        acc = 0.0
        for j in range(nx):
            acc += p[ic + i * nx + j] * x[j]
        for j in range(nv):
            acc += p[idd + i * nv + j] * x[v0 + j]
        est[i] = acc
    for i in range(nx):
        acc = 0.0
        for j in range(nx):
            acc += p[ia + i * nx + j] * x[j]
        for j in range(nv):
            acc += p[ib + i * nv + j] * x[v0 + j]
        x[nx + i] = acc
    for i in range(nx):
        x[i] = x[nx + i]


class LTIController(CompiledController):
    """Linear error feedback ``u = K(z) (r - y)`` from a `DiscreteLTI` model (preview 1).

    Parameters
    ----------
    sys : DiscreteLTI
        Discrete controller with one input per error channel (reference axis) and one
        output per command.
    """

    kernel_step: Any = lti_error_step

    def __init__(self, sys: DiscreteLTI) -> None:
        self.sys = sys
        self.params = pack_lti(sys.A, sys.B, sys.C, sys.D)
        self.n_inputs = sys.n_inputs
        self.n_outputs = sys.n_outputs
        self.preview = 1

    def init(self) -> np.ndarray:
        """Zero state, ``n_states`` scratch values and ``n_inputs`` for the error."""
        return np.zeros(2 * self.sys.n_states + self.sys.n_inputs)

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample of ``u = C x + D e``, ``x <- A x + B e`` with ``e = r_k - y``."""
        nx = self.sys.n_states
        e = window.position[0] - np.asarray(measurement, dtype=float)
        x = state[:nx]
        u = self.sys.C @ x + self.sys.D @ e
        new = state.copy()
        new[:nx] = self.sys.A @ x + self.sys.B @ e
        return u, new


class LTIObserver(CompiledObserver):
    """A linear observer from a `DiscreteLTI` model driven by ``[command, measurement]``.

    Parameters
    ----------
    sys : DiscreteLTI
        Inputs: the ``n_commands`` commands of the previous sample, then the measurements;
        outputs: the estimate handed to the controller (feed-through allowed).
    n_commands : int
        How many of the inputs are commands (0 for a pure measurement filter).
    """

    kernel_step: Any = lti_observer_step

    def __init__(self, sys: DiscreteLTI, n_commands: int) -> None:
        if not 0 <= n_commands <= sys.n_inputs:
            raise ValueError(
                f"n_commands must lie in [0, {sys.n_inputs}] (the model's inputs), got {n_commands}"
            )
        self.sys = sys
        self.n_commands = n_commands
        self.params = pack_lti(sys.A, sys.B, sys.C, sys.D)
        self.n_outputs = sys.n_outputs

    def init(self) -> np.ndarray:
        """Zero state, ``n_states`` scratch values and room for the input vector."""
        return np.zeros(2 * self.sys.n_states + self.sys.n_inputs)

    def step(
        self, state: np.ndarray, command: np.ndarray, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``est = C x + D v``, ``x <- A x + B v`` with ``v = [command, measurement]``."""
        nx = self.sys.n_states
        v = np.concatenate([np.asarray(command, float)[: self.n_commands], measurement])
        x = state[:nx]
        est = self.sys.C @ x + self.sys.D @ v
        new = state.copy()
        new[:nx] = self.sys.A @ x + self.sys.B @ v
        return est, new


@dataclass(frozen=True, kw_only=True)
class Delay:
    """Feedforward that delays the command by a whole number of samples.

    The first sample is held (derivatives zero) for ``samples`` samples before the
    command, so the result is ``samples`` longer.

    Parameters
    ----------
    samples : int
        Delay in samples (>= 0).
    """

    samples: int

    def __post_init__(self) -> None:
        check_int("delay", self.samples, 0, "samples")

    def apply(self, trajectory: Trajectory) -> Trajectory:
        """The delayed trajectory, ``n_samples + samples`` long."""
        d = self.samples
        if d == 0:
            return trajectory
        pos = trajectory.position
        derivs = {}
        for name in _DERIVATIVES:
            arr = getattr(trajectory, name)
            derivs[name] = None if arr is None else np.vstack([np.zeros((d, arr.shape[1])), arr])
        s = trajectory.s
        return Trajectory(
            dt=trajectory.dt,
            position=np.vstack([np.repeat(pos[:1], d, axis=0), pos]),
            s=None if s is None else np.concatenate([np.full(d, s[0]), s]),
            axes=trajectory.axes,
            at_rest=trajectory.at_rest,
            meta=dict(trajectory.meta),
            **derivs,
        )


@dataclass(frozen=True, kw_only=True, eq=False)
class Loop:
    """One closed loop's control side, as data: which parts, interpreted by `microfab.sim`.

    Order of operations. Before the run, ``feedforward`` (if any) filters the whole
    command into the loop reference ``r``. Then at each sample ``k``:

    1. the plant's output ``y_k`` is read and measured: ``m_k = y_k + noise_k``;
    2. ``observer`` (if any) turns the previous command ``u_{k-1}`` (zero at rest) and
       ``m_k`` into an estimate; without an observer the estimate is ``m_k``;
    3. ``controller`` computes ``u_k`` from the window ``r_k .. r_{k+preview-1}`` and the
       estimate;
    4. the plant advances one sample with ``u_k``.

    Parameters
    ----------
    controller : Controller
        The feedback (and preview) controller.
    feedforward : Feedforward, optional
        Command filter applied before the loop.
    observer : Observer, optional
        Estimator between the measurement and the controller.
    """

    controller: Controller
    feedforward: Feedforward | None = None
    observer: Observer | None = None

    def __post_init__(self) -> None:
        # The members of the Controller / Observer protocols, checked by hasattr as a
        # runtime_checkable isinstance does, without its per-call cost (a `Loop` is
        # built at every `simulate` call).
        if not _has(self.controller, ("preview", "init", "step")):
            raise TypeError(
                f"controller must have preview, init() and step(); got "
                f"{type(self.controller).__name__}"
            )
        p = self.controller.preview
        check_int("controller preview", p, 1, "samples")
        if self.feedforward is not None and not isinstance(self.feedforward, Feedforward):
            raise TypeError(
                f"feedforward must have apply(trajectory); got {type(self.feedforward).__name__}"
            )
        if self.observer is not None and not _has(self.observer, ("n_outputs", "init", "step")):
            raise TypeError(
                f"observer must have n_outputs, init() and step(); got "
                f"{type(self.observer).__name__}"
            )

    @property
    def preview(self) -> int:
        """The controller's preview in samples."""
        return int(self.controller.preview)


def _has(obj: object, names: tuple[str, ...]) -> bool:
    return all(hasattr(obj, n) for n in names)


def as_loop(controller: Controller | Loop) -> Loop:
    """A `Loop` as given, or a plain controller wrapped in one."""
    return controller if isinstance(controller, Loop) else Loop(controller=controller)
