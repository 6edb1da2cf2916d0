"""The calibration algorithm: global search, polish, sensitivity and the conflict sweep.

`calibrate` searches the free parameters, normalised to [0, 1] (logarithmically where a
parameter asks for it), for the least sum of squared fit residuals: SciPy's
`differential_evolution` over the whole box (its population evaluated a generation at a
time, ``updating="deferred"``, through a map that runs the model in a process pool when
``workers > 1``), then `least_squares` on the fit residual vector within the bounds from
the best point found. Every evaluation goes through one memo (`memo.Memo`), so the polish,
the sensitivity, the conflict sweep and a resumed run re-run no point.

Whether the calibration converged is decided on the answer's residuals (every fit target
``|r| <= 1``), never from an optimiser's flag.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.optimize import differential_evolution, least_squares

from microfab.calibrate.memo import Memo
from microfab.calibrate.problem import CalibrationProblem
from microfab.calibrate.report import CalibrationResult, Conflict, build_result, pareto_filter

__all__ = ["Progress", "calibrate"]

#: Residual given to a target whose model value is not finite (a diverging twin): assumed,
#: far beyond any met target (|r| <= 1) yet finite, so the optimisers steer away from it.
NONFINITE_RESIDUAL = 1.0e6
#: Central-difference step of the sensitivity, in normalised coordinates: assumed, 0.1 % of
#: each parameter's range (large against a simulation's round-off, small against its curvature).
SENSITIVITY_STEP = 1.0e-3
#: Forward-difference step of the polish's Jacobian, normalised: assumed (smooth models).
POLISH_STEP = 1.0e-6
#: Points of the epsilon-constraint sweep between the two worst targets' single optima.
SWEEP_POINTS = 7


@dataclass(frozen=True)
class Progress:
    """What `calibrate` reports after each batch of evaluations.

    Attributes
    ----------
    phase : str
        ``"search"``, ``"polish"``, ``"sensitivity"`` or ``"conflict"``.
    requested : int
        Points asked for so far (memo hits included).
    evaluated : int
        Points the model computed so far (new ones).
    best_worst : float
        The least worst fit ``|r|`` seen so far.
    """

    phase: str
    requested: int
    evaluated: int
    best_worst: float


class _BudgetSpentError(Exception):
    """The phase's evaluation budget is spent."""


class _ModelError(Exception):
    """Carries a model's TypeError or ValueError through SciPy's map wrapper."""


class _Evaluator:
    """Model evaluations through the memo, in batches, serial or in a process pool."""

    def __init__(
        self,
        problem: CalibrationProblem,
        memo: Memo,
        workers: int,
        on_progress: Callable[[Progress], None] | None,
    ) -> None:
        self.problem = problem
        self.memo = memo
        self.workers = workers
        self.on_progress = on_progress
        self.phase = "search"
        self.requested = 0
        self.evaluated = 0
        self.cap: int | None = None
        self.first_met: int | None = None
        self.best_worst = math.inf
        self.visited: dict[tuple[float, ...], None] = {}
        self._pool: Executor | None = None
        self._fit = np.array(problem.fit_index)

    def close(self) -> None:
        self.memo.save()
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def residuals(self, model: np.ndarray) -> np.ndarray:
        r = self.problem.residuals(model)
        return np.where(np.isfinite(r), r, NONFINITE_RESIDUAL)

    def batch(self, points: Iterable[Sequence[float]]) -> list[np.ndarray]:
        """Model vectors (targets order) at the normalised ``points``; new ones computed."""
        keys = [tuple(float(min(max(x, 0.0), 1.0)) for x in p) for p in points]
        if self.cap is not None and self.requested + len(keys) > self.cap:
            raise _BudgetSpentError
        todo = list(dict.fromkeys(k for k in keys if k not in self.memo))
        if todo:
            args = [self.problem.values(k) for k in todo]
            if self.workers > 1 and len(todo) > 1:
                if self._pool is None:
                    self._pool = ProcessPoolExecutor(max_workers=self.workers)
                outs = list(self._pool.map(self.problem.evaluate, args))
            else:
                outs = [self.problem.evaluate(a) for a in args]
            for k, out in zip(todo, outs, strict=True):
                self.memo.put(k, self.problem.model_vector(out))
            self.evaluated += len(todo)
        models = []
        for k in keys:
            model = self.memo.get(k)
            assert model is not None
            self.requested += 1
            self.visited[k] = None
            worst = float(np.max(np.abs(self.residuals(model)[self._fit])))
            self.best_worst = min(self.best_worst, worst)
            searching = self.phase in ("search", "polish")
            if worst <= 1.0 and self.first_met is None and searching:
                self.first_met = self.requested
            models.append(model)
        if todo and (len(keys) > 1 or self.memo.unsaved >= 10):
            self.memo.save()
        if self.on_progress is not None:
            self.on_progress(Progress(self.phase, self.requested, self.evaluated, self.best_worst))
        return models

    def one(self, u: Sequence[float]) -> np.ndarray:
        return self.batch([u])[0]

    def seen(self) -> list[tuple[tuple[float, ...], np.ndarray]]:
        """``(point, model)`` of every point this run asked for, in order.

        Not the whole memo: a resumed run's memo also holds the points of phases still to
        come, and choosing from them would make the resumed run ask for other points.
        """
        out = []
        for k in self.visited:
            model = self.memo.get(k)
            assert model is not None
            out.append((k, model))
        return out


