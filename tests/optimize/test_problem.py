"""ContourProblem and the rule for N (seed 002 eq. 8)."""

from __future__ import annotations

import pytest

from microfab.geometry.shapes import circle
from microfab.optimize.problem import ContourProblem, n_points


def test_n_points_rule():
    assert n_points(20.36e-3, 20e-6) == 1019  # the letter r of our sizing: the seed's N ≈ 10³
    assert n_points(1e-3, 20e-6) == 200
    assert n_points(1.0, 20e-6) == 2000
    with pytest.raises(ValueError, match="tolerance"):
        n_points(1e-2, 0.0)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"a_max": 0.0}, "a_max must lie in"),
        ({"a_max": 40.5}, "a_max must lie in"),
        ({"a_max": float("nan")}, "a_max"),
        ({"tolerance_m": 0.0}, "tolerance"),
        ({"tolerance_m": -1e-6}, "tolerance"),
        ({"tolerance_m": 2e-3}, "tolerance"),
    ],
)
def test_bad_bounds_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        ContourProblem(circle(1e-3), **kw)


def test_outside_the_workspace_names_the_axis():
    with pytest.raises(ValueError, match=r"y = 190\.500 mm beyond 190\.000 mm"):
        ContourProblem(circle(1e-3, center=(0.0, 0.1895)))
    p = ContourProblem(circle(1e-3), a_max=40.0)
    assert p.closed and p.v_max == 1.5 and p.length == pytest.approx(2e-3 * 3.141592653589793)
