"""The discretised planning problem of `microfab.trajectory.optimal` and its LP solvers.

`_Problem` holds the constraint operators and bounds on ``x = ṡ²`` over the grid of
`microfab.trajectory.optimal_grid`, the velocity/acceleration LP (`_Problem.solve_va`),
the sequential LP with tangent jerk constraints (`_Problem.solve_jerk`) and the knot times
of a solution; `LPSolver` is the interface of the solver it calls and `HighsLP` the
default one. They are apart from `~microfab.trajectory.optimal.time_optimal`, which runs
the verification rounds around them and re-exports these names; the method is described
in :mod:`microfab.trajectory.optimal`.
"""

from __future__ import annotations

import inspect
import warnings
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy import sparse
from scipy.optimize import linprog, minimize_scalar

from microfab.core.interrupt import interruptible
from microfab.core.limits import MachineLimits
from microfab.trajectory.highs import HighsSession
from microfab.trajectory.optimal_grid import (
    _acc_operator,
    _greatest_va,
    _Grid,
    _jerk_operator,
    _midpoint_cubic,
    _start_time,
    _travel_time,
)

__all__ = ["HighsLP", "LPSolver", "PlanningError"]

_TIME_RTOL = 1e-4  # stop the sequential LP when T improves by less than this, relative


class PlanningError(RuntimeError):
    """The planner could not produce a trajectory within the limits."""


class LPSolver(Protocol):
    """A linear-program solver: minimise ``c @ x`` s.t. ``A_ub @ x <= b_ub``, bounds.

    A solver whose ``solve`` also accepts a keyword ``x0`` is given a starting point for
    the velocity/acceleration LP (see the module notes); others are called as below.
    """

    def solve(
        self,
        c: np.ndarray,
        A_ub: sparse.csr_matrix,
        b_ub: np.ndarray,
        bounds: np.ndarray,
    ) -> np.ndarray:
        """Return the minimiser ``x``; raise :class:`PlanningError` if there is none."""
        ...


@dataclass(frozen=True, kw_only=True)
class HighsLP:
    """SciPy's HiGHS LP solver (:func:`scipy.optimize.linprog`, ``method="highs"``).

    Parameters
    ----------
    time_limit : float, optional
        Wall-time limit per LP, s.
    """

    time_limit: float | None = None
    _session: HighsSession = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.time_limit is not None and not self.time_limit > 0:
            raise ValueError(f"time_limit must be positive, got {self.time_limit} s")
        object.__setattr__(self, "_session", HighsSession(self.time_limit))

    def solve(
        self,
        c: np.ndarray,
        A_ub: sparse.csr_matrix,
        b_ub: np.ndarray,
        bounds: np.ndarray,
        x0: np.ndarray | None = None,
    ) -> np.ndarray:
        """Minimise ``c @ x`` subject to ``A_ub @ x <= b_ub`` and ``bounds`` (n, 2).

        With a starting point ``x0``, or the same ``A_ub`` object as the previous call
        that had one, the LP goes to a kept HiGHS model (warm start, see
        :class:`~microfab.trajectory.highs.HighsSession`); otherwise to
        :func:`scipy.optimize.linprog`. Not thread-safe: one instance per thread.
        """
        session = self._session
        if session.available and (x0 is not None or session.holds(A_ub)):
            try:
                x, status = session.solve(c, A_ub, b_ub, bounds, x0)
            except (AttributeError, TypeError) as exc:  # bindings of another HiGHS: linprog
                session.broken = True
                warnings.warn(
                    f"HiGHS bindings unusable ({exc}); solving with linprog", stacklevel=2
                )
            else:
                if x is None:
                    raise PlanningError(f"HiGHS LP failed: {status}")
                return x
        options: dict[str, object] = {}
        if self.time_limit is not None:
            options["time_limit"] = float(self.time_limit)
        res = interruptible(
            linprog, c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method="highs", options=options
        )  # Ctrl-C is a KeyboardInterrupt, never a failed LP
        if res.status != 0 or res.x is None:
            raise PlanningError(f"HiGHS LP failed: {res.message}")
        return np.asarray(res.x, dtype=float)


