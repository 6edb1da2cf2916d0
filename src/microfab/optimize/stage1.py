"""Stage 1 of seed 002: minimum-time contouring on the linear model (eqs. 8-12).

The contour is sampled at ``N`` points equally spaced in ``s`` (eq. 8); the time steps
``Δτ_k`` between them are decision variables, so ``T = Σ Δτ_k`` is one too. The linear
model (eq. 6) is stepped by RK4 with the input held over a step (eq. 9); the output must
reach each point's local frame on its normal (12g) within the tolerance (12h), under the
output's speed and acceleration bounds (12i, 12j) and in the workspace (12e). The cost is
the time plus the mean squared second difference of the input (12a). CasADi builds the
problem (SX, vectorised by ``Function.map``) and IPOPT solves it, as in the seed (§IV-C).

What is done differently from a plain transcription, and why (the problem is the same):

* **ν eliminated** (eqs. 10-12f-h). With the unit tangent ``t_k`` and the unit normal
  ``n_k`` (to port) of the exact path at ``s_k``, ``ν_k = [t_k, n_k]ᵀ(γ_k - Ξ_k)``:
  12g is ``t_kᵀ(γ_k - Ξ_k) = 0`` and 12h is ``|n_kᵀ(γ_k - Ξ_k)| ≤ μ``. *Seed point:* eq.
  (10) writes the rotation block ``[[cos α, sin α], [-sin α, cos α]]``, which maps
  ``ν = (1, 0)`` to ``(cos α, -sin α)``; a local→global map must send it to
  ``(cos α, sin α)`` (the tangent), so the block is transposed. The tangent and normal
  used here are the path's own.
* **The RK4 step as matrices** (eq. 9): for ``ż = Az + Bρ`` with ``ρ`` held, one RK4 step
  of length ``h`` is exactly ``z⁺ = Φ(h) z + Γ(h) ρ`` with ``Φ = Σ_{j≤4} (hA)^j / j!`` and
  ``Γ = h Σ_{j≤3} (hA)^j / (j+1)! B``: polynomials in ``h`` with constant matrices.
* **Divisions multiplied out.** 12i: ``|γ_{k+1} - γ_k| ≤ v_max Δτ_k``. 12j uses the
  second difference on unequal steps (*seed point:* ``(γ_{k+1} - 2γ_k + γ_{k-1}) /
  (Δτ_k Δτ_{k+1})`` is exact only for equal steps): ``2[(γ_{k+1}-γ_k)/Δτ_k -
  (γ_k-γ_{k-1})/Δτ_{k-1}] / (Δτ_{k-1}+Δτ_k)``, written
  ``|2[(γ_{k+1}-γ_k) Δτ_{k-1} - (γ_k-γ_{k-1}) Δτ_k]| ≤ a_max Δτ_{k-1} Δτ_k (Δτ_{k-1}+Δτ_k)``.
  The cost's input term uses the same operator (it must divide; ``Δτ`` is bounded away
  from 0, below).
* **Scaled units.** Lengths in mm, time steps in units of ``τ_ref`` (the warm start's mean
  step), the tolerance rows divided by ``μ``, the model state in a balanced realisation
  (`balanced`: equal controllability and observability Gramians), the cost divided by
  the warm start's time.
* **Warm start** from `microfab.trajectory.optimal.time_optimal` along the same path under
  the output's bounds (the steps from its ``s(t)``), the input on the path and the state
  simulated by the same RK4 steps. The seed starts from the path at constant speed
  (``warm="constant"``, kept for comparison: `benchmarks/bench_optimize.py`).

Ends (the seed does not say; ours): the stage starts **at rest** on ``Ξ_0``: ``z_0`` is
the equilibrium of eq. (6) for the input ``ρ_rest = G(0)⁻¹ Ξ_0`` (``G(0) = D - C A⁻¹ B``,
the static gain), held before ``t_0``. ``ρ_0`` is free (with ``D = 0`` the output could
not leave ``Ξ_0`` in the first step otherwise), and 12g-12h hold at ``k = 0`` too; the
output's speed before ``t_0`` is 0, so the first acceleration row reads
``|γ_1 - γ_0| ≤ a_max Δτ_0²`` (the formula above with a virtual resting step of length
``Δτ_0``). It **ends** on ``Ξ_{N-1}`` in its frame (12g-h), not
necessarily at rest (stage 2 holds the input after the end).

Index ranges (*seed point:* the text has ``Δτ_k`` for ``k = 0…N-1`` but 12a-12d run over
``1…N``): here ``N`` points ``k = 0…N-1``, ``N-1`` steps, ``T = t_{N-1}``.

Step bounds and RK4 sub-steps (assumed). ``Δτ_k ≥ 10⁻³ τ_ref`` (the seed's ``Δτ ≥ 0``,
kept positive so that the input term is defined; never active in our runs) and
``Δτ_k ≤ 3 sqrt(Δs / a_max)``: three times the shortest first step from rest, which must
cover ``Δs`` at ``a_max``. One RK4 step of that length can be unstable (RK4 needs
``Δτ |λ| ≲ 2.8``; for the fitted stage model, |λ| ≈ 80 rad/s, a single step would cap
``Δτ`` at 35 ms, below the 45 ms a first step of 20 µm at 0.1 m/s² needs), so eq. (9) is
taken as ``m`` equal RK4 sub-steps with the input held, ``m`` the least with
``(Δτ_max / m) |λ|_max ≤ 1`` (``m = 1`` or 2 for the letters at 1 m/s²; the seed's
single step when the bound allows it).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.core.interrupt import interruptible
from microfab.identify.subspace_model import ContinuousModel
from microfab.io.atomic import atomic_save_npz
from microfab.optimize.blocks import Block, BlockNLP
from microfab.optimize.feasibility import Feasibility
from microfab.optimize.linear_steps import balanced, rk4_matrices, rk4_poly, warm_inputs
from microfab.optimize.problem import ContourProblem, n_points
from microfab.trajectory.optimal import time_optimal

__all__ = [
    "N_MIN",
    "Stage1Error",
    "Stage1Result",
    "Stage1Settings",
    "balanced",
    "rk4_matrices",
    "solve_stage1",
]

N_MIN = 10  # issue 18: fewer points are refused
_MM = 1e3  # scaled length unit: mm per m
_DT_MIN = 1e-3  # assumed: lower bound of Δτ in units of τ_ref (module docstring)
_RK4_HL = 1.0  # assumed: RK4 sub-steps with h |λ|_max ≤ 1 (module docstring)
_STEP_MAX = 3.0  # assumed: Δτ ≤ 3 sqrt(Δs / a_max) (module docstring)
_ACTIVE = 1e-5  # a row within this (relative, scaled) of its bound is reported active
#: IPOPT's return statuses of a finished solve (`Stage1Result.converged` also measures).
_SUCCESS = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


class Stage1Error(RuntimeError):
    """Stage 1 found no solution.

    Infeasible (the message names the tolerance and the ``s`` where it fails), not
    converged, or reported solved by IPOPT while a hard constraint measured on its answer
    is broken (`Stage1Result.feasibility`: the constraint, its residual and knot); the
    last iterate is in ``result``.
    """

    def __init__(self, message: str, result: Stage1Result | None = None) -> None:
        super().__init__(message)
        self.result = result


@dataclass(frozen=True)
class Stage1Settings:
    """Settings of stage 1.

    Parameters
    ----------
    n : int, optional
        Points ``N`` (eq. 8); default `microfab.optimize.problem.n_points`. At least 10.
    smoothing : float
        Weight of the input term of (12a) relative to the seed's ``1/(N-2)`` in SI units
        (s and (m/s²)²): 1 is the seed's cost.
    warm : {"time_optimal", "constant"}
        Initial guess (module docstring); "constant" is the seed's.
    constant_speed : float
        Path speed of the "constant" guess, m/s (assumed 0.05 m/s: slow enough that the
        linear model's lag stays within a few µm... of the guess; only the guess).
    max_iter : int
        IPOPT iterations.
    tol : float
        IPOPT's tolerance (scaled problem).
    print_level : int
        IPOPT's print level (0 silent).
    """

    n: int | None = None
    smoothing: float = 1e-3
    warm: str = "time_optimal"
    constant_speed: float = 0.05
    max_iter: int = 3000
    tol: float = 1e-8
    print_level: int = 0
    ipopt: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.n is not None and (isinstance(self.n, bool) or not isinstance(self.n, int)
                                   or self.n < N_MIN):  # fmt: skip
            raise ValueError(f"n must be an integer >= {N_MIN} points, got {self.n!r}")
        if not (math.isfinite(self.smoothing) and self.smoothing >= 0):
            raise ValueError(f"smoothing must be >= 0, got {self.smoothing!r}")
        if self.warm not in ("time_optimal", "constant"):
            raise ValueError(f"warm must be 'time_optimal' or 'constant', got {self.warm!r}")
        if not (math.isfinite(self.constant_speed) and self.constant_speed > 0):
            raise ValueError(f"constant_speed must be > 0 m/s, got {self.constant_speed!r}")
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")
        if not (math.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be > 0, got {self.tol!r}")


@dataclass(frozen=True, eq=False)
class Stage1Result:
    """The minimum-time trajectory of stage 1.

    Attributes
    ----------
    t : numpy.ndarray
        Knot times ``t_k``, shape (N,), s, ``t_0 = 0``.
    s : numpy.ndarray
        Path progress ``s_k``, shape (N,), m (eq. 8).
    target : numpy.ndarray
        ``Ξ_k``, shape (N, 2), m.
    rho : numpy.ndarray
        Input ``ρ_k`` held over step k, shape (N, 2), m.
    gamma : numpy.ndarray
        Predicted output ``γ_k`` (eq. 9b), shape (N, 2), m.
    z : numpy.ndarray
        Model state (the model's own coordinates), shape (N, n).
    active : dict of str to numpy.ndarray
        Boolean (N,) per constraint family ("tolerance", "velocity", "acceleration"):
        within 1e-6 (scaled) of its bound at point k.
    deviation : numpy.ndarray
        ``n_kᵀ(γ_k - Ξ_k)``, shape (N,), m (signed, port positive).
    status : str
        IPOPT's return status.
    iterations : int
        IPOPT iterations.
    wall_s : float
        Build and solve time, s.
    info : dict
        Settings, a_max, μ, costs.
    feasibility : Feasibility or None
        Eqs. 12b-12j measured on the returned input and times
        (`microfab.optimize.stage1_check.stage1_feasibility`).
    """

    t: np.ndarray
    s: np.ndarray
    target: np.ndarray
    rho: np.ndarray
    gamma: np.ndarray
    z: np.ndarray
    active: dict[str, np.ndarray]
    deviation: np.ndarray
    status: str
    iterations: int
    wall_s: float
    info: dict[str, Any] = field(default_factory=dict)
    feasibility: Feasibility | None = None

    @property
    def converged(self) -> bool:
        """IPOPT stopped with success *and* every hard constraint holds on the answer.

        Never from IPOPT's flag alone (`microfab.optimize.feasibility.FEASIBILITY_RTOL`).
        """
        ok = self.status in _SUCCESS
        return ok and self.feasibility is not None and self.feasibility.feasible

    @property
    def duration(self) -> float:
        """``T = t_{N-1}``, s."""
        return float(self.t[-1])

    @property
    def n(self) -> int:
        """``N``."""
        return int(self.t.shape[0])

    def s_of_t(self, t: np.ndarray) -> np.ndarray:
        """Path progress at times ``t`` (s), m.

        Piecewise linear between the knots, held at 0 before and at ``S`` after.
        """
        return np.interp(np.asarray(t, dtype=float), self.t, self.s)

    def rho_of_t(self, t: np.ndarray) -> np.ndarray:
        """The input at times ``t`` (s), shape (len(t), 2), m: linear between knots."""
        tt = np.asarray(t, dtype=float)
        return np.column_stack([np.interp(tt, self.t, self.rho[:, a]) for a in range(2)])

    def sample(self, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Eq. (13): times, path progress and input at a fixed rate.

        Parameters
        ----------
        rate_hz : float
            The network model's rate (400 Hz).

        Returns
        -------
        t : numpy.ndarray
            ``t_i = i Δt``, ``i = 0 … M`` with ``M = ceil(T / Δt)``, shape (M + 1,), s.
        s : numpy.ndarray
            ``s(t_i)``, shape (M + 1,), m, held at ``S`` after ``T``.
        rho : numpy.ndarray
            Stage 1's input at ``t_i`` (linear between knots, held after ``T``),
            shape (M + 1, 2), m.
        """
        dt = 1.0 / rate_hz
        m = math.ceil(self.duration / dt - 1e-9)
        t = np.arange(m + 1) * dt
        return t, self.s_of_t(t), self.rho_of_t(t)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the arrays (``.npz``) atomically; the rest goes in the caller's summary."""
        arrays = {k: getattr(self, k) for k in ("t", "s", "target", "rho", "gamma", "z",
                                                "deviation")}  # fmt: skip
        arrays.update({f"active_{k}": v for k, v in self.active.items()})
        atomic_save_npz(path, **arrays)

    def summary(self) -> dict[str, Any]:
        """JSON-ready: T, N, status, converged, 12b-12j measured, iterations, time, info."""
        feas = self.feasibility
        return {
            "duration_s": self.duration,
            "n": self.n,
            "status": self.status,
            "converged": self.converged,
            "feasibility": None if feas is None else feas.as_dict(),
            "iterations": self.iterations,
            "wall_s": self.wall_s,
            "max_deviation_m": float(np.abs(self.deviation).max()),
            "active": {k: int(v.sum()) for k, v in self.active.items()},
            **self.info,
        }


def _frames(
    problem: ContourProblem, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    s = np.linspace(0.0, problem.length, n)  # eq. (8)
    pts = problem.path.point(s)
    tan = problem.path.tangent(s)
    tan = tan / np.linalg.norm(tan, axis=1, keepdims=True)
    nor = np.column_stack([-tan[:, 1], tan[:, 0]])  # port side (seed Fig. 10)
    return s, pts, tan, nor


def _warm_times(problem: ContourProblem, s: np.ndarray, settings: Stage1Settings) -> np.ndarray:
    """Knot times of the warm start, shape (N,), s."""
    if settings.warm == "constant":
        return s / settings.constant_speed
    import dataclasses

    lim = dataclasses.replace(problem.limits, acceleration=(problem.a_max,) * 2)
    res = time_optimal(problem.path, lim, n_grid=min(max(len(s), 200), 2000))
    traj = res.trajectory
    ts = np.arange(traj.position.shape[0]) * traj.dt
    sp = traj.s if traj.s is not None else None
    if sp is None:  # pragma: no cover - time_optimal always records s
        return s / settings.constant_speed
    sp = np.maximum.accumulate(np.asarray(sp, dtype=float))
    t = np.interp(s, sp, ts)
    t[0] = 0.0
    t[-1] = max(t[-1], ts[-1])
    # strictly increasing (a plateau of s at a stop): at least 1e-3 of the mean step
    step = np.maximum(np.diff(t), 1e-3 * t[-1] / (len(s) - 1))
    return np.concatenate([[0.0], np.cumsum(step)])


def _blocks(
    ca: Any, powers: list[np.ndarray], B: np.ndarray, C: np.ndarray, D: np.ndarray,
    scales: dict[str, float], n: int, nx: int, frames: np.ndarray, frame0: np.ndarray,
) -> list[Block]:  # fmt: skip
    """Stage 1 as blocks (`microfab.optimize.blocks`).

    One per interval (dynamics 12b, 12g, 12h, 12i, 12e and the time term of 12a), one per
    corner (12j and the input term of 12a), and the first step from rest (12j at k = 0).

    Global variables: ``d_0 … d_{n-2}``, then ``[z_k; ρ_k]`` for ``k = 0 … n-1``.
    """
    nw = nx + 2
    tau, t_scale = scales["tau"], scales["t_scale"]
    mu_mm, v_step, a_step = scales["mu_mm"], scales["v_step"], scales["a_step"]
    sx = ca.SX
    dsym = sx.sym("d")
    phi, gam = rk4_poly(ca, powers, B, tau, dsym, scales["substeps"])

    def out(c: Any) -> Any:
        return ca.mtimes(ca.DM(C), c[:nx]) + ca.mtimes(ca.DM(D), c[nx:])

    def col(k: np.ndarray) -> np.ndarray:  # global indices of [z_k; ρ_k], (len(k), nw)
        return (n - 1) + k[:, None] * nw + np.arange(nw)[None, :]

    # interval k = 1..n-1: v = [c_{k-1}, c_k, d_{k-1}], p = Ξ_k (mm), t_k, n_k
    v = sx.sym("v", 2 * nw + 1)
    fr = sx.sym("frame", 6)
    c0, c1, d0 = v[:nw], v[nw : 2 * nw], v[2 * nw]
    g0, g1 = out(c0), out(c1)
    phi0, gam0 = ca.substitute(phi, dsym, d0), ca.substitute(gam, dsym, d0)
    dyn = c1[:nx] - phi0 @ c0[:nx] - gam0 @ c0[nx:]
    err = g1 - fr[:2]
    vel = (g1 - g0) / v_step  # 12i: |vel| ≤ d
    rows = ca.vertcat(dyn, ca.dot(err, fr[2:4]) / mu_mm, ca.dot(err, fr[4:6]) / mu_mm,
                      vel - d0, vel + d0, g1)  # fmt: skip
    k = np.arange(1, n)
    interval = Block(
        rows=ca.Function("interval", [v, fr], [rows]),
        cost=ca.Function("time", [v, fr], [tau * d0 / t_scale]),
        index=np.hstack([col(k - 1), col(k), (k - 1)[:, None]]),
        params=frames,
    )
    # corner k = 1..n-2: v = [c_{k-1}, c_k, c_{k+1}, d_{k-1}, d_k]
    v = sx.sym("v", 3 * nw + 2)
    p0 = sx.sym("p", 1)
    c0, c1, c2, d0, d1 = v[:nw], v[nw : 2 * nw], v[2 * nw : 3 * nw], v[3 * nw], v[3 * nw + 1]
    g0, g1, g2 = out(c0), out(c1), out(c2)
    num = 2 * ((g2 - g1) * d0 - (g1 - g0) * d1) / a_step  # 12j, multiplied out
    den = d0 * d1 * (d0 + d1)
    r0, r1, r2 = c0[nx:], c1[nx:], c2[nx:]
    rho_acc = 2 * ((r2 - r1) / d1 - (r1 - r0) / d0) / (d0 + d1) / (tau**2 * _MM)  # m/s²
    k = np.arange(1, n - 1)
    corner = Block(
        rows=ca.Function("corner", [v, p0], [ca.vertcat(num - den, num + den)]),
        cost=ca.Function("smooth", [v, p0],
                         [scales["smoothing"] / max(n - 2, 1) * ca.sumsqr(rho_acc) / t_scale]),
        index=np.hstack([col(k - 1), col(k), col(k + 1), (k - 1)[:, None], k[:, None]]),
        params=np.zeros((n - 2, 1)),
    )  # fmt: skip
    # the first step from rest: |γ_1 - γ_0| ≤ a_max Δτ_0²
    v = sx.sym("v", 2 * nw + 1)
    c0, c1, d0 = v[:nw], v[nw : 2 * nw], v[2 * nw]
    acc0 = (out(c1) - out(c0)) / a_step
    first = Block(
        rows=ca.Function("first", [v, p0], [ca.vertcat(acc0 - d0**2, acc0 + d0**2)]),
        cost=None,
        index=np.hstack([col(np.array([0])), col(np.array([1])), np.array([[0]])]),
        params=np.zeros((1, 1)),
    )
    # the start point k = 0: ρ_0 is free (z_0 is fixed at rest), so 12g-12h hold at Ξ_0
    v = sx.sym("v", nw)
    err = out(v) - fr[:2]
    start = Block(
        rows=ca.Function("start", [v, fr], [ca.vertcat(ca.dot(err, fr[2:4]) / mu_mm,
                                                       ca.dot(err, fr[4:6]) / mu_mm)]),
        cost=None,
        index=col(np.array([0])),
        params=frame0[None, :],
    )  # fmt: skip
    return [interval, corner, first, start]


def solve_stage1(
    problem: ContourProblem,
    model: ContinuousModel,
    settings: Stage1Settings | None = None,
) -> Stage1Result:
    """Minimum-time contouring of ``problem`` on the linear ``model`` (module docstring).

    Parameters
    ----------
    problem : ContourProblem
        Contour, μ, a_max, Table I.
    model : ContinuousModel
        Eq. (6), inputs and outputs (x, y) in m, stable.
    settings : Stage1Settings, optional

    Returns
    -------
    Stage1Result

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C while IPOPT ran (`microfab.core.interrupt.interruptible`), not a status.
    Stage1Error
        IPOPT reports the problem infeasible (the message names μ and the ``s`` of the
        worst tolerance row of the last iterate) or stops without converging, or a hard
        constraint of eq. (12) measured on its answer is broken
        (`microfab.optimize.stage1_check.stage1_feasibility`; every message names the
        measured residuals).
    """
    import casadi as ca

    st = Stage1Settings() if settings is None else settings
    t_start = time.perf_counter()
    n = st.n if st.n is not None else n_points(problem.length, problem.tolerance_m)
    bal = balanced(model)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (bal.a, bal.b, bal.c, bal.d))
    nx = A.shape[0]
    if B.shape[1] != 2 or C.shape[0] != 2:
        raise ValueError(f"the linear model must have 2 inputs and 2 outputs, got {B.shape[1]} "
                         f"and {C.shape[0]}")  # fmt: skip
    lam = float(np.max(np.abs(np.linalg.eigvals(A))))
    s, xi, tan, nor = _frames(problem, n)
    t_warm = _warm_times(problem, s, st)
    tau = float(t_warm[-1] / (n - 1))  # τ_ref, s
    ds = float(s[1] - s[0])
    d_max = _STEP_MAX * math.sqrt(ds / problem.a_max) / tau
    substeps = max(1, math.ceil(d_max * tau * lam / _RK4_HL))
    g0 = D - C @ np.linalg.solve(A, B)  # static gain
    rho0 = np.linalg.solve(g0, xi[0] * _MM)  # ρ_rest, mm
    z0 = -np.linalg.solve(A, B @ rho0)

    # scaled symbols: d (time step / τ), z (balanced, mm inputs), ρ, γ in mm
    Ah = tau * A
    powers = [np.linalg.matrix_power(Ah, j) for j in range(5)]
    mu_mm = problem.tolerance_m * _MM
    v_step = problem.v_max * tau * _MM  # mm per unit step
    a_step = problem.a_max * tau**2 * _MM
    nw = nx + 2
    t_scale = float(t_warm[-1])
    scales = {"tau": tau, "t_scale": t_scale, "mu_mm": mu_mm, "v_step": v_step,
              "a_step": a_step, "smoothing": st.smoothing, "substeps": substeps}  # fmt: skip
    frames = np.vstack([xi.T * _MM, tan.T, nor.T]).T  # (n, 6)
    blocks = _blocks(ca, powers, B, C, D, scales, n, nx, frames[1:], frames[0])
    nlp = BlockNLP((n - 1) + nw * n, blocks)
    inf = np.inf
    ws = problem.limits.workspace
    # per interval: dyn (nx) = 0, along = 0, across in [-1, 1], vel - d (2) ≤ 0,
    # vel + d (2) ≥ 0, γ (2) in the workspace (12e); per corner and first: 2 ≤ 0, 2 ≥ 0
    lo_i = np.concatenate([np.zeros(nx), [0.0, -1.0], [-inf] * 2, [0.0] * 2,
                           [ws[0][0] * _MM, ws[1][0] * _MM]])  # fmt: skip
    hi_i = np.concatenate([np.zeros(nx), [0.0, 1.0], [0.0] * 2, [inf] * 2,
                           [ws[0][1] * _MM, ws[1][1] * _MM]])  # fmt: skip
    lo_c, hi_c = np.array([-inf, -inf, 0.0, 0.0]), np.array([0.0, 0.0, inf, inf])
    lbg = np.concatenate([np.tile(lo_i, n - 1), np.tile(lo_c, n - 2), lo_c, [0.0, -1.0]])
    ubg = np.concatenate([np.tile(hi_i, n - 1), np.tile(hi_c, n - 2), hi_c, [0.0, 1.0]])

    # warm start: steps from t_warm, input on the path (static-gain inverse), RK4 state
    d_init = np.clip(np.diff(t_warm) / tau, _DT_MIN, d_max)
    rho_init = np.linalg.solve(g0, (xi * _MM).T).T

    def step(dk: float) -> tuple[np.ndarray, np.ndarray]:
        return rk4_poly(None, powers, B, tau, dk, substeps)

    z_init, rho_init = warm_inputs(step, z0, rho_init, d_init, xi * _MM, A, B, C, D)
    x0 = np.concatenate([d_init, np.hstack([z_init, rho_init]).ravel()])
    # z_0 fixed at rest (the equilibrium of ρ_rest); ρ_0 is free
    lbx = np.concatenate([np.full(n - 1, _DT_MIN), z0, [-inf, -inf], np.full(nw * (n - 1), -inf)])
    ubx = np.concatenate([np.full(n - 1, d_max), z0, [inf, inf], np.full(nw * (n - 1), inf)])

    opts = {
        "ipopt.print_level": st.print_level,
        "print_time": False,
        "ipopt.max_iter": st.max_iter,
        "ipopt.tol": st.tol,
        "ipopt.sb": "yes",
        **st.ipopt,
    }
    solver = nlp.solver(opts)
    # a Ctrl-C inside IPOPT comes back as its status (NonIpopt_Exception_Thrown): raise it
    sol = interruptible(solver, x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    x = np.asarray(sol["x"]).ravel()
    d_opt = x[: n - 1]
    colsv = x[n - 1 :].reshape(n, nw).T
    z_opt, rho_opt = colsv[:nx], colsv[nx:]
    gamma_opt = C @ z_opt + D @ rho_opt
    t = np.concatenate([[0.0], np.cumsum(d_opt * tau)])
    dev = np.sum((gamma_opt.T / _MM - xi) * nor, axis=1)
    gval = np.asarray(sol["g"]).ravel()
    # active rows, per point
    n_int = nx + 8
    across_v = gval[: n_int * (n - 1)].reshape(n - 1, n_int)[:, nx + 1]
    act_tol = np.zeros(n, bool)
    act_tol[1:] = np.abs(across_v) > 1 - _ACTIVE
    vel_v = np.abs(np.diff(gamma_opt, axis=1)) / v_step - d_opt
    act_vel = np.zeros(n, bool)
    act_vel[:-1] = np.any(vel_v > -_ACTIVE * d_opt, axis=0)
    dgv = np.diff(gamma_opt, axis=1)
    num = 2 * (dgv[:, 1:] * d_opt[:-1] - dgv[:, :-1] * d_opt[1:]) / a_step
    den = d_opt[:-1] * d_opt[1:] * (d_opt[:-1] + d_opt[1:])
    act_acc = np.zeros(n, bool)
    act_acc[1:-1] = np.any(np.abs(num) - den > -_ACTIVE * den, axis=0)
    status = str(stats.get("return_status", ""))
    from microfab.optimize.stage1_check import stage1_feasibility

    feas = stage1_feasibility(problem, bal, t=t, s=s, rho=rho_opt.T / _MM,
                              gamma=gamma_opt.T / _MM, rho_rest=rho0 / _MM,
                              substeps=substeps)  # fmt: skip
    result = Stage1Result(
        t=t,
        s=s,
        target=xi,
        rho=rho_opt.T / _MM,
        gamma=gamma_opt.T / _MM,
        z=(z_opt.T),
        active={"tolerance": act_tol, "velocity": act_vel, "acceleration": act_acc},
        deviation=dev,
        status=status,
        iterations=int(stats.get("iter_count", -1)),
        wall_s=time.perf_counter() - t_start,
        info={
            "a_max": problem.a_max,
            "tolerance_m": problem.tolerance_m,
            "n": n,
            "smoothing": st.smoothing,
            "warm": st.warm,
            "rk4_substeps": substeps,
            "rho_rest": (rho0 / _MM).tolist(),
            "step_max_s": d_max * tau,
            "warm_duration_s": float(t_warm[-1]),
            "cost": float(sol["f"]) * t_scale,
        },
        feasibility=feas,
    )
    measured = f"measured on it: {feas.describe()}"
    if not stats.get("success", False):
        if "Infeasible" in status:
            k = int(np.argmax(np.abs(dev)))
            raise Stage1Error(
                f"stage 1 is infeasible at tolerance {problem.tolerance_m * 1e6:g} µm: the "
                f"worst point is s = {s[k] * 1e3:.3f} mm (deviation {abs(dev[k]) * 1e6:.1f} µm); "
                f"raise the tolerance or a_max ({measured})",
                result,
            )
        raise Stage1Error(
            f"stage 1 did not converge ({status}, {result.iterations} iterations); the last "
            f"iterate is kept; raise max_iter ({measured})",
            result,
        )
    if not result.converged:
        raise Stage1Error(
            f"stage 1 is infeasible: IPOPT reports {status}, but its answer breaks a hard "
            f"constraint ({measured}); the answer is kept",
            result,
        )
    return result
