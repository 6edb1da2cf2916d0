"""SDIRK2 against theory: tableau, order of convergence, L-stability, step-size control."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.sim.integrators import SDIRK2, DenseProblem, StepResult

GAMMA = 1.0 - 1.0 / math.sqrt(2.0)


def _linear(a: np.ndarray, **tol: float) -> DenseProblem:
    return DenseProblem(lambda t, y: a @ y, lambda t, y: a, **tol)


def _fixed_steps(problem: DenseProblem, y0: np.ndarray, t_end: float, n: int) -> np.ndarray:
    sdirk = SDIRK2()
    y, h = y0.copy(), t_end / n
    for k in range(n):
        out = sdirk.step(problem, k * h, y, h)
        assert out.y is not None
        y = out.y
    return y


def _stability(z: complex) -> complex:
    # R(z) = 1 + z b^T (I - z A)^{-1} 1 for Alexander's SDIRK2
    return (1.0 + (1.0 - 2.0 * GAMMA) * z) / (1.0 - GAMMA * z) ** 2


def test_tableau_order_conditions_and_stiff_accuracy() -> None:
    tab = SDIRK2.tableau()
    assert SDIRK2.gamma == pytest.approx(GAMMA, abs=1e-16)
    np.testing.assert_allclose(tab.a.sum(axis=1), tab.c, atol=1e-15)
    assert tab.b.sum() == pytest.approx(1.0, abs=1e-15)  # order 1
    assert tab.b @ tab.c == pytest.approx(0.5, abs=1e-15)  # order 2
    assert tab.b_hat.sum() == pytest.approx(1.0, abs=1e-15)  # embedded: order 1
    assert tab.b_hat @ tab.c != pytest.approx(0.5)  # ... and not 2
    np.testing.assert_array_equal(tab.a[-1], tab.b)  # stiffly accurate
    # R(inf) = 1 - b^T A^{-1} 1 = 0: L-stable
    assert 1.0 - tab.b @ np.linalg.solve(tab.a, np.ones(2)) == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize("z", [-0.1, -1.0, -10.0, -1e3, 0.5, -0.3 + 2.0j])
def test_one_step_is_the_stability_function(z: complex) -> None:
    # y' = lambda y as a real 2x2 system (x + i y): one step multiplies by R(h lambda)
    lam = complex(z)
    a = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]])
    out = SDIRK2().step(_linear(a), 0.0, np.array([1.0, 0.0]), 1.0)
    assert out.y is not None
    r = _stability(lam)
    np.testing.assert_allclose(out.y, [r.real, r.imag], rtol=1e-12, atol=1e-15)


def test_second_order_convergence_on_a_linear_ode() -> None:
    # damped rotation, exact solution by the matrix exponential
    a = np.array([[-0.5, 2.0], [-2.0, -0.5]])
    y0 = np.array([1.0, 0.0])
    t_end = 2.0
    w, v = np.linalg.eig(a)
    exact = (v @ np.diag(np.exp(w * t_end)) @ np.linalg.solve(v, y0)).real
    errs = [
        np.linalg.norm(_fixed_steps(_linear(a), y0, t_end, n) - exact) for n in (40, 80, 160, 320)
    ]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    np.testing.assert_allclose(orders, SDIRK2.order, atol=0.05)


def test_error_estimate_is_second_order_in_h() -> None:
    # the embedded solution is first order: the local estimate shrinks like h^2
    a = np.array([[-1.0, 0.3], [0.0, -0.2]])
    p = _linear(a, rtol=1.0, atol=1.0)
    y0 = np.array([1.0, 2.0])
    est = [SDIRK2().step(p, 0.0, y0, h).error for h in (0.02, 0.01, 0.005)]
    ratios = np.array(est[:-1]) / np.array(est[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.05)


def test_l_stability_on_a_stiff_decay() -> None:
    # y' = -1e6 (y - cos t): one step of h = 0.1 damps any initial layer by
    # |R(-1e5)| ~ 5e-5 and lands near the slow manifold y ~ cos t; the trapezoidal rule
    # (A- but not L-stable) would carry the layer on with a factor near -1.
    k = 1e6
    p = DenseProblem(lambda t, y: -k * (y - math.cos(t)), lambda t, y: np.array([[-k]]))
    h = 0.1
    runs = []
    for y0 in (1.0, 10.0):
        y, t = np.array([y0]), 0.0
        for _ in range(5):
            out = SDIRK2().step(p, t, y, h)
            assert out.y is not None
            y, t = out.y, t + h
            assert abs(y[0] - math.cos(t)) < 1e-3
        runs.append(y[0])
    # the layer of 9 is gone after one step, the runs agree to round-off after five
    assert abs(runs[1] - runs[0]) < 1e-12
    assert abs(_stability(-k * h)) < 1e-4
    assert abs(_stability(-1e12)) < 1e-10


def test_step_size_control() -> None:
    s = SDIRK2()
    assert s.step_after_acceptance(1.0, 0.0) == 3.0  # error floor, growth capped
    assert s.step_after_acceptance(1.0, 1.0) == pytest.approx(0.9)
    assert s.step_after_acceptance(1.0, 1e4) == 0.2
    assert s.step_after_rejection(1.0, None) == 0.25
    assert s.step_after_rejection(1.0, 4.0) == pytest.approx(0.45)
    assert s.step_after_rejection(1.0, math.nan) == 0.2
    assert s.accepts(1.0) and not s.accepts(1.0 + 1e-12) and not s.accepts(math.nan)
    custom = SDIRK2(safety=0.8, max_factor=2.0, failure_factor=0.5)
    assert custom.step_after_acceptance(1.0, 0.0) == 2.0
    assert custom.step_after_rejection(2.0, None) == 1.0


def test_adaptive_integration_meets_the_tolerance() -> None:
    # y' = -y + sin t, y(0) = 1; exact y = 1.5 e^-t + (sin t - cos t) / 2
    p = DenseProblem(lambda t, y: -y + math.sin(t), lambda t, y: -np.eye(1), rtol=1e-6, atol=1e-8)
    s = SDIRK2()
    t, y, h, t_end = 0.0, np.array([1.0]), 1.0, 5.0
    accepted = rejected = 0
    while t < t_end - 1e-12:
        h = min(h, t_end - t)
        out = s.step(p, t, y, h)
        if out.y is None or not s.accepts(out.error):
            rejected += 1
            h = s.step_after_rejection(h, None if out.y is None else out.error)
            continue
        accepted += 1
        t, y = t + h, out.y
        h = s.step_after_acceptance(h, out.error)
    exact = 1.5 * math.exp(-t_end) + 0.5 * (math.sin(t_end) - math.cos(t_end))
    assert rejected >= 1  # the first step of 1.0 is far too long
    assert 20 < accepted < 2000
    assert abs(y[0] - exact) < 1e-4


def test_failures_are_reported_not_raised() -> None:
    s = SDIRK2()
    bad_rhs = DenseProblem(lambda t, y: np.full_like(y, math.nan), lambda t, y: -np.eye(1))
    out = s.step(bad_rhs, 0.0, np.array([1.0]), 0.1)
    assert out.failed and out.error == math.inf
    # a Newton iteration that cannot converge: cubic right-hand side, linear Jacobian
    stiff = DenseProblem(lambda t, y: -(y**3), lambda t, y: np.zeros((1, 1)))
    out = SDIRK2(newton_max_iter=2).step(stiff, 0.0, np.array([10.0]), 1.0)
    assert out.failed
    assert StepResult(np.zeros(1), 0.5).failed is False


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"newton_tol": 0.0}, "newton_tol"),
        ({"newton_max_iter": 0}, "newton_max_iter"),
        ({"newton_max_iter": 2.5}, "newton_max_iter"),
        ({"safety": 1.5}, "safety"),
        ({"min_factor": 1.0}, "min_factor"),
        ({"max_factor": 0.5}, "max_factor"),
        ({"failure_factor": 0.0}, "failure_factor"),
        ({"min_step": math.nan}, "min_step"),
    ],
)
def test_settings_are_validated(kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        SDIRK2(**kwargs)
