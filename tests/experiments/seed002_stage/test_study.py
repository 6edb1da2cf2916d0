"""Seed 002 Table II's letters columns for the linear model, on the calibrated twin.

The networks' columns need a 15-minute training each (`benchmarks/bench_ann.py`, the
``stage-identify`` job); the linear model's need a fit of seconds, so they are checked
here on 120 s of random data (the seed's 600 s give the same to within 1 %).
Acceptance (issue 17): σ within ×0.5…×2 of the seed's, |μ| ≤ max(2 µm, σ/3).
"""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.seed002_stage import paper
from microfab.experiments.seed002_stage.study import CaseSettings, StudySettings, run_study
from microfab.machines.xy_stage.identify import LinearSettings


@pytest.fixture(scope="module")
def study():
    s = StudySettings(
        linear=LinearSettings(total_s=120.0),
        orders=(),
        ann=None,
        coupling=False,
        classic=False,
        cases=CaseSettings(sweep_a_max=()),
    )
    return run_study(s)


def _check(study, column: str, axis: str) -> tuple[float, float, float]:
    a = {"letters_1": 1.0, "letters_3": 3.0}[column]
    err = study.letters(a, "linear")
    j = "xy".index(axis)
    seed = paper.TABLE_II["linear"][axis][column].sigma_m
    return float(err.mean[j]), float(err.std[j]), seed


#: Measured on the twin calibrated on the core (120 s of data): σ on the letters at 1 m/s².
_LETTERS_1 = (
    "on the twin calibrated on the core (issue 46; linear σ on its training data 33.9 / "
    "48.7 µm against Table II's 48.0 / 156.3, 1 of its 6 fit targets met) the linear "
    "error on the letters at 1 m/s² is {} of the seed's {}"
)


@pytest.mark.parametrize(
    "axis",
    [
        pytest.param(
            ax,
            marks=pytest.mark.xfail(
                raises=AssertionError, strict=True, reason=_LETTERS_1.format(got, seed)
            ),
        )
        for ax, got, seed in (("x", "12.6 µm (0.42)", "30.1"), ("y", "22.8 µm (0.21)", "108.5"))
    ],
)
def test_linear_on_the_letters_at_1(study, axis):
    mu, sigma, seed = _check(study, "letters_1", axis)  # seed 30.1 / 108.5 µm
    assert 0.5 * seed <= sigma <= 2 * seed
    assert abs(mu) <= max(2e-6, sigma / 3)


def test_linear_on_the_letters_at_3_x(study):
    mu, sigma, seed = _check(study, "letters_3", "x")  # seed 57.2 µm
    assert 0.5 * seed <= sigma <= 2 * seed
    assert abs(mu) <= max(2e-6, sigma / 3)


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="the seed's linear error on the letters doubles from 1 to 3 m/s² (108.5 -> 229.4 "
    "µm on y); on the twin it grows from 22.4 to 59.1 µm (600 s of data: 0.26 of the "
    "seed's), as the twin's y axis falls short of Table II column 1 too (48.7 against "
    "156.3 µm, test_calibration)",
)
def test_linear_on_the_letters_at_3_y(study):
    _, sigma, seed = _check(study, "letters_3", "y")  # seed 229.4 µm
    assert 0.5 * seed <= sigma <= 2 * seed


def test_letters_run_within_table_i_and_pool_four_letters(study):
    assert all(c.limited == 0 for c in study.cases)
    err = study.letters(1.0, "linear")
    assert len(err.per_run) == 4
    assert np.isfinite(err.std).all()
