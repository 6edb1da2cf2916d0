"""Acceptance criteria: seed 000 Tables 1 and 2 and Fig. 6 on the galvo twin."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.seed000_msl import paper as seed000
from microfab.experiments.seed000_msl.job import reproduce_tables
from microfab.measure.metrics import learning_transient

AXES = ("x", "y")
RATES = seed000.RATES  # seed 000 §4: 100, 200, 400 features/s


@pytest.fixture(scope="module")
def reproduced():
    """All three rates, 30 iterations each (seed 000 §4), on the calibrated twin."""
    return reproduce_tables(iterations=30)


@pytest.fixture(scope="module")
def tables(reproduced):
    return reproduced[0]


@pytest.fixture(scope="module")
def runs(reproduced):
    return reproduced[1]


# ------------------------------------------------------------------------ Table 1
@pytest.mark.parametrize("axis", AXES)
@pytest.mark.parametrize("rate", RATES)
def test_table1_feedback_rows_within_20pct(tables, axis, rate, scaled):
    ours = scaled(tables["table1"][axis][str(rate)])
    seed = seed000.TABLE1_MV[axis][rate]  # seed 000 Table 1
    for key in ("fb_rms", "fb_pp"):
        assert ours[key] == pytest.approx(seed[key], rel=0.20), (axis, rate, key, ours[key])


@pytest.mark.parametrize("axis", AXES)
@pytest.mark.parametrize("rate", RATES)
def test_table1_ilc_rms_within_30pct(tables, axis, rate, scaled):
    # Two-sided: the residual after learning is set by the twin's calibrated noise and
    # dynamics, so one far below the seed's is as wrong as one above. The old one-sided
    # "at most 1.5x the seed" passed with our number halved or x1.5 (the mutation check,
    # issue 43). Measured ours / seed: 1.04, 1.00, 0.96 (x), 1.01, 1.26, 1.05 (y).
    ours = scaled(tables["table1"][axis][str(rate)]["ilc_rms"])
    seed = seed000.TABLE1_MV[axis][rate]["ilc_rms"]  # seed 000 Table 1
    assert ours == pytest.approx(seed, rel=0.30), (axis, rate, ours, seed)


@pytest.mark.parametrize("axis", AXES)
def test_ilc_reduces_rms_by_20_at_400_features(tables, axis):
    # seed 000 abstract / Table 1: reduction up to 25.9 at 400 features/s
    row = tables["table1"][axis]["400"]
    ratio = row["fb_rms"] / row["ilc_rms"]
    assert ratio >= 20.0, (axis, ratio)


def test_table1_matches_runs(tables, runs):
    # the table is the runs' last-trial and first-trial errors in mV
    for rate in RATES:
        for a, axis in enumerate(AXES):
            row = tables["table1"][axis][str(rate)]
            r = runs[rate]
            assert row["fb_rms"] == pytest.approx(r.rms_history[0, a] * 1e3, rel=1e-9)
            assert row["ilc_rms"] == pytest.approx(r.rms_history[-1, a] * 1e3, rel=1e-9)
            assert row["fb_pp"] == pytest.approx(r.pp_history[0, a] * 1e3, rel=1e-9)


# ---------------------------------------------------------- Fig. 6 learning transient
@pytest.mark.parametrize("rate", RATES)
def test_learning_is_monotonic_over_first_10_iterations(runs, rate):
    # seed 000 §4: "experimental verification of the monotonic convergence"; Fig. 6
    rms = runs[rate].rms_history
    assert rms.shape == (30, 2)
    for a, axis in enumerate(AXES):
        lt = learning_transient(rms[:10, a])
        assert lt.is_monotonic(), (rate, axis, rms[:10, a])


@pytest.mark.parametrize("rate", [100, 200])
def test_converged_within_10_iterations(runs, rate):
    # seed 000 §4.1: "the RMS errors converge to a minimum within 10 iterations"
    lt = learning_transient(runs[rate].rms_history)
    for a, axis in enumerate(AXES):
        assert lt.converged_within(10, axis=a), (rate, axis, lt.convergence_iteration())


def test_400_features_nearly_converged_at_10_iterations(runs):
    # seed 000 §4.1: y at 400 features/s converges more slowly (around iteration 30)
    lt = learning_transient(runs[400].rms_history)
    for a, axis in enumerate(AXES):
        assert lt.rms[9, a] <= 1.5 * lt.final[a], (axis, lt.rms[9, a], lt.final[a])


def test_learned_harmonics(runs):
    # seed 000 §4: up to 8 kHz, i.e. harmonics 1..20 at 400 features/s, odd ones only
    for h in runs[400].harmonics:
        assert h.tolist() == list(range(1, 20, 2))
    for rate in RATES:
        f = np.asarray(runs[rate].harmonics[0]) * rate
        assert f.max() <= 8000.0
        assert np.all(np.asarray(runs[rate].harmonics[0]) % 2 == 1)


# ------------------------------------------------------------------------ Table 2
def test_table2_velocity_std_drops_at_400_features(tables):
    t2 = tables["table2"]["400"]
    # seed 000 Table 2: 202 -> 91 mm/s (0.45x)
    assert t2["ilc_std"] <= 0.6 * t2["fb_std"], (t2["ilc_std"], t2["fb_std"])


def test_table2_max_velocity_error_at_400_features(tables, scaled):
    t2 = scaled(tables["table2"]["400"])
    target = seed000.TARGET_SPEED_MM_S[400]  # seed 000 §4.2: 960 mm/s
    # seed 000 §4.2: (1401 - 960)/960 = 45.8 % (FB) and (1101 - 960)/960 = 14.6 % (ILC);
    # the table's rounded speeds give 45.9 % and 14.7 %, hence the 0.2 % tolerance
    for speed, key in ((1401, "fb"), (1101, "ilc")):  # seed 000 Table 2, 400 features/s
        rel = (speed - target) / target
        assert rel == pytest.approx(seed000.MAX_VELOCITY_ERROR_400[key], abs=2e-3)
    fb_err = (t2["fb_max"] - target) / target
    ilc_err = (t2["ilc_max"] - target) / target
    assert ilc_err <= 0.20, f"ILC max velocity error {ilc_err:.1%} (seed 14.6 %)"
    assert fb_err > 0.25, f"FB max velocity error {fb_err:.1%} (seed 45.8 %)"
    assert ilc_err < fb_err


def test_table2_mean_speed_near_target(tables, scaled):
    # seed 000 §4.2: target speeds 240, 480, 960 mm/s; Table 2 means within ~10 %
    for rate in RATES:
        t2 = scaled(tables["table2"][str(rate)])
        target = seed000.TARGET_SPEED_MM_S[rate]
        assert t2["fb_mean"] == pytest.approx(target, rel=0.12)
        assert t2["ilc_mean"] == pytest.approx(target, rel=0.12)


def test_margins_reported(tables):
    for axis in AXES:
        m = tables["margins"][axis]
        assert m["pm_deg"] > 0 and m["gm_db"] > 0
        assert 1500.0 <= m["pm_freq_hz"] <= 2800.0
    assert set(tables["rms_history"]) == set(AXES)
    assert len(tables["rms_history"]["x"]["400"]) == 30
