"""The calibration core on toy problems with known answers."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

import numpy as np
import pytest

from microfab.calibrate import CalibrationProblem, FreeParameter, Progress, Target, calibrate

CALLS = {"n": 0}


def consistent_model(p: Mapping[str, float]) -> dict[str, float]:
    """a = x, b = x + y, chk = x * y: a = 1, b = 3 give x = 1, y = 2, so chk = 2."""
    CALLS["n"] += 1
    x, y = p["x"], p["y"]
    return {"a": x, "b": x + y, "chk": x * y}


def consistent(chk: float = 2.0, high: float = 5.0) -> CalibrationProblem:
    return CalibrationProblem(
        [
            Target("a", 1.0, 0.01, "m", "toy: a = x"),
            Target("b", 3.0, 0.01, "m", "toy: b = x + y"),
            Target("chk", chk, 0.05, "m^2", "toy: chk = x y, held back", role="check"),
        ],
        [
            FreeParameter("x", 0.0, high, "m", "assumed: toy"),
            FreeParameter("y", 0.01, 10.0, "m", "assumed: toy, 3 decades", log=True),
        ],
        consistent_model,
    )


def test_consistent_problem_is_met_and_the_check_is_predicted(tmp_path):
    res = calibrate(consistent(), budget=150, seed=1, memo_path=tmp_path / "memo.json")
    assert res.converged
    rows = {t.name: t for t in res.targets}
    assert rows["a"].met and rows["b"].met
    # The check target is reported as a check, predicted (x y = 2) within its tolerance.
    assert rows["chk"].role == "check"
    assert rows["chk"].met, rows["chk"]
    assert res.conflict is None
    assert res.values["x"] == pytest.approx(1.0, abs=0.01)
    assert res.values["y"] == pytest.approx(2.0, abs=0.02)
    header, table = res.as_table()
    assert len(table) == 3 and len(header) == len(table[0])
    doc = json.loads(res.to_json())
    assert doc["converged"] is True and doc["targets"][2]["role"] == "check"


def test_a_check_target_does_not_steer_the_fit(tmp_path):
    memo = tmp_path / "memo.json"
    first = calibrate(consistent(2.0), budget=150, seed=1, memo_path=memo)
    # Another check value: the search asks for exactly the same points (nothing new is
    # evaluated from the memo) and lands on the same one.
    second = calibrate(consistent(50.0), budget=150, seed=1, memo_path=memo)
    assert second.evaluated == 0
    assert [p.normalised for p in second.parameters] == [p.normalised for p in first.parameters]
    assert second.converged
    assert not {t.name: t for t in second.targets}["chk"].met


def conflict_model(p: Mapping[str, float]) -> dict[str, float]:
    return {"a": p["x"], "b": p["x"]}


def test_conflict_found_with_a_monotone_front():
    problem = CalibrationProblem(
        [Target("a", 1.0, 0.1, "m", "toy: needs x = 1"), Target("b", 2.0, 0.1, "m", "toy: x = 2")],
        [FreeParameter("x", 0.0, 3.0, "m", "assumed: toy")],
        conflict_model,
    )
    res = calibrate(problem, budget=60, seed=3)
    assert not res.converged
    c = res.conflict
    assert c is not None and {c.target_a, c.target_b} == {"a", "b"}
    assert "a" in c.finding and "b" in c.finding and "cannot both be met" in c.finding
    front = np.abs(np.array(c.front))
    assert len(front) >= 3
    assert np.all(np.diff(front[:, 0]) > 0) and np.all(np.diff(front[:, 1]) < 0)
    # Best of one with the other met: |x - 1| = 0.9 (or |x - 2| = 0.9), r = 9. The polish
    # meets the hinge to about 1e-3 of r in this toy; 0.2 is ample.
    met_b = front[front[:, 1] <= 1.0 + 1e-9]
    assert met_b[:, 0].min() == pytest.approx(9.0, abs=0.2)


def bound_model(p: Mapping[str, float]) -> dict[str, float]:
    return {"a": p["x"], "b": p["y"]}


def test_a_parameter_pinned_at_its_bound_is_flagged():
    problem = CalibrationProblem(
        [Target("a", 1.5, 0.1, "m", "toy: beyond x's range"), Target("b", 0.5, 0.1, "m", "toy")],
        [
            FreeParameter("x", 0.0, 1.0, "m", "assumed: toy"),
            FreeParameter("y", 0.0, 1.0, "m", "assumed: toy"),
        ],
        bound_model,
    )
    res = calibrate(problem, budget=100, seed=0, conflict_budget=0)
    at = {p.name: p.at_bound for p in res.parameters}
    assert at == {"x": "high", "y": None}
    assert not res.converged and res.conflict is None


def separable_model(p: Mapping[str, float]) -> dict[str, float]:
    return {"A": p["p1"] ** 2, "B": 3.0 * p["p2"], "C": p["p1"] + p["p2"]}


def test_sensitivity_shows_which_parameter_pins_which_target():
    problem = CalibrationProblem(
        [
            Target("A", 4.0, 0.01, "1", "toy: p1 only"),
            Target("B", 3.0, 0.01, "1", "toy: p2 only"),
            Target("C", 3.0, 0.1, "1", "toy: both", role="check"),
        ],
        [
            FreeParameter("p1", 0.0, 5.0, "1", "assumed: toy"),
            FreeParameter("p2", 0.0, 5.0, "1", "assumed: toy"),
        ],
        separable_model,
    )
    res = calibrate(problem, budget=120, seed=2)
    assert res.converged
    assert res.pins == {"A": ("p1",), "B": ("p2",), "C": ("p1", "p2")}
    s = res.sensitivity
    assert s.shape == (3, 2)
    assert abs(s[0, 1]) < 1e-9 and abs(s[1, 0]) < 1e-9  # exact zeros up to round-off
    # dB/du2 = 3 * 5 / 0.01 (r per unit of the normalised coordinate): linear, so the
    # central difference is exact to round-off.
    assert s[1, 1] == pytest.approx(1500.0, rel=1e-6)


def needle_model(p: Mapping[str, float]) -> dict[str, float]:
    return {"peak": math.exp(-(((p["x"] - 0.731) / 1e-4) ** 2))}


def test_not_converged_when_the_residuals_say_so():
    problem = CalibrationProblem(
        [Target("peak", 1.0, 0.01, "1", "toy: a needle 1e-4 wide")],
        [FreeParameter("x", 0.0, 1.0, "1", "assumed: toy")],
        needle_model,
    )
    res = calibrate(problem, budget=12, seed=0)
    assert res.search_requested <= 12
    assert not res.converged and res.worst_fit > 1.0 and res.first_met is None


def test_memo_resumes_and_refuses_another_problem(tmp_path):
    memo = tmp_path / "memo.json"
    CALLS["n"] = 0
    full = calibrate(consistent(), budget=150, seed=4)
    n_full = CALLS["n"]
    assert full.evaluated == n_full > 0

    # Interrupted after a few batches: what was evaluated is on disk.
    seen = []

    def stop(p: Progress) -> None:
        seen.append(p)
        if len(seen) == 4:
            raise KeyboardInterrupt

    CALLS["n"] = 0
    with pytest.raises(KeyboardInterrupt):
        calibrate(consistent(), budget=150, seed=4, memo_path=memo, on_progress=stop)
    n_first = CALLS["n"]
    assert 0 < n_first < n_full and memo.exists()

    CALLS["n"] = 0
    resumed = calibrate(consistent(), budget=150, seed=4, memo_path=memo)
    assert CALLS["n"] == n_full - n_first == resumed.evaluated
    assert resumed.values == full.values

    CALLS["n"] = 0
    again = calibrate(consistent(), budget=150, seed=4, memo_path=memo)
    assert CALLS["n"] == 0 and again.evaluated == 0 and again.requested == full.requested

    with pytest.raises(ValueError, match="another calibration problem") as err:
        calibrate(consistent(high=6.0), budget=150, seed=4, memo_path=memo)
    assert "\n" not in str(err.value)


def test_process_pool_asks_for_the_same_points():
    serial = calibrate(consistent(), budget=100, seed=5)
    pooled = calibrate(consistent(), budget=100, seed=5, workers=2)
    assert pooled.requested == serial.requested
    assert pooled.values == pytest.approx(serial.values, rel=1e-12)


def test_the_conflict_pair_is_the_worst_target_and_what_pulls_against_it():
    from microfab.calibrate.solve import conflict_pair

    # a (worst) and c both depend on x and pull it opposite ways; b (second worst)
    # depends on y alone: the conflict is a against c, not a against b
    r = np.array([3.0, 2.0, -1.5])
    jac = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    assert conflict_pair(r, jac, [0, 1, 2]) == (0, 2)
    # nothing opposes a: the second worst
    assert conflict_pair(np.array([3.0, 2.0, 1.0]), jac, [0, 1, 2]) == (0, 1)


def test_a_small_budget_over_many_parameters_is_refused_not_crashed():
    # eight parameters: SciPy's smallest population is 8 (popsize 1 x 8), not 5
    params = [FreeParameter(f"p{i}", 0.0, 1.0, "1", "assumed: toy") for i in range(8)]
    prob = CalibrationProblem(
        [Target("s", 1.0, 0.1, "1", "toy: the sum")],
        params,
        lambda p: {"s": sum(p.values())},
    )
    with pytest.raises(ValueError, match="give at least"):
        calibrate(prob, budget=7, seed=0, polish=False)
    res = calibrate(prob, budget=16, seed=0, polish=False, conflict_budget=0)
    assert res.requested >= 8 and len(res.parameters) == 8
