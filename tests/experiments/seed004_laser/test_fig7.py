"""Seed 004 Fig. 7: on the paper's model, the twin's prediction beside it, the turn-rate cause."""

from __future__ import annotations

import functools
import itertools

import pytest

from microfab.experiments.seed004_laser import paper
from microfab.experiments.seed004_laser.fig7 import (
    FIG7_PAPER_DRAWING,
    fig7_cause,
    fig7_paper_direction,
    fig7_paper_model,
    fig7_point,
    fig7_study,
)


@functools.cache
def _paper_rows(speeds: tuple[float, ...], resolution: bool) -> tuple[dict, ...]:
    """`fig7_paper_model` once per set of speeds (the mutations reuse it)."""
    return tuple(fig7_paper_model(speeds, resolution=resolution, laps=2))


@pytest.mark.mutate(only=1.5, reason="the low-speed bound is one-sided: a ratio at most 1.2")
def test_on_the_paper_s_model_the_ratio_without_over_with_rises_with_speed(scaled):
    """Seed 004 §IV.D on the model the seed states (eq. 2 with M = M_n = 0.6 kg, F_l = 0,
    eqs. 3-15, noise off): "almost no significant contribution ... at low speeds",
    "significant" at high. Issue 45's target: the ratio rises over 0.5-20 mm/s and is
    <= 1.2 at 0.5 mm/s. Measured 1.02 / 1.95 / 5.01 / 5.24 / 5.46 / 5.84 at 0.5 / 1 / 2 /
    5 / 10 / 20 mm/s; three of these speeds run here."""
    rows = _paper_rows((0.5, 2.0, 20.0), False)
    direction = fig7_paper_direction(list(rows))
    ratios = scaled(direction["ratios"])
    assert ratios[0] <= paper.PROJECT_CHOICES["fig7_ratio_low_max"], ratios  # measured 1.02
    assert all(b >= a for a, b in itertools.pairwise(ratios)), ratios  # 1.02, 5.01, 5.84
    low, mid, high = rows
    # at 0.5 mm/s both runs sit on the reference's own rounding (4.5 pm of 5.2 pm)
    assert low["without_nm"] < 2 * low["reference_nm"], low
    # what the compensator changes: 0.03 nm at 2 mm/s, 192 nm at 20 mm/s
    assert abs(mid["change_nm"]) < 0.1 < 100 < high["change_nm"], (mid, high)


def test_with_table_one_s_10_nm_encoder_low_speed_changes_stay_within_one_count():
    """The paper's model with Table I's 10 nm encoder resolution in eq. 3's measured
    position: the floor is the count, and up to 5 mm/s the compensator moves the error
    by less than a count either way (measured -1.7 nm at 1 mm/s, ratio 0.79); at 20 mm/s
    it cuts it 5.5x (235 -> 43 nm)."""
    slow, fast = _paper_rows((1.0, 20.0), True)
    assert abs(slow["change_nm"]) < 10.0 and slow["without_nm"] < 10.0, slow  # one count
    assert fast["ratio"] > 3.0, fast


def test_the_calibrated_twin_predicts_the_opposite_trend_from_its_friction():
    """The calibrated twin (friction on, noise off) is a prediction beside the paper's
    model: its low-speed error is the LuGre friction's quadrant glitches (306 nm at 0.5
    mm/s against 0.005 nm on the paper's model), which the compensator's normal stiffness
    removes best where they last longest, so its ratio falls with speed (4.85x at 0.5
    mm/s, 2.84x at 10 mm/s)."""
    slow = fig7_point(FIG7_PAPER_DRAWING, 0.5, True)
    fast = fig7_point(FIG7_PAPER_DRAWING, 10.0, True)
    assert slow["without_nm"] > 100.0, slow  # friction glitches, not contouring lag
    assert slow["gain"] > fast["gain"] > 1.0, (slow, fast)


def test_near_the_axis_bandwidth_the_normal_row_alone_trades_normal_for_tangential_error():
    # 30 µm circle at 10 mm/s turns at 333 rad/s against the 314 rad/s axis loop
    cause = fig7_cause(30e-6, 10.0)
    assert cause["turn_rate_rad_s"] > cause["bandwidth_rad_s"]
    n, t, c = cause["normal_nm"], cause["tangential_nm"], cause["contour_nm"]
    assert abs(n["normal-only"]) >= 0.9 * abs(n["preview-dob"]), n  # normal error kept
    assert abs(t["normal-only"]) >= 10 * abs(t["preview-dob"]), t  # tangential: 26 -> 2337
    assert c["normal-only"] >= c["preview-dob"], c  # 1112 -> 1253 nm
    # the path-frame model of the module notes predicts the normal-only errors to 15 %
    pn, pt = cause["predicted_nm"]
    assert pn == pytest.approx(n["normal-only"], rel=0.15)
    assert pt == pytest.approx(t["normal-only"], rel=0.15)
    # the seed's full law (eq. 13 row 2, eq. 15's J̇ v) halves it: 1112 -> 249 nm
    assert c["preview-dob"] >= paper.PROJECT_CHOICES["fig7_gain_min"] * c["contour"], c


def test_a_speed_beyond_table_one_is_marked_refused_not_run():
    rows = fig7_study(["circle:radius=1e-4"], [20.0], [(False, False)])
    assert len(rows) == 1 and "continuous force" in rows[0]["refused"]
    assert "with_nm" not in rows[0]
