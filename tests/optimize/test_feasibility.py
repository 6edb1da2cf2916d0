"""Constraints measured on a solution (optimize.feasibility): residual, where, worst."""

from __future__ import annotations

import json

import numpy as np
import pytest

from microfab.optimize.feasibility import FEASIBILITY_RTOL, Feasibility, Residual, measure


def _acc(values, bound=2.0):
    k = np.arange(1, len(values) + 1)
    return measure("acceleration", "14f", "m/s²", np.array(values), bound, samples=k,
                   times=k / 400.0)  # fmt: skip


def test_a_residual_is_the_largest_row_and_where_it_is():
    r = _acc([1.0, 2.5, 1.9, 3.0, 2.0005])
    assert (r.largest, r.bound, r.sample) == (3.0, 2.0, 4)
    assert r.excess == pytest.approx(1.0) and r.time_s == pytest.approx(4 / 400)
    assert r.rows == 5 and r.rows_over == 2  # 2.0005 is within the allowed 2e-3
    assert not r.holds and r.relative == pytest.approx(0.5)
    assert r.allowed == pytest.approx(FEASIBILITY_RTOL * 2.0)
    assert "eq. 14f (acceleration) broken by 1 m/s² beyond 2 m/s² at sample 4" in r.describe()
    ok = _acc([1.0, 2.0 + 0.9 * FEASIBILITY_RTOL * 2.0])
    assert ok.holds and ok.relative == 0.0 and ok.rows_over == 0


def test_the_worst_constraint_is_the_largest_relative_excess():
    k = np.arange(1, 4)
    tol = measure("tolerance", "14c", "µm", np.array([10.0, 50.0, 30.0]), 20.0, samples=k,
                  times=k / 400.0)  # fmt: skip
    acc = _acc([1.0, 3.0, 2.0])  # 1 m/s² beyond 2: 0.5 of its bound; tolerance: 1.5
    feas = Feasibility((acc, tol))
    assert not feas.feasible and feas.worst is tol
    # the L1 violation: every row beyond, in units of its bound: 0.5 + (1.5 + 0.5)
    assert (acc.violation, tol.violation) == (pytest.approx(0.5), pytest.approx(2.0))
    assert feas.score == pytest.approx(2.5)
    assert feas.describe().startswith("eq. 14c (tolerance) broken by 30 µm")
    assert Feasibility((_acc([1.0]),)).worst is None
    assert Feasibility((_acc([1.0]),)).score == 0.0


def test_a_non_finite_prediction_is_broken_and_json_ready():
    r = _acc([1.0, np.nan, 1.0])
    assert not r.holds and r.sample == 2 and r.rows_over == 1
    d = Feasibility((r,)).as_dict()
    json.dumps(d, allow_nan=False)
    assert Residual.from_dict(d["residuals"]["acceleration"]) == r


def test_a_zero_bound_needs_a_scale():
    with pytest.raises(ValueError, match="scale of workspace must be positive"):
        measure("workspace", "14d", "µm", np.zeros(3), 0.0, samples=np.arange(3),
                times=np.zeros(3))  # fmt: skip
