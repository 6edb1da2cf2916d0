"""The linear model of seed 002 (eq. 6) as stage 1 steps it (eq. 9).

* `balanced`: a balanced realisation (equal, diagonal Gramians), for conditioning;
* `rk4_matrices` / `rk4_poly`: one RK4 step with the input held is exactly
  ``z⁺ = Φ(h) z + Γ(h) ρ`` with ``Φ = Σ_{j≤4} (hA)^j / j!`` and
  ``Γ = h Σ_{j≤3} (hA)^j / (j+1)! B``, polynomials in ``h``; ``m`` sub-steps compose;
* `warm_inputs`: the warm start's state and input (the exact inverse of the RK4 model
  when it exists).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.linalg

from microfab.identify.subspace_model import ContinuousModel

__all__ = ["balanced", "rk4_matrices", "rk4_poly", "warm_inputs"]


def balanced(model: ContinuousModel) -> ContinuousModel:
    """The model in a balanced realisation (equal, diagonal Gramians; same input-output).

    Square-root method: Gramians from the Lyapunov equations, their Cholesky factors, the
    SVD of their product. Falls back to the model as given if it is not stable.
    """
    a, b, c, d = (np.asarray(m, dtype=float) for m in (model.a, model.b, model.c, model.d))
    if np.any(np.linalg.eigvals(a).real >= 0):
        return model
    wc = scipy.linalg.solve_continuous_lyapunov(a, -b @ b.T)
    wo = scipy.linalg.solve_continuous_lyapunov(a.T, -c.T @ c)
    lc = np.linalg.cholesky((wc + wc.T) / 2)
    lo = np.linalg.cholesky((wo + wo.T) / 2)
    u, sv, vt = np.linalg.svd(lo.T @ lc)
    s_half = np.diag(sv**-0.5)
    t = lc @ vt.T @ s_half  # z = t x_bal
    ti = s_half @ u.T @ lo.T
    return ContinuousModel(a=ti @ a @ t, b=ti @ b, c=c @ t, d=d)


def rk4_matrices(
    a: np.ndarray, b: np.ndarray, h: float, substeps: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """``Φ, Γ`` of ``substeps`` RK4 steps of ``h / substeps`` with the input held.

    ``z⁺ = Φ z + Γ ρ`` (module docstring).
    """
    if substeps > 1:
        ph, ga = rk4_matrices(a, b, h / substeps)
        phi_m, gam_m = ph, ga
        for _ in range(substeps - 1):
            phi_m, gam_m = ph @ phi_m, ph @ gam_m + ga
        return phi_m, gam_m
    n = a.shape[0]
    ha = h * a
    p = np.eye(n)
    phi = np.eye(n)
    gam = np.zeros_like(a)
    fact = 1.0
    for j in range(1, 5):
        gam = gam + p / (fact * j)  # (hA)^{j-1} / j!
        p = p @ ha
        fact *= j
        phi = phi + p / fact
    return phi, h * gam @ b


def rk4_poly(
    ca: Any, powers: list[np.ndarray], B: np.ndarray, tau: float, d: Any, m: int
) -> tuple[Any, Any]:
    """``Φ, Γ`` of ``m`` RK4 sub-steps over ``d τ`` as expressions of ``d`` (`rk4_matrices`).

    ``powers[j] = (τ A)^j``; works on CasADi SX (``ca`` the module) and on floats
    (``ca`` None).
    """

    def lift(x: np.ndarray) -> Any:
        return x if ca is None else ca.DM(x)

    h = d / m
    phi = sum(lift(powers[j] / math.factorial(j)) * h**j for j in range(5))
    gam = sum(lift(powers[j] @ B * tau / math.factorial(j + 1)) * h ** (j + 1) for j in range(4))
    mul = (lambda a, b: a @ b) if ca is None else ca.mtimes
    phi_m, gam_m = phi, gam
    for _ in range(m - 1):  # z⁺ = Φ(Φ z + Γ ρ) + Γ ρ
        phi_m, gam_m = mul(phi, phi_m), mul(phi, gam_m) + gam
    return phi_m, gam_m


def warm_inputs(
    step: Callable[[float], tuple[np.ndarray, np.ndarray]],
    z0: np.ndarray,
    rho: np.ndarray,
    d: np.ndarray,
    target: np.ndarray,
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """State and input of the warm start, shapes (N, n) and (N, 2).

    When ``D`` is invertible and the discrete zero dynamics ``Φ - Γ D⁻¹ C`` of every step
    is stable, the input is the exact inverse of the RK4 model along the warm times
    (``γ_k = Ξ_k`` at every point: 12b-12h hold from the start); otherwise every point
    starts at the equilibrium of ``rho`` (the path through the static-gain inverse), so
    ``γ_k = Ξ_k`` again but the dynamics (12b) do not hold until IPOPT makes them.
    """
    n = rho.shape[0]
    z = np.empty((n, z0.shape[0]))
    z[0] = z0
    r = rho.copy()
    invert = abs(np.linalg.det(D)) > 1e-6 * max(1.0, float(np.abs(D).max())) ** 2
    if invert:
        dinv_c = np.linalg.solve(D, C)
        for dk in (float(d.min()), float(d.max())):
            ph, ga = step(dk)
            if np.max(np.abs(np.linalg.eigvals(ph - ga @ dinv_c))) >= 1.0:
                invert = False
    if not invert:  # every point at its equilibrium: 12c-12j hold, 12b does not
        ainv_b = np.linalg.solve(A, B)
        return -(ainv_b @ r.T).T, r
    for k in range(n - 1):
        r[k] = np.linalg.solve(D, target[k] - C @ z[k])
        ph, ga = step(float(d[k]))
        z[k + 1] = ph @ z[k] + ga @ r[k]
    r[-1] = np.linalg.solve(D, target[-1] - C @ z[-1])
    return z, r
