"""Run one compiled component of a loop over a recorded signal (open loop).

A controller is deterministic given its reference and the measurements it saw, so running
it over a measured trace reproduces the commands it sent (`replay_controller`): a check
that the controller on a real-time target is the one simulated here (its recorded
current against ours), and a way to read its internal signals on hardware data. A plant
is deterministic given its commands, so running it over the commands of a run gives its
state after every sample (`replay_plant`: true positions, forces, disturbances that the
simulator does not return). Each kernel runs in a numba loop compiled once per kernel
(as `microfab.sim.kernels`); the controller's is `microfab.control.replay.replay_steps`,
the loop the controllers' own ``replay`` methods run too.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController
from microfab.control.replay import replay_steps
from microfab.plants.base import CompiledPlant
from microfab.sim.loop import reference_array

__all__ = ["replay_controller", "replay_plant"]


def replay_controller(
    controller: CompiledController,
    position: np.ndarray,
    measured: np.ndarray,
    derivatives: Sequence[np.ndarray] = (),
    state: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Commands a compiled controller sends for recorded measurements.

    Parameters
    ----------
    controller : CompiledController
        The controller (its ``n_outputs`` commands per sample).
    position : numpy.ndarray
        Reference positions, shape (n, n_axes).
    measured : numpy.ndarray
        What the controller saw at each sample, shape (n, n_measurements).
    derivatives : sequence of numpy.ndarray
        Reference velocity, acceleration (a prefix), each (n, n_axes).
    state : numpy.ndarray, optional
        Starting state (default ``controller.init()``).

    Returns
    -------
    tuple of numpy.ndarray
        ``(commands (n, n_outputs), final state)``.

    Raises
    ------
    ValueError
        On shapes that do not match or values that are not finite.
    """
    if not isinstance(controller, CompiledController):
        raise TypeError(
            f"replay_controller needs a compiled controller, got {type(controller).__name__}"
        )
    ym = np.ascontiguousarray(measured, dtype=np.float64)
    if ym.ndim != 2 or not np.isfinite(ym).all():
        raise ValueError(f"measured must be finite and shaped (n, n_measurements), got {ym.shape}")
    R = reference_array(position, derivatives, controller.preview)
    if R.shape[0] - controller.preview + 1 != ym.shape[0]:
        raise ValueError(
            f"the reference has {R.shape[0] - controller.preview + 1} samples, the "
            f"measurements {ym.shape[0]}; give one reference sample per measurement"
        )
    x = controller.init() if state is None else np.array(state, dtype=np.float64)
    n_out = int(getattr(controller, "n_outputs", getattr(controller, "n_inputs", 1)))
    (step,) = controller.kernels()
    u, _log = replay_steps(step, controller.packed_params(), x, R, ym, n_out)
    return u, x


@functools.cache
def _plant_loop(update: Any) -> Callable[..., None]:
    """The plant replay loop with ``update`` bound in (compiled once per kernel)."""

    @njit(nogil=True)
    def loop(p: np.ndarray, s: np.ndarray, u: np.ndarray, out: np.ndarray) -> None:
        for k in range(u.shape[0]):
            update(p, s, u[k])
            for i in range(s.shape[0]):
                out[k, i] = s[i]

    return loop


def replay_plant(
    plant: CompiledPlant, commands: np.ndarray, state: np.ndarray | None = None
) -> np.ndarray:
    """The state of a compiled plant after each of the given commands.

    Parameters
    ----------
    plant : CompiledPlant
        The plant.
    commands : numpy.ndarray
        Commands held over each sample, shape (n, n_inputs).
    state : numpy.ndarray, optional
        State before the first sample (default ``plant.init()``); not modified.

    Returns
    -------
    numpy.ndarray
        States after samples 0 .. n - 1, shape (n, n_states).
    """
    if not isinstance(plant, CompiledPlant):
        raise TypeError(f"replay_plant needs a compiled plant, got {type(plant).__name__}")
    u = np.ascontiguousarray(commands, dtype=np.float64)
    if u.ndim != 2 or u.shape[1] != plant.n_inputs or not np.isfinite(u).all():
        raise ValueError(f"commands must be finite and shaped (n, {plant.n_inputs}), got {u.shape}")
    s = np.array(plant.init() if state is None else state, dtype=np.float64)
    out = np.empty((u.shape[0], s.shape[0]))
    _out_k, update = plant.kernels()
    _plant_loop(update)(plant.packed_params(), s, u, out)
    return out
