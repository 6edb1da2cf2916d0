"""``microfab reproduce slm-shaper``: issue 16 acceptance rows on the twin (seed 003 part 2)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.catalog import REPRODUCTIONS
from microfab.experiments.kinds import no_progress
from microfab.experiments.seed003_slm import paper


@pytest.fixture(scope="module")
def data():
    res = REPRODUCTIONS["slm-shaper"].run({"seed": 0, "noise": True}, no_progress)
    assert res.tables and res.data is not None
    return res.data


def test_fit_on_the_noisy_twin_is_within_two_percent(data, scaled):
    seed = np.array([paper.MODEL_NUM[0], *paper.MODEL_DEN[1:]])
    ours = scaled(np.asarray(data["fit"]["coefficients"]))
    np.testing.assert_allclose(ours, seed, rtol=0.02)


@pytest.mark.mutate(only=1.5, reason="the seed's 'reduced by a factor two' is a floor")
def test_lag_settling_and_speed_of_the_continuous_design(data, scaled):
    lag0, lag1 = data["lag_us"]
    assert lag0 == pytest.approx(453.9, rel=0.005) and lag1 == pytest.approx(159.2, rel=0.005)
    assert scaled(lag1 / lag0) <= 1 / paper.LAG_FACTOR
    set0, set1 = data["settling_us"]
    assert set0 == pytest.approx(870, rel=0.05) and set1 == pytest.approx(362, rel=0.05)
    assert scaled(set1 / set0) <= 1 / paper.SETTLING_FACTOR
    spd0, spd1 = data["speed95_us"]
    assert spd0 == pytest.approx(788, rel=0.05) and spd1 == pytest.approx(309, rel=0.05)


def test_jump_delay_of_one_cell(data):
    jd = data["jump_delay_us"]
    assert abs(jd["unshaped"] - 754) <= 75
    assert abs(jd["zpetc"] - 260) <= 40


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="the seed's ZOH-discretised shaper on the 10 µs axis: jump delay 570 µs, not "
    "260 ± 40 (its 23.7x spike reaches the axis as a 10 µs staircase; settling 724 µs)",
)
def test_jump_delay_with_the_seeds_zoh_filter(data):
    assert abs(data["jump_delay_us"]["zoh"] - 260) <= 40


def test_sampled_settling_shows_the_discretisation_gap(data):
    s = data["settling_sampled_us"]
    assert s["zpetc"] <= 1.1 * data["settling_us"][1]  # keeps the continuous design's gain
    assert s["zoh"] > 1.5 * s["zpetc"]


@pytest.mark.mutate(only=0.5, reason="the seed's 'scan time reduction of 10%' is a floor")
def test_lattice_layer_scan_time_cut(data, scaled):
    assert scaled(data["layer_cut"]) >= paper.SCAN_TIME_REDUCTION
