"""Tests of the lead-lag design of seed 000 eq. (1)."""

from __future__ import annotations

import numpy as np
import pytest

import control
from microfab.control.leadlag import lead_lag

FC_HZ = 2000.0  # seed 000 §3.1: w_c = 2 pi 2000
WC = 2 * np.pi * FC_HZ


def evalc(sys: control.LTI, w: float) -> complex:
    return complex(control.evalfr(sys, 1j * w))


@pytest.mark.parametrize("gain", [1.0, 3.7e8])
def test_loop_gain_is_one_at_crossover_for_double_integrator(gain):
    G = control.tf([gain], [1.0, 0.0, 0.0])
    C = lead_lag(G, FC_HZ)
    mag = abs(evalc(C, WC) * evalc(G, WC))
    # eq. (1): 1/3 cancels the lead's gain of 3 at w_c; the lag adds
    # (w_i/w_it) |1 + j w_c/w_i| / |1 + j w_c/w_it| = 1.005, hence "within 1 %"
    assert mag == pytest.approx(1.0, rel=0.01)
    wi, wit = WC / 10, 2 * np.pi * 6.0  # seed 000 §3.1
    lag = (wi / wit) * abs(1 + 1j * WC / wi) / abs(1 + 1j * WC / wit)
    lead = abs(1 + 3j) / abs(1 + 1j / 3)
    assert mag == pytest.approx(lag * lead / 3.0, rel=1e-9)


def test_phase_at_crossover_is_lead_plus_lag():
    G = control.tf([1.0], [1.0, 0.0, 0.0])
    C = lead_lag(G, FC_HZ)
    # seed 000 §3.1: w_d = w_c/3, w_dt = 3 w_c, w_i = w_c/10, w_it = 2 pi 6
    wi, wit, wd, wdt = WC / 10, 2 * np.pi * 6.0, WC / 3, 3 * WC
    lead = np.arctan(WC / wd) - np.arctan(WC / wdt)
    assert lead == pytest.approx(np.arctan(3) - np.arctan(1 / 3))
    lag = np.arctan(WC / wi) - np.arctan(WC / wit)
    assert np.angle(evalc(C, WC)) == pytest.approx(lead + lag, abs=1e-9)
    # the lead's contribution alone: divide out the analytic lag factor
    lag_factor = (wi / wit) * (1 + 1j * WC / wi) / (1 + 1j * WC / wit)
    assert np.angle(evalc(C, WC) / lag_factor) == pytest.approx(
        np.arctan(3) - np.arctan(1 / 3), abs=1e-9
    )
    # the lead's phase is maximal at w_c (geometric mean of w_d and w_dt)
    w = WC * np.array([0.8, 1.0, 1.25])
    phases = [
        np.angle(evalc(C, x) / ((wi / wit) * (1 + 1j * x / wi) / (1 + 1j * x / wit))) for x in w
    ]
    assert phases[1] > phases[0] and phases[1] > phases[2]


def test_controller_structure():
    G = control.tf([5.0], [1.0, 0.0, 0.0])
    C = lead_lag(G, FC_HZ)
    poles = np.sort(np.abs(C.poles()))
    zeros = np.sort(np.abs(C.zeros()))
    np.testing.assert_allclose(poles, [2 * np.pi * 6.0, 3 * WC], rtol=1e-9)
    np.testing.assert_allclose(zeros, [WC / 10, WC / 3], rtol=1e-9)
    # DC gain 1/(3 |G(j w_c)|) * w_i / w_it
    dc = evalc(C, 0.0).real
    assert dc == pytest.approx(1 / (3 * 5.0 / WC**2) * (WC / 10) / (2 * np.pi * 6.0), rel=1e-9)


def test_other_crossover_and_ratios():
    G = control.tf([1.0], [1.0, 0.0, 0.0])
    fc = 500.0
    C = lead_lag(G, fc, integrator_pole_hz=1.0, integrator_ratio=20.0, lead_ratio=4.0)
    wc = 2 * np.pi * fc
    # lead of ratio r: phase atan(r) - atan(1/r) at w_c
    wi, wit = wc / 20, 2 * np.pi * 1.0
    lag_factor = (wi / wit) * (1 + 1j * wc / wi) / (1 + 1j * wc / wit)
    ratio = evalc(C, wc) / lag_factor
    assert np.angle(ratio) == pytest.approx(np.arctan(4) - np.arctan(1 / 4), abs=1e-9)
    assert abs(ratio * evalc(G, wc)) == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"crossover_hz": 0.0}, "crossover_hz"),
        ({"crossover_hz": -2000.0}, "crossover_hz"),
        ({"crossover_hz": np.nan}, "crossover_hz"),
        ({"integrator_pole_hz": 0.0}, "integrator_pole_hz"),
        ({"integrator_ratio": -10.0}, "integrator_ratio"),
        ({"lead_ratio": 0.0}, "lead_ratio"),
        ({"lead_ratio": np.inf}, "lead_ratio"),
        # lag pole above the lag zero (w_c/10 = 200 Hz)
        ({"integrator_pole_hz": 300.0}, "integrator_pole_hz"),
    ],
)
def test_validation(kwargs, match):
    G = control.tf([1.0], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=match):
        lead_lag(G, **kwargs)


def test_plant_with_zero_gain_at_crossover_is_refused():
    # (s^2 + w_c^2) / (s+1)^3 vanishes at j w_c
    G = control.tf([1.0, 0.0, WC**2], np.polymul([1.0, 1.0], np.polymul([1.0, 1.0], [1.0, 1.0])))
    with pytest.raises(ValueError, match="non-zero"):
        lead_lag(G, FC_HZ)
