"""State-machine components for the closed-loop simulators.

A **plant** has ``init() -> state``, ``output(state) -> y`` and ``update(state, u) -> state``.
A **controller** has ``init() -> state`` and
``step(state, reference, measurement) -> (command, state)``.
Components that also carry ``params`` (a flat float array) and numba kernels
(``kernel_output``/``kernel_update`` for plants, ``kernel_step`` for controllers, see
`microfab.sim.kernels`) run in the compiled per-sample loop; any other component runs in
the Python loop, more slowly but with the same results.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from microfab.plants.lti import DiscreteLTI
from microfab.sim.kernels import lti_error_step, lti_output, lti_update, pack_lti

__all__ = ["Controller", "LTIController", "LTIPlant", "Plant"]


@runtime_checkable
class Plant(Protocol):
    """A discrete-time plant as an explicit state machine (strictly proper)."""

    n_inputs: int
    n_outputs: int
    dt: float

    def init(self) -> np.ndarray:
        """Initial state."""
        ...

    def output(self, state: np.ndarray) -> np.ndarray:
        """Output at the current state, shape (n_outputs,)."""
        ...

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """Next state after applying ``command`` (shape (n_inputs,)) for one sample."""
        ...


@runtime_checkable
class Controller(Protocol):
    """A discrete-time controller as an explicit state machine."""

    def init(self) -> np.ndarray:
        """Initial state."""
        ...

    def step(
        self, state: np.ndarray, reference: np.ndarray, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample: return ``(command, next_state)``."""
        ...


class LTIPlant:
    """A linear plant from a `DiscreteLTI` model (``D`` must be zero).

    Parameters
    ----------
    sys : DiscreteLTI
        The discrete model; inputs are commands, outputs are measured positions.
    """

    kernel_output: Any = lti_output
    kernel_update: Any = lti_update

    def __init__(self, sys: DiscreteLTI) -> None:
        if np.any(sys.D != 0):
            raise ValueError(
                "LTIPlant needs a strictly proper model (D = 0) to avoid an algebraic loop"
            )
        self.sys = sys
        self.params = pack_lti(sys.A, sys.B, sys.C, sys.D)
        self.n_inputs = sys.n_inputs
        self.n_outputs = sys.n_outputs
        self.dt = sys.dt

    def init(self) -> np.ndarray:
        """Zero state (with kernel scratch space)."""
        return np.zeros(2 * self.sys.n_states)

    def output(self, state: np.ndarray) -> np.ndarray:
        """``y = C x``."""
        return self.sys.C @ state[: self.sys.n_states]

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """``x <- A x + B u``."""
        nx = self.sys.n_states
        new = state.copy()
        new[:nx] = self.sys.A @ state[:nx] + self.sys.B @ np.asarray(command, dtype=float)
        return new


class LTIController:
    """A linear error-feedback controller ``u = K(z) (r - y)`` from a `DiscreteLTI` model.

    Parameters
    ----------
    sys : DiscreteLTI
        Discrete controller with one input per error channel and one output per command.
    """

    kernel_step: Any = lti_error_step

    def __init__(self, sys: DiscreteLTI) -> None:
        self.sys = sys
        self.params = pack_lti(sys.A, sys.B, sys.C, sys.D)
        self.n_inputs = sys.n_inputs
        self.n_outputs = sys.n_outputs

    def init(self) -> np.ndarray:
        """Zero state (with kernel scratch space)."""
        return np.zeros(2 * self.sys.n_states + self.sys.n_inputs)

    def step(
        self, state: np.ndarray, reference: np.ndarray, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample of ``u = C x + D e``, ``x <- A x + B e`` with ``e = r - y``."""
        nx = self.sys.n_states
        e = np.asarray(reference, dtype=float) - np.asarray(measurement, dtype=float)
        x = state[:nx]
        u = self.sys.C @ x + self.sys.D @ e
        new = state.copy()
        new[:nx] = self.sys.A @ x + self.sys.B @ e
        return u, new
