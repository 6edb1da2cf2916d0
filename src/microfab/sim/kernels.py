"""The compiled per-sample closed loop (numba).

Every component of the loop is an explicit state machine whose state and parameters are
flat ``float64`` arrays and whose kernels (`microfab.core.compiled.Compiled`) work in place
and allocate nothing, so one compiled loop runs any combination of plant, controller and
observer:

* plant: ``output(params, state, y_out)``, ``update(params, state, command)``
  (`microfab.plants.base.CompiledPlant`);
* controller: ``step(params, state, reference, k, measurement, command_out)``
  (`microfab.control.base.CompiledController`), where ``reference`` has shape
  (n_samples + preview - 1, n_orders, n_axes) so that a preview controller reads the
  samples ahead of ``k``;
* observer: ``step(params, state, command, measurement, estimate_out)``
  (`microfab.control.base.CompiledObserver`); `passthrough_step` stands in when the loop
  has none.

The LTI kernels live beside their components (`microfab.plants.base.lti_output`,
`microfab.control.base.lti_error_step`, ...).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

__all__ = ["compiled_loop", "passthrough_step", "run_loop"]


@njit(cache=True)
def passthrough_step(
    p: np.ndarray, x: np.ndarray, u: np.ndarray, ym: np.ndarray, est: np.ndarray
) -> None:
    """Observer kernel of a loop without observer: the estimate is the measurement."""
    for i in range(ym.shape[0]):
        est[i] = ym[i]


@functools.cache
def compiled_loop(
    plant_output: Any, plant_update: Any, ctrl_step: Any, obs_step: Any
) -> Callable[..., None]:
    """The closed loop compiled for one combination of kernels (kept per combination).

    The kernels are bound into the compiled loop as constants rather than passed as
    arguments: each call then skips numba's typing of four function objects (some 80 µs,
    a third of a 2500-sample period), and the kernels' code is compiled into the loop's.

    Parameters
    ----------
    plant_output, plant_update : numba dispatcher
        The plant's kernels (`microfab.plants.base.CompiledPlant`).
    ctrl_step : numba dispatcher
        The controller's kernel (`microfab.control.base.CompiledController`).
    obs_step : numba dispatcher
        The observer's kernel, or `passthrough_step`.

    Returns
    -------
    callable
        ``loop(pp, px, cp, cx, op, ox, ref, noise, u_prev, est, y, ym, u)``, working in
        place as described in `run_loop`.
    """

    @njit(nogil=True)  # other threads (checkpoint writers) run meanwhile
    def loop(
        pp: np.ndarray,
        px: np.ndarray,
        cp: np.ndarray,
        cx: np.ndarray,
        op: np.ndarray,
        ox: np.ndarray,
        ref: np.ndarray,
        noise: np.ndarray,
        u_prev: np.ndarray,
        est: np.ndarray,
        y: np.ndarray,
        ym: np.ndarray,
        u: np.ndarray,
    ) -> None:
        n = noise.shape[0]
        ny = y.shape[1]
        nu = u.shape[1]
        yk = np.empty(ny)
        ymk = np.empty(ny)
        uk = np.empty(nu)
        for k in range(n):
            plant_output(pp, px, yk)
            for i in range(ny):
                ymk[i] = yk[i] + noise[k, i]
                y[k, i] = yk[i]
                ym[k, i] = ymk[i]
            obs_step(op, ox, u_prev, ymk, est)
            ctrl_step(cp, cx, ref, k, est, uk)
            for i in range(nu):
                u[k, i] = uk[i]
                u_prev[i] = uk[i]
            plant_update(pp, px, uk)

    return loop


def run_loop(
    plant_output: Any,
    plant_update: Any,
    pp: np.ndarray,
    px: np.ndarray,
    ctrl_step: Any,
    cp: np.ndarray,
    cx: np.ndarray,
    obs_step: Any,
    op: np.ndarray,
    ox: np.ndarray,
    ref: np.ndarray,
    noise: np.ndarray,
    u_prev: np.ndarray,
    est: np.ndarray,
    y: np.ndarray,
    ym: np.ndarray,
    u: np.ndarray,
) -> None:
    """Run the closed loop for ``noise.shape[0]`` samples, in place.

    At sample ``k``: the plant's output is read and encoder noise added; the observer
    turns the previous command (``u_prev``) and the measurement into the estimate
    (``est``); the controller computes the command from ``ref`` around ``k`` and the
    estimate; the plant advances one step with that command. States (``px, cx, ox``) and
    ``u_prev`` are left at their values after the last sample; the signals are written
    into ``y, ym`` (n_samples, n_outputs) and ``u`` (n_samples, n_inputs).

    The loop itself is `compiled_loop` of the four kernels.
    """
    compiled_loop(plant_output, plant_update, ctrl_step, obs_step)(
        pp, px, cp, cx, op, ox, ref, noise, u_prev, est, y, ym, u
    )
