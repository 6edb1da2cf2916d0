"""Stage 1 (seed 002 eqs. 8-12) on a synthetic linear model: constraints, T, refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("casadi")

from microfab.geometry.shapes import circle, rectangle
from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.linear_steps import balanced, rk4_matrices
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Error, Stage1Settings, solve_stage1


def axis_model(wn: float, zeta: float, wz: float, d: float) -> ContinuousModel:
    """Per-axis ``(d s² + b1 s + wn²) / (s² + 2ζ wn s + wn²)``: unit static gain, feedthrough d."""
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    b = np.array([[0.0], [1.0]])
    # y = d u + c z, with numerator d s² + wz s + wn²
    c = np.array([[wn**2 - d * wn**2, wz - d * 2 * zeta * wn]])
    return ContinuousModel(a=a, b=b, c=c, d=np.array([[d]]))


def stage_model(d: float = 0.9) -> ContinuousModel:
    mx, my = axis_model(70.0, 0.5, 40.0, d), axis_model(60.0, 0.6, 30.0, d)
    z = np.zeros((2, 2))
    return ContinuousModel(
        a=np.block([[mx.a, z], [z, my.a]]),
        b=np.block([[mx.b, np.zeros((2, 1))], [np.zeros((2, 1)), my.b]]),
        c=np.block([[mx.c, np.zeros((1, 2))], [np.zeros((1, 2)), my.c]]),
        d=np.diag([d, d]),
    )


def check_constraints(res, problem, model, tol=1e-6):
    """12b-12j from the result's arrays, in the model's own coordinates (independent)."""
    t, rho, gamma = res.t, res.rho, res.gamma
    dt = np.diff(t)
    assert np.all(dt > 0)
    # 12b-12c: simulate ρ through RK4 from rest on the model as given (not balanced)
    g0 = model.d - model.c @ np.linalg.solve(model.a, model.b)
    rest = np.array(res.info["rho_rest"])
    z = -np.linalg.solve(model.a, model.b @ rest)
    sim = [model.c @ z + model.d @ rho[0]]
    for k in range(len(t) - 1):
        ph, ga = rk4_matrices(model.a, model.b, dt[k], res.info["rk4_substeps"])
        z = ph @ z + ga @ rho[k]
        sim.append(model.c @ z + model.d @ rho[k + 1])
    sim = np.array(sim)
    assert np.abs(sim - gamma).max() < 1e-9
    assert np.allclose(g0 @ rest, res.target[0], atol=1e-12)  # at rest on Ξ_0
    # 12g, 12h: along the tangent 0, across within μ
    tan = problem.path.tangent(res.s)
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    err = gamma - res.target
    mu = problem.tolerance_m
    assert np.abs(np.sum(err * tan, axis=1)).max() <= tol * mu
    assert np.abs(res.deviation).max() <= mu * (1 + tol)
    # 12i, 12j (unequal steps) with the rest start
    v = np.diff(gamma, axis=0) / dt[:, None]
    assert np.abs(v).max() <= problem.v_max * (1 + tol)
    acc = 2 * (v[1:] - v[:-1]) / (dt[1:] + dt[:-1])[:, None]
    assert np.abs(acc).max() <= problem.a_max * (1 + 1e-5)
    assert np.abs(gamma[1] - gamma[0]).max() <= problem.a_max * dt[0] ** 2 * (1 + 1e-5)


@pytest.fixture(scope="module")
def square_problem():
    path = rectangle(8e-3, 6e-3, center=(0.01, -0.02), corner_radius=0.5e-3)
    return ContourProblem(path, a_max=1.0, tolerance_m=20e-6)


def test_balanced_keeps_the_transfer_function():
    m = stage_model()
    b = balanced(m)
    for s in (1j, 10j, 100j):
        g = m.c @ np.linalg.solve(s * np.eye(4) - m.a, m.b) + m.d
        gb = b.c @ np.linalg.solve(s * np.eye(4) - b.a, b.b) + b.d
        assert np.allclose(g, gb, atol=1e-10)


def test_rk4_matrices_are_one_rk4_step():
    m = stage_model()
    rng = np.random.default_rng(1)
    z, u, h = rng.normal(size=4), rng.normal(size=2), 3e-3

    def f(x):
        return m.a @ x + m.b @ u

    k1 = f(z)
    k2 = f(z + h / 2 * k1)
    k3 = f(z + h / 2 * k2)
    k4 = f(z + h * k3)
    ph, ga = rk4_matrices(m.a, m.b, h)
    assert np.allclose(ph @ z + ga @ u, z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), atol=1e-14)


def test_stage1_meets_every_constraint_and_finds_a_time(square_problem):
    model = stage_model()
    res = solve_stage1(square_problem, model, Stage1Settings(n=150))
    assert res.status == "Solve_Succeeded"
    check_constraints(res, square_problem, model)
    # the tolerance or an acceleration bound is active somewhere (else it could go faster)
    assert res.active["tolerance"].any() or res.active["acceleration"].any()
    # a lower bound: 28 mm at most 1.5 m/s, and at least the time to brake from rest
    assert res.duration > square_problem.length / (1.5 * np.sqrt(2))
    assert res.s[0] == 0 and res.s[-1] == pytest.approx(square_problem.length)
    assert res.s_of_t(np.array([-1.0, 1e3])) == pytest.approx([0.0, square_problem.length])


def test_stage1_time_shrinks_like_the_root_of_a_max(square_problem):
    model = stage_model()
    t1 = solve_stage1(square_problem, model, Stage1Settings(n=150)).duration
    p3 = dataclasses.replace(square_problem, a_max=3.0)
    res3 = solve_stage1(p3, model, Stage1Settings(n=150))
    check_constraints(res3, p3, model)
    assert 0.5 < res3.duration / t1 < 0.7  # acceleration-limited: ~ 1/sqrt(3) = 0.577


def test_stage1_converges_in_n_and_from_the_seed_start():
    p = ContourProblem(circle(3e-3), a_max=2.0, tolerance_m=20e-6)
    model = stage_model()
    t_a = solve_stage1(p, model, Stage1Settings(n=100)).duration
    t_b = solve_stage1(p, model, Stage1Settings(n=200)).duration
    assert abs(t_b / t_a - 1) < 0.01
    t_c = solve_stage1(p, model, Stage1Settings(n=100, warm="constant")).duration
    assert abs(t_c / t_a - 1) < 0.01


def test_stage1_without_feedthrough():
    p = ContourProblem(circle(3e-3), a_max=2.0, tolerance_m=50e-6)
    model = stage_model(d=0.0)
    res = solve_stage1(p, model, Stage1Settings(n=80))
    check_constraints(res, p, model)


def test_stage1_not_converged_keeps_the_last_iterate(square_problem):
    with pytest.raises(Stage1Error, match=r"did not converge.*max_iter") as info:
        solve_stage1(square_problem, stage_model(), Stage1Settings(n=60, max_iter=2))
    assert info.value.result is not None and info.value.result.n == 60


def test_stage1_reports_the_constraints_measured_on_its_answer(square_problem):
    """Eqs. 12b-12j on the returned input, re-simulated: every one holds (issue 43)."""
    model = stage_model()
    res = solve_stage1(square_problem, model, Stage1Settings(n=150))
    feas = res.feasibility
    assert res.converged and feas.feasible and feas.worst is None
    names = {r.constraint: r for r in feas.residuals}
    assert set(names) == {"dynamics", "along-track", "tolerance", "workspace", "velocity",
                          "acceleration"}  # fmt: skip
    assert names["tolerance"].equation == "12h" and names["tolerance"].unit == "µm"
    assert names["tolerance"].largest == pytest.approx(np.abs(res.deviation).max() * 1e6, abs=1e-3)
    assert names["dynamics"].largest < 1e-3  # µm: the returned γ is the model's output
    s = res.summary()
    assert s["converged"] is True and s["feasibility"]["feasible"] is True


def test_a_broken_answer_is_named_by_its_constraint(square_problem):
    """The answer moved 30 µm along the normal at one knot: 12h broken there, by 10 µm."""
    from microfab.optimize.stage1_check import stage1_feasibility

    model = stage_model()
    res = solve_stage1(square_problem, model, Stage1Settings(n=150))
    k = 40
    tan = square_problem.path.tangent(res.s[k : k + 1])[0]
    nor = np.array([-tan[1], tan[0]]) / np.linalg.norm(tan)
    target = res.target[k] + 30e-6 * nor
    # the input of knot k set so that the output there lands on `target` (D is diagonal)
    rho = res.rho.copy()
    rho[k] += np.linalg.solve(model.d, target - res.gamma[k])
    feas = stage1_feasibility(square_problem, model, t=res.t, s=res.s, rho=rho,
                              gamma=res.gamma, rho_rest=np.array(res.info["rho_rest"]),
                              substeps=res.info["rk4_substeps"])  # fmt: skip
    assert not feas.feasible
    tol = {r.constraint: r for r in feas.residuals}["tolerance"]
    assert not tol.holds and tol.sample == k and tol.time_s == pytest.approx(res.t[k])
    assert tol.excess == pytest.approx(10.0, abs=0.5)  # µm beyond μ = 20 µm
    assert "eq. 12h (tolerance) broken by" in feas.describe()


def test_ipopt_success_alone_is_not_converged(square_problem, monkeypatch):
    """An answer IPOPT calls solved but that breaks a constraint is refused, named."""
    from microfab.optimize import stage1_check
    from microfab.optimize.feasibility import Feasibility, measure

    def broken(problem, model, **kw):
        rows = np.array([19.0, 25.0])  # µm against μ = 20 µm
        tol = measure("tolerance", "12h", "µm", rows, 20.0, samples=np.array([0, 1]),
                      times=np.array([0.0, 0.01]))  # fmt: skip
        return Feasibility((tol,))

    monkeypatch.setattr(stage1_check, "stage1_feasibility", broken)
    says = r"IPOPT reports Solve_Succeeded, but its answer breaks.*12h \(tolerance\) broken by 5"
    with pytest.raises(Stage1Error, match=says) as info:
        solve_stage1(square_problem, stage_model(), Stage1Settings(n=60))
    res = info.value.result
    assert res.status == "Solve_Succeeded" and not res.converged
    assert res.summary()["converged"] is False


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"n": 5}, "n must be an integer >= 10"),
        ({"n": 10.5}, "n must be an integer"),
        ({"smoothing": -1.0}, "smoothing"),
        ({"warm": "zero"}, "warm must be"),
        ({"max_iter": 0}, "max_iter"),
        ({"tol": 0.0}, "tol"),
    ],
)
def test_settings_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        Stage1Settings(**kw)
