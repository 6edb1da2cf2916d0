"""Per-sample closed-loop simulation of any plant and controller written as state machines.

`simulate` runs the compiled numba loop (`microfab.sim.kernels.run_loop`) when both
components supply kernels, and the plain Python loop `simulate_python` otherwise. The same
code therefore serves linear twins, nonlinear stages and adaptive controllers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from microfab.sim.components import Controller, Plant
from microfab.sim.kernels import run_loop
from microfab.sim.result import SimResult

__all__ = ["has_kernels", "simulate", "simulate_python"]


def has_kernels(plant: Any, controller: Any) -> bool:
    """True when both components can run in the compiled loop."""
    return all(
        hasattr(obj, name)
        for obj, name in (
            (plant, "kernel_output"),
            (plant, "kernel_update"),
            (plant, "params"),
            (controller, "kernel_step"),
            (controller, "params"),
        )
    )


def _prepare(
    plant: Plant, reference: np.ndarray, noise: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    ref = np.ascontiguousarray(np.asarray(reference, dtype=float))
    if ref.ndim == 1:
        ref = ref[:, None]
    if ref.ndim != 2 or ref.shape[0] == 0:
        raise ValueError(f"reference must be shaped (n_samples, n_axes), got {ref.shape}")
    if not np.all(np.isfinite(ref)):
        raise ValueError("reference holds NaN or inf")
    ny = plant.n_outputs
    if noise is None:
        nz = np.zeros((ref.shape[0], ny))
    else:
        nz = np.ascontiguousarray(np.asarray(noise, dtype=float).reshape(ref.shape[0], -1))
        if nz.shape != (ref.shape[0], ny):
            raise ValueError(f"noise must be shaped {(ref.shape[0], ny)}, got {nz.shape}")
    return ref, nz


def simulate(
    plant: Plant,
    controller: Controller,
    reference: np.ndarray,
    noise: np.ndarray | None = None,
    state: tuple[np.ndarray, np.ndarray] | None = None,
    axes: tuple[str, ...] = (),
) -> SimResult:
    """Simulate the sampled feedback loop, one sample at a time.

    Parameters
    ----------
    plant : Plant
        Plant state machine with ``n_outputs`` measured outputs.
    controller : Controller
        Controller state machine mapping (reference, measurement) to plant commands.
    reference : numpy.ndarray
        Loop reference, shape (n_samples, n_axes), in the measurement's unit.
    noise : numpy.ndarray, optional
        Measurement noise added to the plant output, shape (n_samples, n_outputs).
    state : tuple of numpy.ndarray, optional
        ``(plant_state, controller_state)`` to continue from; ``None`` starts at rest.
    axes : tuple of str
        Axis names for the result.

    Returns
    -------
    SimResult
        Signals and the final state (``final_state``) to continue from.
    """
    ref, nz = _prepare(plant, reference, noise)
    if not has_kernels(plant, controller):
        return simulate_python(plant, controller, ref, nz, state, axes)
    px, cx = (
        (plant.init(), controller.init())
        if state is None
        else (
            state[0].copy(),
            state[1].copy(),
        )
    )
    n = ref.shape[0]
    y = np.empty((n, plant.n_outputs))
    ym = np.empty_like(y)
    u = np.empty((n, plant.n_inputs))
    run_loop(
        plant.kernel_output,  # type: ignore[attr-defined]
        plant.kernel_update,  # type: ignore[attr-defined]
        plant.params,  # type: ignore[attr-defined]
        px,
        controller.kernel_step,  # type: ignore[attr-defined]
        controller.params,  # type: ignore[attr-defined]
        cx,
        ref,
        nz,
        y,
        ym,
        u,
    )
    return SimResult(
        dt=plant.dt,
        reference=ref,
        output=y,
        measured=ym,
        command=u,
        axes=axes,
        final_state=(px, cx),
    )


def simulate_python(
    plant: Plant,
    controller: Controller,
    reference: np.ndarray,
    noise: np.ndarray | None = None,
    state: tuple[np.ndarray, np.ndarray] | None = None,
    axes: tuple[str, ...] = (),
) -> SimResult:
    """The same loop as `simulate` in plain Python (reference implementation, slow)."""
    ref, nz = _prepare(plant, reference, noise)
    px, cx = (plant.init(), controller.init()) if state is None else state
    n = ref.shape[0]
    y = np.empty((n, plant.n_outputs))
    ym = np.empty_like(y)
    u = np.empty((n, plant.n_inputs))
    for k in range(n):
        yk = plant.output(px)
        ymk = yk + nz[k]
        uk, cx = controller.step(cx, ref[k], ymk)
        px = plant.update(px, uk)
        y[k], ym[k], u[k] = yk, ymk, uk
    return SimResult(
        dt=plant.dt,
        reference=ref,
        output=y,
        measured=ym,
        command=u,
        axes=axes,
        final_state=(px, cx),
    )
