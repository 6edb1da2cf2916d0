"""Stage 1's hard constraints (seed 002 eqs. 12b-12j) measured on the answer it returns.

IPOPT's ``Solve_Succeeded`` says that it stopped within its tolerances on the scaled
problem; `stage1_feasibility` checks the unscaled answer (`microfab.optimize.feasibility`):
the linear model (eq. 6) is stepped again by the same RK4 sub-steps (eq. 9) with the
returned input ``ρ_k`` and knot times ``t_k``, from rest at ``ρ_rest``, and the rows of
eq. (12) are measured on that output ``γ̂_k`` in physical units:

* dynamics (12b-12c): ``|γ̂_k - γ_k|`` (µm), the returned output against the model's;
* along-track (12g): ``|t_kᵀ(γ̂_k - Ξ_k)|`` (µm) against 0, and tolerance (12h):
  ``|n_kᵀ(γ̂_k - Ξ_k)|`` (µm) against μ, ``t_k``, ``n_k`` the path's unit tangent and
  normal at ``s_k`` (`microfab.optimize.stage1`: ν eliminated);
* workspace (12e): the signed distance outside it (µm) against 0;
* velocity (12i): ``|γ̂_{k+1} - γ̂_k| / Δτ_k`` per axis (m/s) against ``v_max``;
* acceleration (12j): the second difference on unequal steps
  ``2[(γ̂_{k+1}-γ̂_k)/Δτ_k - (γ̂_k-γ̂_{k-1})/Δτ_{k-1}] / (Δτ_{k-1}+Δτ_k)`` per axis, and the
  first step from rest ``|γ̂_1 - γ̂_0| / Δτ_0²`` (m/s²), against ``a_max``.

A row's sample is the knot ``k`` of its newest point; its time ``t_k``.
"""

from __future__ import annotations

import numpy as np

from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.feasibility import Feasibility, measure
from microfab.optimize.linear_steps import rk4_matrices
from microfab.optimize.problem import ContourProblem

__all__ = ["simulate_knots", "stage1_feasibility"]

_UM = 1e6  # µm per m


def simulate_knots(
    model: ContinuousModel, t: np.ndarray, rho: np.ndarray, rho_rest: np.ndarray, substeps: int
) -> np.ndarray:
    """Eq. (9) again: the model's output at the knots for the input held over each step.

    Parameters
    ----------
    model : ContinuousModel
        Eq. (6), inputs and outputs in m.
    t : numpy.ndarray
        Knot times, shape (N,), s.
    rho : numpy.ndarray
        Input held over step ``k``, shape (N, 2), m.
    rho_rest : numpy.ndarray
        The input the model rests on before ``t_0``, shape (2,), m.
    substeps : int
        RK4 sub-steps per step (`microfab.optimize.linear_steps.rk4_matrices`).

    Returns
    -------
    numpy.ndarray
        ``γ̂_k = C z_k + D ρ_k``, shape (N, 2), m, ``z_0`` the equilibrium of ``ρ_rest``.
    """
    a, b, c, d = (np.asarray(m, dtype=float) for m in (model.a, model.b, model.c, model.d))
    z = -np.linalg.solve(a, b @ np.asarray(rho_rest, dtype=float))
    out = np.empty((len(t), c.shape[0]))
    out[0] = c @ z + d @ rho[0]
    for k, h in enumerate(np.diff(t)):
        ph, ga = rk4_matrices(a, b, float(h), substeps)
        z = ph @ z + ga @ rho[k]
        out[k + 1] = c @ z + d @ rho[k + 1]
    return out


def stage1_feasibility(
    problem: ContourProblem,
    model: ContinuousModel,
    *,
    t: np.ndarray,
    s: np.ndarray,
    rho: np.ndarray,
    gamma: np.ndarray,
    rho_rest: np.ndarray,
    substeps: int,
) -> Feasibility:
    """Eqs. 12b-12j measured on stage 1's answer (module docstring).

    Parameters
    ----------
    problem : ContourProblem
        μ, ``v_max``, ``a_max``, the workspace and the path.
    model : ContinuousModel
        The linear model stage 1 ran on, m.
    t, s : numpy.ndarray
        Knot times (s) and path progress (m), shape (N,).
    rho, gamma : numpy.ndarray
        The returned input and output, shape (N, 2), m.
    rho_rest : numpy.ndarray
        The resting input before ``t_0``, (2,), m.
    substeps : int
        RK4 sub-steps per step.

    Returns
    -------
    Feasibility
    """
    t = np.asarray(t, dtype=float)
    g = simulate_knots(model, t, np.asarray(rho, dtype=float), rho_rest, substeps)
    n = len(t)
    k = np.arange(n)
    mu = problem.tolerance_m * _UM
    xi = problem.path.point(np.asarray(s, dtype=float))
    tan = problem.path.tangent(np.asarray(s, dtype=float))
    tan = tan / np.linalg.norm(tan, axis=1, keepdims=True)
    nor = np.column_stack([-tan[:, 1], tan[:, 0]])
    err = (g - xi) * _UM
    ws = np.asarray(problem.limits.workspace, dtype=float)  # (2, 2): per axis (low, high)
    outside = np.maximum(ws[:, 0] - g, g - ws[:, 1]) * _UM  # (N, 2)
    dt = np.diff(t)
    vel = np.abs(np.diff(g, axis=0)) / dt[:, None]  # (N-1, 2), rows k = 1 … N-1
    v = np.diff(g, axis=0) / dt[:, None]
    acc = np.abs(2 * (v[1:] - v[:-1]) / (dt[1:] + dt[:-1])[:, None])  # rows k = 2 … N-1
    acc0 = np.abs(g[1] - g[0]) / dt[0] ** 2  # the first step from rest, k = 1
    acc = np.vstack([acc0[None, :], acc])  # rows k = 1 … N-1

    def per_axis(rows: np.ndarray, k0: int) -> dict[str, np.ndarray]:
        idx = np.arange(k0, k0 + rows.shape[0])
        kk = np.concatenate([idx, idx])
        return {"values": rows.T.ravel(), "samples": kk, "times": t[kk],
                "axes": np.repeat(np.array(["x", "y"]), rows.shape[0])}  # fmt: skip

    return Feasibility((
        measure("dynamics", "12b-12c", "µm", np.linalg.norm(g - gamma, axis=1) * _UM, 0.0,
                samples=k, times=t, scale=mu),
        measure("along-track", "12g", "µm", np.abs(np.sum(err * tan, axis=1)), 0.0, samples=k,
                times=t, scale=mu),
        measure("tolerance", "12h", "µm", np.abs(np.sum(err * nor, axis=1)), mu, samples=k,
                times=t),
        measure("workspace", "12e", "µm", bound=0.0, scale=mu, **per_axis(outside, 0)),
        measure("velocity", "12i", "m/s", bound=problem.v_max, **per_axis(vel, 1)),
        measure("acceleration", "12j", "m/s²", bound=problem.a_max, **per_axis(acc, 1)),
    ))  # fmt: skip