def _takes_keyword(fn: object, name: str) -> bool:
    """Whether the callable ``fn`` accepts the keyword argument ``name``."""
    try:
        params = inspect.signature(fn).parameters  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


# --------------------------------------------------------------------------- planner
class _Problem:
    """The discretised problem: constraint operators, bounds and the two solvers."""

    def __init__(
        self, g: _Grid, limits: MachineLimits, feed: float | None, margin: float, solver: LPSolver
    ) -> None:
        self.g, self.limits, self.feed, self.margin, self.solver = g, limits, feed, margin, solver
        self.lp_count = 0
        self.acc_op = _acc_operator(g)
        # the v/a LP's rows, built once: acc_op / limit, both signs, <= the multiplier
        base = self.acc_bound(np.ones(g.h.size))
        scaled = sparse.csr_matrix(self.acc_op.multiply(1.0 / base[:, None]))
        self.va_rows = sparse.vstack([scaled, -scaled]).tocsr()
        self.va_rows.data.setflags(write=False)
        self.va_weights = np.zeros(g.s.size)  # positive weights: node's share of the length
        self.va_weights[:-1] += 0.5 * g.h
        self.va_weights[1:] += 0.5 * g.h
        # a solver taking a starting point gets the greatest element (see _greatest_va)
        self.va_crash = _takes_keyword(solver.solve, "x0")
        if self.va_crash:
            coo = scaled.tocoo()
            lo = coo.col == coo.row // (2 * g.q.shape[1])  # coefficient of x_k (interval k)
            n_rows = scaled.shape[0]
            self.va_alpha = np.zeros(n_rows)
            self.va_beta = np.zeros(n_rows)
            np.add.at(self.va_alpha, coo.row[lo], coo.data[lo])
            np.add.at(self.va_beta, coo.row[~lo], coo.data[~lo])
        jerk = np.asarray(limits.jerk, dtype=float)
        self.has_jerk = bool(np.any(np.isfinite(jerk)))
        stop = g.stop
        # time weight of each interval: Δt = w / (√x_k + √x_{k+1}) for constant s̈
        self.tw = 2.0 * g.h
        self.jerk_op: sparse.csr_matrix | None = None
        self.jerk_k: np.ndarray | None = None
        self.jerk_i: np.ndarray | None = None
        if self.has_jerk:
            self.jerk_op, self.jerk_k, self.jerk_i = _jerk_operator(g, np.isfinite(jerk))
        # nodes next to a stop, and the length of the interval to it
        nxt = np.zeros(stop.size, dtype=bool)
        nxt[1:] |= stop[:-1]
        nxt[:-1] |= stop[1:]
        nxt &= ~stop
        self.near_stop = np.flatnonzero(nxt)
        h_to = np.full(stop.size, np.inf)
        h_to[1:] = np.where(stop[:-1], self.g.h, h_to[1:])
        h_to[:-1] = np.where(stop[1:], np.minimum(self.g.h, h_to[:-1]), h_to[:-1])
        self.h_to_stop = h_to[self.near_stop]

    # bounds of each constraint, with the per-node/interval multipliers
    def caps(self, vmul: np.ndarray, jmul: np.ndarray | None = None) -> np.ndarray:
        lim_v = (1 - self.margin) * np.asarray(self.limits.velocity)
        with np.errstate(divide="ignore"):
            per_axis = (lim_v[None, :] * vmul[:, None] / np.abs(self.g.d1)) ** 2
        cap = np.min(per_axis, axis=1)
        if self.feed is not None:
            cap = np.minimum(cap, ((1 - self.margin) * self.feed * vmul) ** 2)
        if self.has_jerk and jmul is not None:
            # leaving a stop at constant path jerk σ, s = σt³/6: σ = (2/9) ṡ³ / Δs², so
            # |q'_i| σ <= j_i caps x = ṡ² at the first node at (4.5 j_i Δs² / |q'_i|)^{2/3}
            k = self.near_stop
            lim_j = (1 - self.margin) * np.asarray(self.limits.jerk)[None, :] * jmul[k, None]
            with np.errstate(divide="ignore"):
                first = (4.5 * lim_j * self.h_to_stop[:, None] ** 2 / np.abs(self.g.d1[k])) ** (
                    2.0 / 3.0
                )
            cap[k] = np.minimum(cap[k], np.min(first, axis=1))
        cap[self.g.stop] = 0.0
        return cap

    def acc_bound(self, amul: np.ndarray) -> np.ndarray:
        n_ax = self.g.q.shape[1]
        lim = (1 - self.margin) * np.asarray(self.limits.acceleration)
        return (amul[:, None, None] * np.broadcast_to(lim, (amul.size, 2, n_ax))).reshape(-1)

    def jerk_bound(self, jmul: np.ndarray) -> np.ndarray:
        lim = (1 - self.margin) * np.asarray(self.limits.jerk)
        assert self.jerk_k is not None and self.jerk_i is not None
        return lim[self.jerk_i] * jmul[self.jerk_k]

    def knot_times(self, x: np.ndarray, jmul: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Times at the nodes, and the jerk-ramp duration in intervals touching a stop.

        Constant ``s̈`` per interval; next to a stop with a jerk limit, the path
        acceleration ramps from zero at the path jerk ``σ = min_i j_i / |q'_i|`` first
        (:func:`_start_time`). The ramp duration is NaN elsewhere.
        """
        with np.errstate(divide="ignore"):  # a speed that underflows: refused by the caller
            dt = self.tw / (np.sqrt(np.maximum(x[:-1], 0)) + np.sqrt(np.maximum(x[1:], 0)))
        ramp = np.full(dt.size, np.nan)
        if self.has_jerk:
            # s̈ varies within an interval: Simpson's rule on 1/ṡ, with x at the midpoint
            # from the cubic through the four surrounding nodes (kept between x_k, x_{k+1})
            xm = _midpoint_cubic(self.g.s, np.maximum(x, 0.0))
            lo = np.minimum(x[:-1], x[1:])
            hi = np.maximum(x[:-1], x[1:])
            xm = np.clip(xm, lo, hi)
            with np.errstate(divide="ignore"):
                inv = 1.0 / np.sqrt(np.maximum(x, 0.0))
                simpson = self.g.h / 6.0 * (inv[:-1] + 4.0 / np.sqrt(xm) + inv[1:])
            ok = np.isfinite(simpson)
            dt = np.where(ok, simpson, dt)
            lim_j = (1 - self.margin) * np.asarray(self.limits.jerk)
            for k, h in zip(self.near_stop, self.h_to_stop, strict=True):
                with np.errstate(divide="ignore"):
                    sigma = float(np.min(lim_j * jmul[k] / np.abs(self.g.d1[k])))
                t1, tau = _start_time(float(h), float(np.sqrt(max(x[k], 0.0))), sigma)
                iv = k - 1 if self.g.stop[k - 1] else k  # the interval to the stop
                dt[iv], ramp[iv] = t1, tau
        return np.concatenate([[0.0], np.cumsum(dt)]), ramp

    def solve_va(
        self, vmul: np.ndarray, amul: np.ndarray, jmul: np.ndarray | None = None
    ) -> np.ndarray:
        """The velocity/acceleration optimum: one LP, the greatest feasible ``x``."""
        cap = self.caps(vmul, jmul)
        mul = np.repeat(amul, 2 * self.g.q.shape[1])  # per row of acc_op
        b = np.concatenate([mul, mul])
        w = self.va_weights
        bounds = np.column_stack([np.zeros_like(cap), cap])
        if self.va_crash:
            x0 = _greatest_va(cap, self.va_alpha, self.va_beta, mul, 2 * self.g.q.shape[1])
            x = self.solver.solve(-w / w.max(), self.va_rows, b, bounds, x0=x0)
        else:
            x = self.solver.solve(-w / w.max(), self.va_rows, b, bounds)
        self.lp_count += 1
        return np.clip(x, 0.0, cap)

    def feasible_scale(
        self, x: np.ndarray, vmul: np.ndarray, amul: np.ndarray, jmul: np.ndarray
    ) -> float:
        """Largest ``c <= 1`` with ``c x`` inside every (discrete) constraint."""
        c = 1.0
        cap = self.caps(vmul, jmul)
        pos = x > 0
        if np.any(pos):
            c = min(c, float(np.min(cap[pos] / x[pos])))
        acc = np.abs(self.acc_op @ x)
        bound = self.acc_bound(amul)
        if np.any(acc > 0):
            c = min(c, float(np.min(bound[acc > 0] / acc[acc > 0])))
        if self.has_jerk:
            assert self.jerk_op is not None and self.jerk_k is not None
            jk = np.abs(self.jerk_op @ x) * np.sqrt(np.maximum(x[self.jerk_k], 0.0))
            jb = self.jerk_bound(jmul)
            if np.any(jk > 0):
                c = min(c, float(np.min((jb[jk > 0] / jk[jk > 0]) ** (2.0 / 3.0))))
        return max(c, 0.0) * (1 - 1e-9)

    def solve_jerk(
        self,
        x0: np.ndarray,
        vmul: np.ndarray,
        amul: np.ndarray,
        jmul: np.ndarray,
        max_iter: int,
    ) -> np.ndarray:
        """Sequential LP with tangent (convex-restriction) jerk constraints from feasible x0."""
        assert self.jerk_op is not None and self.jerk_k is not None
        g = self.g
        cap = self.caps(vmul, jmul)
        abound = self.acc_bound(amul)
        A_acc = self.acc_op.multiply(1.0 / abound[:, None]).tocsr()
        jb = self.jerk_bound(jmul)
        bounds = np.column_stack([np.zeros_like(cap), cap])
        x = x0.copy()
        T = _travel_time(x, self.tw)
        floor = 1e-9 * max(float(np.max(cap)), 1e-300)
        nk = self.jerk_k.size
        for _ in range(max_iter):
            xf = np.maximum(x, floor)
            # gradient of T: dT/dx_k = -sum_adjacent Δs / ((√x_k + √x_j)² √x_k)
            r = np.sqrt(xf)
            r[g.stop] = np.sqrt(np.maximum(x[g.stop], 0.0))
            den = (r[:-1] + r[1:]) ** 2
            grad = np.zeros_like(x)
            grad[:-1] -= 0.5 * self.tw / den / r[:-1].clip(np.sqrt(floor))
            grad[1:] -= 0.5 * self.tw / den / r[1:].clip(np.sqrt(floor))
            grad[g.stop] = 0.0
            # tangent of j/√x at x̄:  ±L(x) + j x_k / (2 x̄^{3/2}) <= 3 j / (2 √x̄), normalised
            xk = xf[self.jerk_k]
            rhs = 1.5 * jb / np.sqrt(xk)
            tang = sparse.csr_matrix(
                (0.5 * jb / xk**1.5 / rhs, (np.arange(nk), self.jerk_k)), shape=(nk, x.size)
            )
            Lr = self.jerk_op.multiply(1.0 / rhs[:, None]).tocsr()
            A = sparse.vstack([A_acc, -A_acc, Lr + tang, -Lr + tang]).tocsr()
            b = np.ones(A.shape[0])
            self.lp_count += 1
            try:
                x_lp = self.solver.solve(grad / np.max(np.abs(grad)), A, b, bounds)
            except PlanningError:
                break  # keep the last feasible iterate
            x_lp = np.clip(x_lp, 0.0, cap)
            d = x_lp - x

            def along(theta: float, x: np.ndarray = x, d: np.ndarray = d) -> float:
                return _travel_time(x + theta * d, self.tw)

            best = minimize_scalar(along, bounds=(0.0, 1.0), method="bounded")
            theta = float(best.x) if best.fun < along(1.0) else 1.0
            x_new = x + theta * d
            T_new = _travel_time(x_new, self.tw)
            if not T_new < T:
                break
            improved = (T - T_new) / T
            x, T = x_new, T_new
            if improved < _TIME_RTOL:
                break
        return x
