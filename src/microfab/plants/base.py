"""Plants as explicit state machines: the `Plant` protocol, `CompiledPlant`, `LTIPlant`.

A plant is discrete in time (sample time ``dt`` in s) and strictly proper: its output at
sample ``k`` depends on its state only, and the command of sample ``k`` moves the state to
sample ``k + 1``. Any object with the attributes and methods of `Plant` runs in the Python
loop of `microfab.sim.loop`; a plant that also derives from `CompiledPlant` (and so from
`microfab.core.compiled.Compiled`) runs in the compiled numba loop too. `LTIPlant` is both,
and the simulators recognise it as linear (the lifted path of `microfab.sim.lti_fast`).
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numba import njit

from microfab.core.compiled import Compiled, lti_dims, pack_lti
from microfab.core.validate import check_int
from microfab.plants.lti import DiscreteLTI

__all__ = ["CompiledPlant", "LTIPlant", "Plant", "lti_output", "lti_update", "white_noise"]


@runtime_checkable
class Plant(Protocol):
    """A discrete-time, strictly proper plant as an explicit state machine.

    Attributes
    ----------
    n_inputs : int
        Number of commands (actuator channels).
    n_outputs : int
        Number of measured outputs.
    dt : float
        Sample time, s.

    Notes
    -----
    ``update`` returns a new state and must not modify the one it is given (the simulator
    may keep it to continue from). The state is any object for a Python plant; for a
    `CompiledPlant` it is a flat ``float64`` array.
    """

    n_inputs: int
    n_outputs: int
    dt: float

    def init(self) -> Any:
        """The state at rest."""
        ...

    def output(self, state: Any) -> np.ndarray:
        """Output at ``state``, shape (n_outputs,), in the measurement's unit."""
        ...

    def update(self, state: Any, command: np.ndarray) -> Any:
        """State one sample later, ``command`` (shape (n_inputs,)) held over the sample."""
        ...


class CompiledPlant(Compiled):
    """A plant that also supplies numba kernels for the compiled per-sample loop.

    Kernels (class attributes, ``@numba.njit``; ``params`` and ``state`` are flat
    ``float64`` arrays, the state as returned by ``init``):

    * ``kernel_output(params, state, y_out)``: write the output, shape (n_outputs,);
    * ``kernel_update(params, state, command)``: advance ``state`` one sample in place.
    """

    kernel_names: ClassVar[tuple[str, ...]] = ("kernel_output", "kernel_update")
    n_inputs: int
    n_outputs: int
    dt: float


@njit(cache=True)
def lti_output(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """Write ``y = C x`` (plants are strictly proper: no feed-through)."""
    nx, _nu, ny, _ia, _ib, ic, _id = lti_dims(p)
    for i in range(ny):
        acc = 0.0
        for j in range(nx):
            acc += p[ic + i * nx + j] * x[j]
        y[i] = acc


@njit(cache=True)
def lti_update(p: np.ndarray, x: np.ndarray, u: np.ndarray) -> None:
    """Advance ``x <- A x + B u`` in place (uses ``x[nx:2nx]`` as scratch)."""
    nx, nu, _ny, ia, ib, _ic, _id = lti_dims(p)
    for i in range(nx):
        acc = 0.0
        for j in range(nx):
            acc += p[ia + i * nx + j] * x[j]
        for j in range(nu):
            acc += p[ib + i * nu + j] * u[j]
        x[nx + i] = acc
    for i in range(nx):
        x[i] = x[nx + i]


class LTIPlant(CompiledPlant):
    """A linear plant from a `DiscreteLTI` model (``D`` must be zero).

    Parameters
    ----------
    sys : DiscreteLTI
        The discrete model; inputs are commands, outputs are measured positions.

    Raises
    ------
    ValueError
        When ``sys`` has feed-through (``D != 0``): the loop would be algebraic.
    """

    kernel_output: Any = lti_output
    kernel_update: Any = lti_update

    def __init__(self, sys: DiscreteLTI) -> None:
        if np.any(sys.D != 0):
            raise ValueError(
                "LTIPlant needs a strictly proper model (D = 0) to avoid an algebraic loop, "
                f"got max |D| = {np.max(np.abs(sys.D)):.3g}"
            )
        self.sys = sys
        self.params = pack_lti(sys.A, sys.B, sys.C, sys.D)
        self.n_inputs = sys.n_inputs
        self.n_outputs = sys.n_outputs
        self.dt = sys.dt

    def init(self) -> np.ndarray:
        """Zero state followed by ``n_states`` kernel scratch values, shape (2 n_states,)."""
        return np.zeros(2 * self.sys.n_states)

    def output(self, state: np.ndarray) -> np.ndarray:
        """``y = C x``, shape (n_outputs,)."""
        return self.sys.C @ state[: self.sys.n_states]

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """``x <- A x + B u`` (a new array; ``state`` is left as it was)."""
        nx = self.sys.n_states
        new = state.copy()
        new[:nx] = self.sys.A @ state[:nx] + self.sys.B @ np.asarray(command, dtype=float)
        return new


def white_noise(n_samples: int, seed: int, rms: float, n_outputs: int = 2) -> np.ndarray:
    """Seeded white Gaussian measurement noise, shape (n_samples, n_outputs).

    The twins draw their output noise here, outside the kernels, so that a run is
    reproduced from its seed whatever simulator plays it.

    Parameters
    ----------
    n_samples : int
        Number of samples (>= 0).
    seed : int
        Seed of ``numpy.random.default_rng`` (>= 0); the same seed gives the same noise.
    rms : float
        Standard deviation, in the output's unit.
    n_outputs : int
        Columns (default 2, an XY machine).
    """
    n = check_int("n_samples", n_samples, 0, "samples")
    rng = np.random.default_rng(check_int("seed", seed, 0))
    return rng.standard_normal((n, n_outputs)) * rms
