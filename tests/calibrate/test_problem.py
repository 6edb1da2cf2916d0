"""Bad calibration problems are refused on one line; the scales and fingerprint hold."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.calibrate import CalibrationProblem, FreeParameter, Target, calibrate


def model(p):
    return {"a": p["x"], "b": p["x"]}


A = Target("a", 1.0, 0.1, "m", "toy")
B = Target("b", 1.0, 0.1, "m", "toy", role="check")
X = FreeParameter("x", 0.0, 2.0, "m", "assumed: toy")


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Target("a", 1.0, 0.0, "m", "toy"), "tolerance must be > 0"),
        (lambda: Target("a", math.nan, 0.1, "m", "toy"), "must be finite"),
        (lambda: Target("a", 1.0, 0.1, "m", " "), "source must be a non-empty text"),
        (lambda: Target("a", 1.0, 0.1, "m", "toy", role="guess"), "role must be"),
        (lambda: FreeParameter("x", 2.0, 2.0, "m", "assumed"), "must be below high bound"),
        (lambda: FreeParameter("x", 0.0, math.inf, "m", "assumed"), "must be finite"),
        (lambda: FreeParameter("x", 0.0, 1.0, "m", "assumed", log=True), "needs bounds > 0"),
        (lambda: CalibrationProblem([A, A], [X], model), "target names must be unique"),
        (lambda: CalibrationProblem([A], [X, X], model), "parameter names must be unique"),
        (lambda: CalibrationProblem([B], [X], model), "at least one target with role 'fit'"),
        (lambda: CalibrationProblem([A], [], model), "at least one free parameter"),
        (lambda: CalibrationProblem([A], [X], None), "evaluate must be callable"),
        (lambda: calibrate(CalibrationProblem([A], [X], model), budget=4, seed=0), "budget"),
        (
            lambda: calibrate(CalibrationProblem([A], [X], model), budget=10, seed=0, workers=0),
            "workers",
        ),
        (
            lambda: calibrate(
                CalibrationProblem([A, Target("c", 1.0, 0.1, "m", "toy")], [X], model),
                budget=10,
                seed=0,
            ),
            "no value for target",
        ),
    ],
)
def test_bad_problem_refused_on_one_line(build, message):
    with pytest.raises(ValueError, match=message) as err:
        build()
    assert "\n" not in str(err.value)


def test_log_scale_round_trip_and_fingerprint():
    p = FreeParameter("k", 1e-3, 1.0, "N/m", "assumed: 3 decades", log=True)
    assert p.value(0.0) == pytest.approx(1e-3, rel=1e-12)
    assert p.value(0.5) == pytest.approx(math.sqrt(1e-3), rel=1e-12)
    assert p.normalised(p.value(0.3)) == pytest.approx(0.3, abs=1e-12)
    one = CalibrationProblem([A, B], [X], model)
    # Target values and roles do not change what the model returns: same fingerprint.
    other_values = CalibrationProblem(
        [Target("a", 5.0, 1.0, "m", "toy", role="check"), Target("b", 1.0, 0.1, "m", "toy")],
        [X],
        model,
    )
    assert one.fingerprint() == other_values.fingerprint()
    wider = FreeParameter("x", 0.0, 3.0, "m", "assumed: toy")
    assert one.fingerprint() != CalibrationProblem([A, B], [wider], model).fingerprint()
    assert one.fingerprint() != CalibrationProblem([A, B], [X], model, identity="v2").fingerprint()


def nonfinite_model(p):
    return {"a": p["x"] if p["x"] < 1.5 else math.nan}


def test_a_diverging_model_is_steered_away_from():
    problem = CalibrationProblem([Target("a", 1.4, 0.1, "m", "toy")], [X], nonfinite_model)
    res = calibrate(problem, budget=40, seed=0)
    assert res.converged and res.values["x"] == pytest.approx(1.4, abs=0.1)
    assert '"model": null' not in res.to_json()


def test_a_one_sided_target_is_met_on_its_good_side():
    floor = Target("share", 0.95, 0.01, "1", "seed: 'generally below'", side="at least")
    assert floor.residual(0.99) == 0.0 and floor.residual(0.95) == 0.0
    assert floor.residual(0.93) == pytest.approx(-2.0)
    ceiling = Target("pp", 5.0, 0.5, "um", "project target", side="at most")
    assert ceiling.residual(1.0) == 0.0 and ceiling.residual(6.0) == pytest.approx(2.0)
    assert floor.shown == ">= 0.95" and ceiling.shown == "<= 5"
    prob = CalibrationProblem(
        [floor, ceiling],
        [FreeParameter("x", 0.0, 1.0, "1", "assumed: toy")],
        lambda p: {"share": p["x"], "pp": 10 * p["x"]},
    )
    r = prob.residuals(np.array([0.9, 4.0]))
    assert r[0] == pytest.approx(-5.0) and r[1] == 0.0
    with pytest.raises(ValueError, match="side"):
        Target("t", 1.0, 0.1, "1", "toy", side="above")  # type: ignore[arg-type]
