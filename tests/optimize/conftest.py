"""Shared fixtures of the optimisation tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def case(tiny_models):
    """Stage 2's inputs on a 2 mm circle at 2 m/s²: models, problem, targets, start input.

    The tiny models of ``tiny_models``; stage 1 at N = 80 sampled at the networks' 400 Hz:
    ``(models, problem, targets (M, 2) m, rho (M, 2) m)``.
    """
    pytest.importorskip("casadi")
    from microfab.geometry.shapes import circle
    from microfab.optimize.models import load_models
    from microfab.optimize.problem import ContourProblem
    from microfab.optimize.stage1 import Stage1Settings, solve_stage1

    d, _ = tiny_models
    models = load_models(d)
    problem = ContourProblem(circle(2e-3), a_max=2.0, tolerance_m=20e-6)
    st1 = solve_stage1(problem, models.linear, Stage1Settings(n=80))
    _t, s, rho = st1.sample(400.0)
    return models, problem, problem.path.point(s)[1:], rho[:-1]
