"""Grid margins against loops whose margins are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

import control
from microfab.control.margins import loop_margins
from microfab.machines.galvo.machine import open_loop
from microfab.plants.galvo import default_galvo_axes
from microfab.plants.lti import DiscreteLTI, discretize, with_input_delay

DT = 1e-4


def delayed_integrator(k: float, d: int) -> DiscreteLTI:
    """``L(z) = k dt z^-d / (z - 1)``."""
    return with_input_delay(DiscreteLTI([[1.0]], [[k * DT]], [[1.0]], [[0.0]], DT), d)


def analytic(k: float, d: int) -> dict[str, float]:
    """Margins of ``k dt z^-d / (z - 1)``.

    With ``z = e^{j w dt}``: ``|L| = k dt / (2 sin(w dt / 2))`` and
    ``angle L = -pi/2 - w dt (d + 1/2)``.
    """
    wc = 2 / DT * np.arcsin(k * DT / 2)
    pm = 90.0 - np.degrees(wc * DT * (d + 0.5))
    wp = np.pi / (2 * DT * (d + 0.5))
    gm = -20 * np.log10(k * DT / (2 * np.sin(wp * DT / 2)))
    return {"fc": wc / 2 / np.pi, "pm": pm, "fp": wp / 2 / np.pi, "gm": gm}


@pytest.mark.parametrize(("k", "d"), [(2 * np.pi * 100, 5), (2 * np.pi * 30, 2), (900.0, 11)])
def test_delayed_integrator_margins_match_closed_form(k, d):
    m = loop_margins(delayed_integrator(k, d), n_points=50_000)
    ref = analytic(k, d)
    assert m.pm_freq_hz == pytest.approx(ref["fc"], rel=1e-6)
    assert m.pm_deg == pytest.approx(ref["pm"], abs=1e-4)
    assert m.gm_freq_hz == pytest.approx(ref["fp"], rel=1e-6)
    assert m.gm_db == pytest.approx(ref["gm"], abs=1e-4)
    # every further -180 - 360 m crossing is also where the formula puts it
    phases = [c for c in m.crossings if c.kind == "phase"]
    for i, c in enumerate(phases):
        w = (np.pi / 2 + 2 * np.pi * i) / (DT * (d + 0.5))
        assert c.freq_hz == pytest.approx(w / 2 / np.pi, rel=1e-6)
        mag = k * DT / (2 * np.sin(w * DT / 2))
        assert c.margin == pytest.approx(-20 * np.log10(mag), abs=1e-4)
    assert [c.freq_hz for c in m.crossings] == sorted(c.freq_hz for c in m.crossings)


def test_integrator_without_delay_has_infinite_gain_margin():
    # angle L = -90 - w dt/2 reaches -180 deg only at Nyquist, beyond the grid
    m = loop_margins(delayed_integrator(2 * np.pi * 100, 0), n_points=20_000)
    assert m.gm_db == np.inf
    assert m.gm_freq_hz == np.inf
    assert m.pm_deg == pytest.approx(
        90.0 - np.degrees(np.arcsin(2 * np.pi * 100 * DT / 2)), abs=1e-4
    )


def test_zoh_second_order_loop_against_dense_evaluation():
    # K / (s (s + a)) with ZOH and a 3-sample delay; compare with an independent dense
    # evaluation of the transfer function polynomial on a linear grid
    a, K, d = 2 * np.pi * 300, 1.25e6, 3  # crossover near 100 Hz, PM near 60 deg
    G = control.tf([K], [1.0, a, 0.0])
    L = with_input_delay(discretize(G, DT, "zoh"), d)
    m = loop_margins(L, n_points=50_000)
    Gd = control.c2d(G, DT, "zoh")
    f = np.linspace(1.0, 0.999 / (2 * DT), 2_000_001)
    z = np.exp(2j * np.pi * f * DT)
    H = np.polyval(Gd.num[0][0], z) / np.polyval(Gd.den[0][0], z) * z**-d
    i = np.argmin(np.abs(np.abs(H) - 1.0))
    assert m.pm_freq_hz == pytest.approx(f[i], rel=1e-3)
    assert m.pm_deg == pytest.approx(180 + np.degrees(np.angle(H[i])), abs=0.05)
    ph = np.unwrap(np.angle(H))
    j = np.argmin(np.abs(ph + np.pi))
    assert m.gm_freq_hz == pytest.approx(f[j], rel=1e-3)
    assert m.gm_db == pytest.approx(-20 * np.log10(np.abs(H[j])), abs=0.02)


def test_loop_without_gain_crossing_is_refused():
    static = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[0.1]], DT)
    with pytest.raises(ValueError, match="0 dB"):
        loop_margins(static, n_points=1000)


def test_conditionally_stable_galvo_loop():
    # With the rigid-body pole at ~105 Hz below the lag zero (200 Hz), the phase of the x
    # loop dips below -180 deg at low frequency while |L| >> 1: those phase crossings have
    # negative gain margins (the gain may only *fall* that much), and the reported GM is the
    # one above the crossover.
    ax = default_galvo_axes()["x"]
    m = loop_margins(open_loop(ax), n_points=50_000)
    low = [c for c in m.crossings if c.kind == "phase" and c.freq_hz < m.pm_freq_hz]
    assert len(low) >= 2
    for c in low:
        assert c.margin < 0, c
        L = open_loop(ax).frequency_response(np.array([c.freq_hz]))[0, 0, 0]
        assert abs(L) > 1
        assert -20 * np.log10(abs(L)) == pytest.approx(c.margin, abs=0.05)
        assert np.degrees(np.angle(L)) == pytest.approx(180.0, abs=0.5) or np.degrees(
            np.angle(L)
        ) == pytest.approx(-180.0, abs=0.5)
    assert m.gm_freq_hz > m.pm_freq_hz
    assert m.gm_db > 0
    assert m.pm_deg > 0
    # exactly one gain crossing
    assert sum(c.kind == "gain" for c in m.crossings) == 1
