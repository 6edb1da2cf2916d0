"""The kept HiGHS model (warm starts) and the v/a starting vertex agree with a cold LP."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from scipy import sparse
from scipy.optimize import linprog

from microfab.core.limits import MachineLimits
from microfab.geometry.shapes import rectangle
from microfab.trajectory.highs import HighsSession
from microfab.trajectory.optimal import (
    HighsLP,
    PlanningError,
    _build_grid,
    _greatest_va,
    _Problem,
)

pytestmark = pytest.mark.skipif(not HighsSession().available, reason="no HiGHS bindings")


def cold(c, A, b, bounds) -> np.ndarray:  # type: ignore[no-untyped-def]
    res = linprog(c, A_ub=A, b_ub=b, bounds=bounds, method="highs")
    assert res.status == 0
    return res.x


def chain_lp(n: int = 60, seed: int = 0):  # type: ignore[no-untyped-def]
    """max sum x s.t. |x_{k+1} - x_k| <= d_k (both signs as rows), 0 <= x <= cap."""
    rng = np.random.default_rng(seed)
    rows = sparse.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
    A = sparse.vstack([rows, -rows]).tocsr()
    d = rng.uniform(0.1, 1.0, n - 1)
    cap = rng.uniform(0.0, 5.0, n)
    cap[0] = cap[-1] = 0.0
    return -np.ones(n), A, np.concatenate([d, d]), np.column_stack([np.zeros(n), cap])


def test_session_matches_linprog_cold_and_after_bound_changes() -> None:
    c, A, b, bounds = chain_lp()
    s = HighsSession()
    x, status = s.solve(c, A, b, bounds)
    assert status == ""
    np.testing.assert_allclose(x, cold(c, A, b, bounds), rtol=1e-12, atol=1e-12)
    assert s.holds(A)
    for k in range(4):  # change a few row and column bounds: hot start from the basis
        b = b.copy()
        b[3 * k] *= 0.5
        bounds = bounds.copy()
        bounds[10 + k, 1] *= 0.3
        x, status = s.solve(c, A, b, bounds)
        np.testing.assert_allclose(x, cold(c, A, b, bounds), rtol=1e-12, atol=1e-12)


def test_session_takes_a_starting_point_good_or_bad() -> None:
    c, A, b, bounds = chain_lp(seed=1)
    want = cold(c, A, b, bounds)
    for guess in (want, 0.5 * want, np.zeros_like(want)):
        x, _ = HighsSession().solve(c, A, b, bounds, x0=guess)
        np.testing.assert_allclose(x, want, rtol=1e-12, atol=1e-12)


def test_session_reports_an_infeasible_lp_and_pickles_without_its_model() -> None:
    c, A, b, bounds = chain_lp()
    bounds = bounds.copy()
    bounds[5] = (2.0, 1.0)  # lower above upper
    s = HighsSession(time_limit=5.0)
    x, status = s.solve(c, A, b, bounds)
    assert x is None and status
    assert not s.holds(A)
    back = pickle.loads(pickle.dumps(s))
    assert back.time_limit == 5.0 and not back.holds(A)
    with pytest.raises(PlanningError, match="HiGHS LP failed"):
        HighsLP().solve(c, A, b, bounds, x0=np.zeros(c.size))


def test_va_starting_vertex_is_the_lp_optimum_on_straight_paths() -> None:
    """Lines only: every acceleration row bounds one node by the other, so the passes
    find the greatest element, which is the LP's optimum."""
    stage = MachineLimits.seed002_stage()
    g = _build_grid(rectangle(0.04, 0.03), 400)
    prob = _Problem(g=g, limits=stage, feed=None, margin=0.01, solver=HighsLP())
    n = g.s.size
    cap = prob.caps(np.ones(n))
    mul = np.repeat(np.ones(n - 1), 4)
    x0 = _greatest_va(cap, prob.va_alpha, prob.va_beta, mul, 4)
    b = np.concatenate([mul, mul])
    bounds = np.column_stack([np.zeros(n), cap])
    want = cold(-prob.va_weights, prob.va_rows, b, bounds)
    np.testing.assert_allclose(x0, want, rtol=1e-9, atol=1e-12 * want.max())
    assert np.max(prob.va_rows @ x0 - b) <= 1e-9


def test_unusable_bindings_fall_back_to_linprog(monkeypatch: pytest.MonkeyPatch) -> None:
    c, A, b, bounds = chain_lp(seed=2)
    lp = HighsLP()

    def broken(*args: object, **kwargs: object) -> None:
        raise AttributeError("no such method")

    monkeypatch.setattr(lp._session, "solve", broken)
    with pytest.warns(UserWarning, match="linprog"):
        x = lp.solve(c, A, b, bounds, x0=np.zeros(c.size))
    np.testing.assert_allclose(x, cold(c, A, b, bounds), rtol=1e-12, atol=1e-12)
    assert not lp._session.available
