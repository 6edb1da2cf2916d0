"""The plain CasADi Opti transcription of seed 002's stage 1 (eqs. 8-12), for comparison.

Written as the equations read, started as the seed starts it (§IV-C: "the target geometry
traversed at a constant speed"): MX Opti, a generic RK4 step, ν as variables with eq. (11)
(rotation block transposed, see `microfab.optimize.stage1`), the unequal-step second
difference with the seed's division, the start at rest. It is the baseline of
`bench_optimize.py` and not used by microfab itself.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.problem import ContourProblem


def solve_plain(
    problem: ContourProblem,
    model: ContinuousModel,
    n: int,
    *,
    speed: float = 0.05,
    smoothing: float = 1e-3,
    max_cpu_s: float = 600.0,
) -> dict[str, Any]:
    """Stage 1 as a plain Opti problem; returns T, status, iterations and wall time."""
    import casadi as ca

    t0 = time.perf_counter()
    a, b, c, d = (np.asarray(m, dtype=float) for m in (model.a, model.b, model.c, model.d))
    nx = a.shape[0]
    s = np.linspace(0.0, problem.length, n)
    xi = problem.path.point(s)
    tan = problem.path.tangent(s)
    alpha = np.arctan2(tan[:, 1], tan[:, 0])
    opti = ca.Opti()
    dtau = opti.variable(n - 1)
    rho = opti.variable(2, n)
    z = opti.variable(nx, n)
    nu = opti.variable(2, n)
    A, B, C, D = (ca.DM(m) for m in (a, b, c, d))

    def f(zz: Any, rr: Any) -> Any:
        return A @ zz + B @ rr

    gamma = C @ z + D @ rho
    g0 = d - c @ np.linalg.solve(a, b)
    rest = np.linalg.solve(g0, xi[0])
    opti.subject_to(z[:, 0] == ca.DM(-np.linalg.solve(a, b @ rest)))
    for k in range(n - 1):
        h = dtau[k]
        k1 = f(z[:, k], rho[:, k])
        k2 = f(z[:, k] + h / 2 * k1, rho[:, k])
        k3 = f(z[:, k] + h / 2 * k2, rho[:, k])
        k4 = f(z[:, k] + h * k3, rho[:, k])
        opti.subject_to(z[:, k + 1] == z[:, k] + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))  # 12b
    for k in range(n):
        ca_, sa = float(np.cos(alpha[k])), float(np.sin(alpha[k]))
        rot = ca.DM([[ca_, -sa], [sa, ca_]])  # eq. (10), block transposed
        opti.subject_to(gamma[:, k] == rot @ nu[:, k] + ca.DM(xi[k]))  # 12f
        opti.subject_to(nu[0, k] == 0)  # 12g
        opti.subject_to(opti.bounded(-problem.tolerance_m, nu[1, k], problem.tolerance_m))
    opti.subject_to(dtau >= 1e-6)  # 12d (kept positive: the cost divides by it)
    cost = ca.sum1(dtau)
    for k in range(n - 1):
        opti.subject_to(
            opti.bounded(-problem.v_max, (gamma[:, k + 1] - gamma[:, k]) / dtau[k], problem.v_max)
        )  # 12i
    for k in range(1, n - 1):
        acc = (
            2
            * (
                (gamma[:, k + 1] - gamma[:, k]) / dtau[k]
                - (gamma[:, k] - gamma[:, k - 1]) / dtau[k - 1]
            )
            / (dtau[k - 1] + dtau[k])
        )
        opti.subject_to(opti.bounded(-problem.a_max, acc, problem.a_max))  # 12j
        racc = (
            2
            * ((rho[:, k + 1] - rho[:, k]) / dtau[k] - (rho[:, k] - rho[:, k - 1]) / dtau[k - 1])
            / (dtau[k - 1] + dtau[k])
        )
        cost = cost + smoothing / (n - 2) * ca.sumsqr(racc)  # fmt: skip
    opti.minimize(cost)
    # the seed's start: the path at constant speed
    t_guess = s / speed
    opti.set_initial(dtau, np.diff(t_guess))
    opti.set_initial(rho, np.linalg.solve(g0, xi.T))
    opti.set_initial(z, -np.linalg.solve(a, b @ np.linalg.solve(g0, xi.T)))
    opti.solver("ipopt", {"print_time": False},
                {"print_level": 0, "sb": "yes", "max_cpu_time": max_cpu_s})  # fmt: skip
    try:
        sol = opti.solve()
        status = sol.stats()["return_status"]
        total = float(np.sum(sol.value(dtau)))
        iters = int(sol.stats()["iter_count"])
    except RuntimeError:
        st = opti.stats()
        status, total, iters = st.get("return_status", "failed"), float("nan"), st["iter_count"]
    return {"T": total, "status": status, "iterations": iters, "wall_s": time.perf_counter() - t0}
