"""Plants as explicit state machines: the `Plant` protocol, `CompiledPlant`, `LTIPlant`.

The twins' measurement noise is here too: `NoiseLevel` (rms per output and its unit),
`NoisyOutputs` (a twin's ``noise_level`` and its seeded ``noise``) and `white_noise`.

A plant is discrete in time (sample time ``dt`` in s) and strictly proper: its output at
sample ``k`` depends on its state only, and the command of sample ``k`` moves the state to
sample ``k + 1``. Any object with the attributes and methods of `Plant` runs in the Python
loop of `microfab.sim.loop`; a plant that also derives from `CompiledPlant` (and so from
`microfab.core.compiled.Compiled`) runs in the compiled numba loop too. `LTIPlant` is both,
and the simulators recognise it as linear (the lifted path of `microfab.sim.lti_fast`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from numba import njit

from microfab.core.compiled import Compiled, lti_dims, pack_lti
from microfab.core.signals import check_unit
from microfab.core.validate import check_int, check_nonnegative
from microfab.plants.lti import DiscreteLTI

__all__ = [
    "CompiledPlant",
    "LTIPlant",
    "NoiseLevel",
    "NoisyOutputs",
    "Plant",
    "lti_output",
    "lti_update",
    "white_noise",
]


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


def white_noise(
    n_samples: int, seed: int, rms: float | np.ndarray, n_outputs: int = 2
) -> np.ndarray:
    """Seeded white Gaussian measurement noise, shape (n_samples, n_outputs).

    The twins draw their output noise here, outside the kernels, so that a run is
    reproduced from its seed whatever simulator plays it:
    ``default_rng(seed).standard_normal((n_samples, n_outputs)) * rms``.

    Parameters
    ----------
    n_samples : int
        Number of samples (>= 0).
    seed : int
        Seed of ``numpy.random.default_rng`` (>= 0); the same seed gives the same noise.
    rms : float or numpy.ndarray
        Standard deviation, in the output's unit: one for all columns or one per column,
        shape (n_outputs,).
    n_outputs : int
        Columns (default 2, an XY machine).
    """
    n = check_int("n_samples", n_samples, 0, "samples")
    rng = np.random.default_rng(check_int("seed", seed, 0))
    return rng.standard_normal((n, n_outputs)) * rms


@dataclass(frozen=True)
class NoiseLevel:
    """White Gaussian measurement noise of a twin's outputs: its rms and unit per output.

    The one spelling of a twin's noise level (`NoisyOutputs.noise_level`); the twins' data
    files keep their own keys (``noise_rms_m``, ``noise_rms_bit``, ``noise_rms_mm``, ...).

    Parameters
    ----------
    rms : tuple of float
        Standard deviation per output, in its unit (>= 0), shape (n_outputs,).
    unit : str or tuple of str
        The outputs' unit (e.g. ``"m"``), or one per output (e.g. ``("V", "m")``).

    Raises
    ------
    ValueError
        On an empty, negative or non-finite rms, or units that are not single-line
        strings, one or one per output.
    """

    rms: tuple[float, ...]
    unit: str | tuple[str, ...]

    def __post_init__(self) -> None:
        if isinstance(self.rms, (str, bytes)) or not hasattr(self.rms, "__len__"):
            raise ValueError(f"rms needs one value per output, got {self.rms!r}")
        units = (self.unit,) * len(self.rms) if isinstance(self.unit, str) else self.unit
        if len(self.rms) == 0 or len(units) != len(self.rms):
            raise ValueError(
                f"rms needs one value per output and unit one string or one per output, got "
                f"rms {self.rms!r}, unit {self.unit!r}"
            )
        rms = tuple(
            check_nonnegative(f"noise rms[{i}]", r, check_unit(u))
            for i, (r, u) in enumerate(zip(self.rms, units, strict=True))
        )
        object.__setattr__(self, "rms", rms)
        if not isinstance(self.unit, str):
            object.__setattr__(self, "unit", tuple(units))

    @property
    def n_outputs(self) -> int:
        """Number of outputs."""
        return len(self.rms)

    @property
    def units(self) -> tuple[str, ...]:
        """The unit of each output, shape (n_outputs,)."""
        return (self.unit,) * self.n_outputs if isinstance(self.unit, str) else self.unit

    def array(self) -> np.ndarray:
        """The rms per output as an array, in their units, shape (n_outputs,)."""
        return np.array(self.rms, dtype=np.float64)

    def draw(self, n_samples: int, seed: int = 0) -> np.ndarray:
        """Seeded noise (`white_noise`), in the outputs' units, shape (n_samples, n_outputs)."""
        return white_noise(n_samples, seed, self.array(), self.n_outputs)


class NoisyOutputs:
    """A twin whose simulators add seeded white noise to its outputs (not the plant).

    A subclass defines ``noise_level`` (a `NoiseLevel`, an attribute or a property);
    ``noise`` draws it.
    """

    noise_level: NoiseLevel

    def noise(self, n_samples: int, seed: int = 0) -> np.ndarray:
        """Seeded white Gaussian output noise in the outputs' units, (n_samples, n_outputs).

        ``noise_level.draw(n_samples, seed)``: `white_noise` with the rms of each output
        (the same seed gives the same noise).
        """
        return self.noise_level.draw(n_samples, seed)