def _population(budget: int, n: int) -> tuple[int, int]:
    """DE's population and generations after the first within ``budget`` points, n params."""
    # One member per parameter at least (SciPy's population is popsize x n with popsize
    # >= 1, and never below 5), up to 15 per parameter (its default), fewer when the
    # budget allows fewer than about 8 generations.
    members = max(5, max(1, min(15, budget // (8 * n))) * n)
    return members, budget // members - 1


def de_sized(budget: int, n: int, polish: bool) -> int:
    """Generations DE gets from ``budget`` points (-1: not even one population)."""
    share = max(2 * (n + 1), budget // 5) if polish else 0
    return _population(budget - share, n)[1]


def _minimise(
    ev: _Evaluator,
    residual_vector: Callable[[np.ndarray], np.ndarray],
    budget: int,
    seed: int,
    polish: bool,
    *,
    start: tuple[float, ...] | None = None,
) -> tuple[float, ...] | None:
    """Least ``sum(residual_vector(model)**2)``: DE, then `least_squares`; the best point.

    With ``start``, no global search: the whole budget polishes from ``start``.
    """
    n = len(ev.problem.parameters)
    best: list[tuple[float, tuple[float, ...]]] = []

    def cost_of(model: np.ndarray) -> float:
        return float(np.sum(residual_vector(model) ** 2))

    def remember(keys: list[tuple[float, ...]], models: list[np.ndarray]) -> None:
        for k, m in zip(keys, models, strict=True):
            c = cost_of(m)
            if not best or c < best[0][0]:
                best[:] = [(c, k)]

    def mapper(_func: object, population: Iterable[np.ndarray]) -> list[float]:
        keys = [tuple(float(x) for x in p) for p in population]
        try:
            models = ev.batch(keys)
        except (TypeError, ValueError) as exc:  # SciPy would turn these into a RuntimeError
            raise _ModelError(exc) from exc
        remember(keys, models)
        return [cost_of(m) for m in models]

    if start is not None:
        best.append((cost_of(ev.one(start)), start))
        polish, budget = True, budget - 1
    elif de_sized(budget, n, polish) < 0 and len(ev.memo):
        # Too few points for a population: polish from the best point this run asked for
        # (the conflict sweep's single optima), else the best one stored.
        pool = ev.seen() if ev.visited else list(ev.memo.items())
        start = min(pool, key=lambda item: cost_of(item[1]))[0]
        best.append((cost_of(ev.one(start)), start))
        polish, budget = True, budget - 1
    begin = ev.requested
    polish_share = budget if start is not None else max(2 * (n + 1), budget // 5) if polish else 0
    de_budget = budget - polish_share
    members, generations = _population(de_budget, n)
    ev.cap = begin + budget
    try:
        if generations >= 0:
            differential_evolution(
                lambda _u: math.nan,  # never called: every evaluation goes through `mapper`
                [(0.0, 1.0)] * n,
                maxiter=generations,
                popsize=max(1, members // n),
                rng=seed,
                polish=False,
                updating="deferred",
                workers=mapper,
                init="latinhypercube",
            )
        if polish and best:

            def fun(u: np.ndarray) -> np.ndarray:
                key = tuple(float(x) for x in u)
                model = ev.one(key)
                remember([key], [model])
                return residual_vector(model)

            phase = ev.phase
            ev.phase = "polish" if phase == "search" else phase
            try:
                least_squares(
                    fun,
                    np.array(best[0][1]),
                    bounds=(0.0, 1.0),
                    method="trf",
                    diff_step=POLISH_STEP,
                    max_nfev=max(1, begin + budget - ev.requested),
                )
            finally:
                ev.phase = phase
    except _BudgetSpentError:
        pass
    except _ModelError as exc:
        raise exc.args[0] from None
    finally:
        ev.cap = None
    return best[0][1] if best else None


def _sensitivity(ev: _Evaluator, u: tuple[float, ...]) -> np.ndarray:
    """``d r_i / d u_j`` at ``u`` by central differences (one-sided at a bound), (m, n)."""
    n = len(u)
    points: list[tuple[float, ...]] = []
    spans = []
    for j in range(n):
        up, dn = list(u), list(u)
        up[j] = min(u[j] + SENSITIVITY_STEP, 1.0)
        dn[j] = max(u[j] - SENSITIVITY_STEP, 0.0)
        points += [tuple(up), tuple(dn)]
        spans.append(up[j] - dn[j])
    models = ev.batch(points)
    r = [ev.problem.residuals(m) for m in models]
    return np.stack([(r[2 * j] - r[2 * j + 1]) / spans[j] for j in range(n)], axis=1)


def conflict_pair(r: np.ndarray, jac: np.ndarray, fit: Sequence[int]) -> tuple[int, int]:
    """The worst fit target and the fit target that pulls hardest against it.

    At a least-squares answer the fit targets' pulls ``r_i ∇r_i`` (``jac`` rows, shape
    (m, n), scaled by the residuals ``r`` (m,)) balance; the counterpart of the worst target
    ``a`` is the target whose pull opposes ``a``'s most (the most negative
    ``r_i r_a ∇r_i · ∇r_a``), not merely the second worst: with three fit targets or more
    the second worst may depend on other parameters. Falls back to the second worst when
    no pull opposes ``a``'s.
    """
    order = sorted(fit, key=lambda i: -abs(r[i]))
    a = order[0]
    pull = np.nan_to_num(r[:, None] * jac)
    opposed = [(float(pull[i] @ pull[a]), i) for i in order[1:]]
    against = [x for x in opposed if x[0] < 0.0]
    b = min(against)[1] if against else order[1]
    return a, b


def _conflict(
    ev: _Evaluator,
    u: tuple[float, ...],
    budget: int,
    seed: int,
    polish: bool,
    jac: np.ndarray,
) -> Conflict | None:
    """The Pareto front of the worst fit target at ``u`` and its counterpart (`conflict_pair`).

    Found by an epsilon-constraint sweep.
    """
    problem = ev.problem
    fit = list(problem.fit_index)
    a, b = conflict_pair(ev.residuals(ev.one(u)), jac, fit)
    ends = budget // 5  # each single optimum: global search and polish

    def run(vec: Callable[[np.ndarray], np.ndarray], k: int) -> None:
        if k < 2:
            _minimise(ev, vec, ends, seed + 1 + k, polish)
            return
        # A level of the sweep: polished from the best point stored for its objective.
        # At least about 5 polish iterations of n + 1 points each, whatever the budget.
        each = max(6 * (len(u) + 1), (budget - 2 * ends) // len(levels))
        start = min(ev.seen(), key=lambda item: float(np.sum(vec(item[1]) ** 2)))[0]
        _minimise(ev, vec, each, seed + 1 + k, polish, start=start)

    def pair(model: np.ndarray) -> np.ndarray:
        r = ev.residuals(model)
        return np.array([r[a], r[b]])

    run(lambda m: pair(m)[:1], 0)  # A alone
    run(lambda m: pair(m)[1:], 1)  # B alone
    front = pareto_filter([pair(m) for _, m in ev.seen()])
    b_lo = float(np.min(np.abs(front[:, 1])))
    b_hi = float(np.abs(front[np.argmin(np.abs(front[:, 0])), 1]))
    levels = list(np.linspace(b_lo, b_hi, SWEEP_POINTS))
    if b_lo < 1.0 < b_hi:
        levels.append(1.0)
    hinge = math.sqrt(1.0e3)  # assumed weight: |r_B| over eps costs like 30 |r_A|
    for k, eps in enumerate(levels):

        def vec(m: np.ndarray, eps: float = float(eps)) -> np.ndarray:
            ra, rb = pair(m)
            return np.array([ra, hinge * max(0.0, abs(rb) - eps)])

        run(vec, 2 + k)
    front = pareto_filter([pair(m) for _, m in ev.seen()])
    sampled = []
    for eps in sorted(set(levels)):
        ok = front[np.abs(front[:, 1]) <= eps + 1e-12]
        if len(ok):
            sampled.append(ok[np.argmin(np.abs(ok[:, 0]))])
    points = pareto_filter(sampled)
    return Conflict.from_front(
        problem.targets[a].name, problem.targets[b].name, points, front, ev.requested
    )


def calibrate(
    problem: CalibrationProblem,
    *,
    budget: int,
    seed: int,
    workers: int = 1,
    polish: bool = True,
    on_progress: Callable[[Progress], None] | None = None,
    memo_path: str | os.PathLike[str] | None = None,
    conflict_budget: int | None = None,
) -> CalibrationResult:
    """Choose the free parameters that meet the fit targets; report every target.

    Parameters
    ----------
    problem : CalibrationProblem
        Targets, free parameters and model.
    budget : int
        Points the search (global search and polish) may ask for, memo hits included, so
        that a resumed run asks for the same points; >= 5.
    seed : int
        Seed of the global search (and of the conflict sweep's, derived from it).
    workers : int
        Model evaluations run side by side in a process pool when > 1 (the model must
        then be picklable).
    polish : bool
        Polish the global search's best point with `least_squares` (a fifth of the budget).
    on_progress : callable, optional
        Called with a `Progress` after each batch of evaluations.
    memo_path : path-like, optional
        JSON file of every evaluation, written atomically after each batch and reloaded:
        an interrupted calibration rerun with the same arguments evaluates no point twice.
        A memo of another problem is refused.
    conflict_budget : int, optional
        Points the conflict sweep may ask for when a fit target is not met (default
        ``budget``; each sweep level gets ``6 (n + 1)`` points at least); the sweep runs
        only with two fit targets or more.

    Returns
    -------
    CalibrationResult
        Per-target rows, parameters, sensitivity, conflict and counts.

    Raises
    ------
    ValueError
        A budget below 5 or a worker count below 1; a memo of another problem; a model
        that does not return every target.
    """
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 5:
        raise ValueError(f"budget must be an integer >= 5 evaluations, got {budget!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if conflict_budget is None:
        conflict_budget = budget
    if conflict_budget < 0:
        raise ValueError(f"conflict_budget must be >= 0, got {conflict_budget}")
    memo = Memo(problem, memo_path)
    n = len(problem.parameters)
    if de_sized(budget, n, polish) < 0 and not len(memo):
        # no population to search and no stored point to polish from: nothing to start at
        least = next(b for b in range(budget, budget + 1000) if de_sized(b, n, polish) >= 0)
        raise ValueError(
            f"budget {budget} is below one population of the search over {n} parameters; "
            f"give at least {least}"
        )
    ev = _Evaluator(problem, memo, workers, on_progress)
    fit = np.array(problem.fit_index)
    try:
        u = _minimise(ev, lambda m: ev.residuals(m)[fit], budget, seed, polish)
        assert u is not None  # the budget covers one population at least
        # The answer: the best point the search asked for (not only the optimisers' last).
        u = min(ev.visited, key=lambda k: float(np.sum(ev.residuals(memo.get(k))[fit] ** 2)))
        search_requested = ev.requested
        ev.phase = "sensitivity"
        jac = _sensitivity(ev, u)
        r = np.abs(ev.residuals(ev.one(u))[fit])
        conflict = None
        if np.any(r > 1.0) and len(fit) >= 2 and conflict_budget >= 1:
            ev.phase = "conflict"
            conflict = _conflict(ev, u, conflict_budget, seed, polish, jac)
            # The sweep may find a point that meets every fit target (the search's budget
            # was short, not the model): then that point is the answer and there is no
            # conflict to report.
            met = [k for k, m in ev.seen() if bool(np.all(np.abs(ev.residuals(m)[fit]) <= 1.0))]
            if met:
                u = min(met, key=lambda k: float(np.sum(ev.residuals(memo.get(k))[fit] ** 2)))
                ev.phase = "sensitivity"
                jac = _sensitivity(ev, u)
                conflict = None
    finally:
        ev.close()
    model = memo.get(u)
    assert model is not None
    return build_result(
        problem,
        u,
        model,
        jac,
        conflict,
        requested=ev.requested,
        evaluated=ev.evaluated,
        search_requested=search_requested,
        first_met=ev.first_met,
        seed=seed,
        budget=budget,
    )
