"""Stage 1's times on the twin's identified linear model against Table III (seed 002 §V).

The letter height and the chord are the job's sizing step on this model (stage 1 gives
"r" 0.807 s and the airfoil 1.322 s at 1 m/s²; `sizing.reference_sizes`, 18.95 mm and
106.3 mm, pinned here to keep the test short: the step itself is checked on a coarse
grid in `test_sizing_step_reaches_its_target`, whose sizes then differ by up to 9 %).
Everything else is a check: the other letters' times within ±20 % of Table III,
T(3)/T(1) = 0.586 ± 0.04 for every letter (seed 0.59), the airfoil at 2 and 3 m/s² within
±15 % of 1.081 and 1.024 s (issue 18).
"""

from __future__ import annotations

import pytest

pytest.importorskip("casadi")

from microfab.experiments.seed002_reference import paper
from microfab.machines.xy_stage.cases import CaseSizes, case_paths
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Settings, solve_stage1

SIZES = CaseSizes(18.95e-3, 106.3e-3)  # the sizing step's result on the twin's model
N = 1000  # coarser than the rule for the larger shapes (T within 0.5 % of N = 1700-2000)


@pytest.fixture(scope="module")
def linear():
    from microfab.machines.xy_stage.identify import linear_study

    _, fit = linear_study()
    return fit.model.to_continuous()


@pytest.fixture(scope="module")
def times(linear):
    paths = case_paths(SIZES)
    out = {}
    for case, a_list in (("u", (1.0, 3.0)), ("r", (1.0, 3.0)), ("c", (1.0, 3.0)),
                         ("h", (1.0, 3.0)), ("airfoil", (1.0, 2.0, 3.0))):  # fmt: skip
        for a in a_list:
            p = ContourProblem(paths[case], a_max=a)
            out[(case, a)] = solve_stage1(p, linear, Stage1Settings(n=N)).duration
    return out


def test_sized_times_are_the_seeds(times):
    assert times[("r", 1.0)] == pytest.approx(0.807, rel=0.01)
    assert times[("airfoil", 1.0)] == pytest.approx(1.322, rel=0.01)


@pytest.mark.parametrize("case", ["u", "r", "c", "h"])
def test_letters_speed_up_like_the_seeds_with_a_max(times, case, scaled):
    ratio = scaled(times[(case, 3.0)] / times[(case, 1.0)])
    assert abs(ratio - 0.586) <= 0.04, ratio


@pytest.mark.parametrize("case", ["u", "c"])
@pytest.mark.parametrize("a", [1.0, 3.0])
def test_letter_times_within_a_fifth_of_table_iii(times, case, a, scaled):
    assert scaled(times[(case, a)]) == pytest.approx(paper.TABLE_III[case][a].time_s, rel=0.2)


@pytest.mark.xfail(raises=AssertionError, strict=True,
                   reason="DejaVu's 'h' takes 1.253 s at 1 m/s² and 0.724 s at "
                   "3 m/s² against Table III's 0.971 and 0.568 s (+29 %, +27 %): its stem and "
                   "arch are longer than the ETH logo's")  # fmt: skip
@pytest.mark.parametrize("a", [1.0, 3.0])
def test_letter_h_within_a_fifth_of_table_iii(times, a):
    assert times[("h", a)] == pytest.approx(paper.TABLE_III["h"][a].time_s, rel=0.2)


def test_airfoil_at_two_within_fifteen_percent(times, scaled):
    assert scaled(times[("airfoil", 2.0)]) == pytest.approx(paper.AIRFOIL_TIMES_S[2.0], rel=0.15)


@pytest.mark.xfail(raises=AssertionError, strict=True,
                   reason="the airfoil takes 0.764 s at 3 m/s² against the "
                   "seed's 1.024 s (-25 %): on the twin's model its time falls like "
                   "1/sqrt(a_max) (T(3)/T(1) = 0.58) where the seed's falls to 0.77")  # fmt: skip
def test_airfoil_at_three_within_fifteen_percent(times):
    assert times[("airfoil", 3.0)] == pytest.approx(paper.AIRFOIL_TIMES_S[3.0], rel=0.15)


def test_sizing_step_reaches_its_target(linear):
    from microfab.experiments.seed002_reference.sizing import reference_sizes

    res = reference_sizes(linear, settings=Stage1Settings(n=200))
    for family, target in (("letter", 0.807), ("airfoil", 1.322)):
        _, t = res.steps[family][-1]
        assert t == pytest.approx(target, rel=1e-3)
    assert len(res.steps["letter"]) <= 5 and len(res.steps["airfoil"]) <= 5
