from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.process.laser import (
    LaserDiode,
    advance_gate,
    as_gate,
    straight_line_closing,
    tail_length_m,
)

DT = 1e-4  # s, the 10 kHz of the twin (assumed in issue 14's contract)
W = 1.5e-6  # m, 1/e² radius of the seed's 3 µm spot (seed 001 §2)
RATIO = math.exp(-(2.5**2) / (2 * 1.5**2))  # E_th / E_max of the 2.5 µm line


def _time(n: int) -> np.ndarray:
    return np.arange(n) * DT


def test_defaults_and_warmup() -> None:
    laser = LaserDiode()
    assert laser.warmup_s == pytest.approx(5e-3)  # issue 14: 5 ms assumed
    assert laser.wavelength_m == pytest.approx(405e-9)  # seed 001 §2
    assert laser.time_to_fraction(1 - math.exp(-1)) == pytest.approx(5e-3)
    assert laser.time_to_fraction(0.5) == pytest.approx(4e-3 + 1e-3 * math.log(2))


def test_instantaneous_power_follows_dead_time_and_rise() -> None:
    laser = LaserDiode(power_w=2e-3, delay_s=1e-3, rise_s=2e-3)
    t = _time(200)
    gate = np.zeros(200, bool)
    gate[20:150] = True  # on at t = 2 ms
    p = laser.power(t, gate)
    since = t - 2e-3
    expect = np.where(gate & (since >= 1e-3), 2e-3 * (1 - np.exp(-(since - 1e-3) / 2e-3)), 0.0)
    np.testing.assert_allclose(p, expect, rtol=1e-12, atol=1e-18)
    assert p[150:].max() == 0.0  # off at once


def test_restart_is_cold() -> None:
    laser = LaserDiode(delay_s=0.0, rise_s=1e-3)
    t = _time(100)
    gate = np.zeros(100, bool)
    gate[0:40] = True
    gate[50:100] = True
    p = laser.power(t, gate)
    np.testing.assert_allclose(p[50:90], p[0:40], rtol=1e-12)
    assert p[40:50].max() == 0.0


def test_average_power_is_the_interval_mean() -> None:
    laser = LaserDiode(power_w=1e-3, delay_s=0.35e-3, rise_s=0.7e-3)
    gate = np.zeros(60, bool)
    gate[10:50] = True
    avg = laser.power(_time(60), gate, average=True)
    # Independent: the model's formula at the midpoints of a 1000x finer grid, averaged.
    m = 1000
    tf = (np.arange(60 * m) + 0.5) * (DT / m) - 10 * DT  # time since the switch-on
    fine = np.where(tf >= 0.35e-3, 1e-3 * (1 - np.exp(-(tf - 0.35e-3) / 0.7e-3)), 0.0)
    fine[np.repeat(~gate, m)] = 0.0
    np.testing.assert_allclose(avg, fine.reshape(60, m).mean(axis=1), rtol=0, atol=1e-9)
    # Energy: an ideal laser would deliver P0 * 4 ms; the ramp lacks P0 * warmup_s.
    on_time = 40 * DT
    lost = on_time - avg.sum() * DT / 1e-3
    assert lost == pytest.approx(laser.warmup_s, rel=1e-2)


