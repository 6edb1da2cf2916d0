"""The one replay loop: a compiled controller run open loop over recorded measurements.

A controller is deterministic given its reference and the measurements it saw, so running
its kernel over a recorded run reproduces the commands it sent, bit for bit, and lets its
internal signals be read sample by sample. `replay_steps` is that loop, compiled once per
pair of kernels (the controller's step and an optional ``record`` kernel that copies what
a caller wants to log out of the state after each step). `microfab.sim.replay`
(`replay_controller`) and the controllers' own ``replay`` methods
(`microfab.control.rbf.RBFAdaptive.replay`,
`microfab.control.certainty.CertaintyEquivalence.replay`,
`microfab.control.preview_dob.PreviewDOB.replay`) all run it. It lives in ``control`` so
that the controllers can use it (``control`` does not import ``sim``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

__all__ = ["no_record", "replay_steps"]


@njit(cache=True)
def no_record(p: np.ndarray, x: np.ndarray, row: np.ndarray) -> None:
    """The ``record`` kernel that logs nothing."""


@functools.cache
def _replay_loop(step: Any, record: Any) -> Callable[..., None]:
    """The replay loop with ``step`` and ``record`` bound in (compiled once per pair)."""

    @njit(nogil=True)
    def loop(
        p: np.ndarray,
        x: np.ndarray,
        ref: np.ndarray,
        ym: np.ndarray,
        u: np.ndarray,
        log: np.ndarray,
    ) -> None:
        for k in range(ym.shape[0]):
            step(p, x, ref, k, ym[k], u[k])
            record(p, x, log[k])

    return loop


def replay_steps(
    step: Any,
    params: np.ndarray,
    state: np.ndarray,
    reference: np.ndarray,
    measured: np.ndarray,
    n_commands: int,
    record: Any = None,
    n_record: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Run a controller's step kernel over recorded measurements, logging after each step.

    Parameters
    ----------
    step : numba dispatcher
        The controller's kernel ``step(p, x, ref, k, ym, u)`` (`CompiledController`):
        writes the command of sample ``k`` into ``u`` and advances ``x`` in place.
    params : numpy.ndarray
        The controller's flat parameters ``p``.
    state : numpy.ndarray
        The controller's state before the first sample, float64; advanced in place (it
        holds the final state on return).
    reference : numpy.ndarray
        The reference as the kernel reads it (``ref``; e.g. shape (n, n_orders, n_axes),
        `microfab.sim.loop.reference_array`), at least as long as ``measured``.
    measured : numpy.ndarray
        What the controller saw at each sample, shape (n, n_measurements), finite.
    n_commands : int
        Commands per sample.
    record : numba dispatcher, optional
        ``record(p, x, row)``, called after each step with the state after it and that
        sample's row of the log (default `no_record`).
    n_record : int
        Length of a log row.

    Returns
    -------
    commands : numpy.ndarray
        Shape (n, n_commands), in the controller's command unit.
    log : numpy.ndarray
        What ``record`` wrote, shape (n, n_record).
    """
    ym = np.ascontiguousarray(measured, dtype=np.float64)
    n = ym.shape[0]
    u = np.empty((n, int(n_commands)))
    log = np.empty((n, int(n_record)))
    _replay_loop(step, no_record if record is None else record)(
        params, state, reference, ym, u, log
    )
    return u, log
