"""Numba kernels for the per-sample closed-loop simulator.

Every component of a per-sample loop is an explicit state machine whose state is a flat
``float64`` array and whose parameters are a flat ``float64`` array, so that one compiled
loop (`microfab.sim.loop`) runs any combination of plants and controllers. A plant supplies
``output(params, state, y_out)`` and ``update(params, state, u)``; a controller supplies
``step(params, state, reference, measurement, u_out)``. All kernels work in place and
allocate nothing.

Packed LTI layout: ``[nx, nu, ny, A.ravel(), B.ravel(), C.ravel(), D.ravel()]``; the state
array of an LTI component holds ``x`` followed by ``nx`` scratch values (and, for the
error-feedback controller, ``nu`` more for the error).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["lti_error_step", "lti_output", "lti_update", "pack_lti", "run_loop"]


def pack_lti(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Pack state-space matrices into the flat parameter layout of the LTI kernels."""
    nx, nu = B.shape
    ny = C.shape[0]
    return np.concatenate(
        [np.array([nx, nu, ny], dtype=float), A.ravel(), B.ravel(), C.ravel(), D.ravel()]
    )


@njit(cache=True, inline="always")
def _dims(p: np.ndarray) -> tuple[int, int, int, int, int, int, int]:
    nx = int(p[0])
    nu = int(p[1])
    ny = int(p[2])
    ia = 3
    ib = ia + nx * nx
    ic = ib + nx * nu
    idd = ic + ny * nx
    return nx, nu, ny, ia, ib, ic, idd


@njit(cache=True)
def lti_output(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """Write ``y = C x`` (plants must be strictly proper: no feed-through)."""
    nx, _nu, ny, _ia, _ib, ic, _id = _dims(p)
    for i in range(ny):
        acc = 0.0
        for j in range(nx):
            acc += p[ic + i * nx + j] * x[j]
        y[i] = acc


@njit(cache=True)
def lti_update(p: np.ndarray, x: np.ndarray, u: np.ndarray) -> None:
    """Advance ``x <- A x + B u`` in place (uses ``x[nx:2nx]`` as scratch)."""
    nx, nu, _ny, ia, ib, _ic, _id = _dims(p)
    for i in range(nx):
        acc = 0.0
        for j in range(nx):
            acc += p[ia + i * nx + j] * x[j]
        for j in range(nu):
            acc += p[ib + i * nu + j] * u[j]
        x[nx + i] = acc
    for i in range(nx):
        x[i] = x[nx + i]


@njit(cache=True)
def lti_error_step(
    p: np.ndarray, x: np.ndarray, r: np.ndarray, ym: np.ndarray, u: np.ndarray
) -> None:
    """Error-feedback LTI controller: ``e = r - ym``, ``u = C x + D e``, ``x <- A x + B e``."""
    nx, nu, ny, ia, ib, ic, idd = _dims(p)
    e0 = 2 * nx
    for j in range(nu):
        x[e0 + j] = r[j] - ym[j]
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


@njit
def run_loop(
    plant_output,
    plant_update,
    pp: np.ndarray,
    px: np.ndarray,
    ctrl_step,
    cp: np.ndarray,
    cx: np.ndarray,
    ref: np.ndarray,
    noise: np.ndarray,
    y: np.ndarray,
    ym: np.ndarray,
    u: np.ndarray,
) -> None:
    """Run the closed loop sample by sample; outputs are written into ``y, ym, u``.

    At sample ``k``: the plant's output is read, encoder noise is added, the controller
    computes the command from the reference and the noisy measurement, and the plant is
    advanced one step with that command.
    """
    n = ref.shape[0]
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
        ctrl_step(cp, cx, ref[k], ymk, uk)
        for i in range(nu):
            u[k, i] = uk[i]
        plant_update(pp, px, uk)