def test_step_laser() -> None:
    laser = LaserDiode(delay_s=3e-4, rise_s=0.0)
    gate = np.ones(10, bool)
    p = laser.power(_time(10), gate)
    np.testing.assert_array_equal(p > 0, _time(10) >= 3e-4 - 1e-12)
    avg = laser.power(_time(10), gate, average=True)
    np.testing.assert_allclose(avg[:3], 0.0, atol=1e-15)
    np.testing.assert_allclose(avg[3:], 1e-3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"power_w": -1e-3}, "power_w"),
        ({"power_w": 0.0}, "power_w"),
        ({"delay_s": -1e-3}, "delay_s"),
        ({"rise_s": float("nan")}, "rise_s"),
        ({"delay_s": float("inf")}, "delay_s"),
    ],
)
def test_bad_laser_refused(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        LaserDiode(**kwargs)


def test_bad_gate_refused() -> None:
    laser = LaserDiode()
    with pytest.raises(ValueError, match="shape"):
        laser.power(_time(5), np.ones(4, bool))
    with pytest.raises(ValueError, match="sample 2"):
        laser.power(_time(5), np.array([0, 1, 0.5, 1, 0]))
    with pytest.raises(ValueError, match="0 or 1"):
        as_gate(np.array([0.0, float("nan")]), 2)
    with pytest.raises(ValueError, match="time"):
        laser.power(np.array([0.0, 1e-4, 3e-4]), np.ones(3, bool))


def test_advance_gate_moves_switch_on_keeps_switch_off() -> None:
    laser = LaserDiode(delay_s=4e-3, rise_s=1e-3)
    gate = np.zeros(400, bool)
    gate[100:200] = True
    gate[300:350] = True
    out = advance_gate(gate, DT, laser, period_s=0.01)
    expect = np.zeros(400, bool)
    expect[50:200] = True  # 5 ms = 50 samples earlier
    expect[250:350] = True
    np.testing.assert_array_equal(out, expect)
    half = advance_gate(gate, DT, laser, period_s=0.01, rise_multiple=0.0)
    assert np.flatnonzero(half)[0] == 60


def test_advance_longer_than_period_refused() -> None:
    gate = np.zeros(400, bool)
    gate[200:300] = True
    with pytest.raises(ValueError, match="warm-up longer than a period"):
        advance_gate(gate, DT, LaserDiode(), period_s=5e-3)
    with pytest.raises(ValueError, match="before the trace"):
        advance_gate(np.ones(400, bool), DT, LaserDiode(), period_s=1.0)
    with pytest.raises(ValueError, match="period_s"):
        advance_gate(gate, DT, LaserDiode(), period_s=float("nan"))


@settings(max_examples=60, deadline=None)
@given(
    bits=st.lists(st.booleans(), min_size=1, max_size=80),
    n_adv=st.integers(min_value=0, max_value=5),
)
def test_advance_gate_only_adds_light_before_switch_ons(bits: list[bool], n_adv: int) -> None:
    gate = np.array([False] * 6 + bits)
    laser = LaserDiode(delay_s=n_adv * DT, rise_s=0.0)
    out = advance_gate(gate, DT, laser, period_s=1.0)
    assert (out | ~gate).all()  # nothing that was on goes off
    falls = lambda g: np.flatnonzero(g[:-1] & ~g[1:])  # noqa: E731
    np.testing.assert_array_equal(falls(out), falls(out | gate))
    assert set(falls(out)) <= set(falls(gate))  # every switch-off is an original one
    added = np.flatnonzero(out & ~gate)
    for i in added:  # each added sample lies at most n_adv before a switch-on
        assert gate[i + 1 : i + 1 + n_adv].any()


def test_tail_length_matches_erfc() -> None:
    delta = tail_length_m(RATIO, W)
    assert 0.5 * math.erfc(math.sqrt(2) * delta / W) == pytest.approx(RATIO, rel=1e-10)
    assert delta == pytest.approx(0.507e-6, abs=1e-9)


def test_straight_closing_pure_delay_gap_is_speed_times_delay_minus_tails() -> None:
    v = 0.5e-3
    laser = LaserDiode(delay_s=8e-3, rise_s=0.0)  # 4 µm: the tails do not touch
    res = straight_line_closing(laser, speed_m_s=v, spot_radius_m=W, threshold_ratio=RATIO)
    h = W / 400
    assert res.gap_m == pytest.approx(v * 8e-3 - 2 * tail_length_m(RATIO, W), abs=2 * h)


def test_straight_closing_compensated_is_nominal() -> None:
    v = 0.47e-3
    step = LaserDiode(delay_s=5e-3, rise_s=0.0)
    res = straight_line_closing(
        step, speed_m_s=v, spot_radius_m=W, threshold_ratio=RATIO, advance_s=5e-3
    )
    assert res.gap_m == 0.0
    np.testing.assert_allclose(res.width_m, 2.5e-6, rtol=1e-9)  # an ideal closed line
    ramp = LaserDiode(delay_s=4e-3, rise_s=1e-3)
    res = straight_line_closing(
        ramp, speed_m_s=v, spot_radius_m=W, threshold_ratio=RATIO, advance_s=ramp.warmup_s
    )
    assert res.gap_m == 0.0
    assert res.closing_width_m == pytest.approx(2.5e-6, rel=0.02)
    # Uncompensated, the same laser leaves a gap and a narrowed closing point.
    res = straight_line_closing(ramp, speed_m_s=v, spot_radius_m=W, threshold_ratio=RATIO)
    assert res.gap_m > 1e-6
    assert res.closing_width_m < 2e-6
