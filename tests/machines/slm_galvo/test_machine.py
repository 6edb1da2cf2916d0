"""The SLM galvo scanner of seed 003 part 2: its surface (limits, twin, play, chirp FRF)."""

from __future__ import annotations

import numpy as np

from microfab.control.setpoint import SetPoint
from microfab.identify.chirp import ChirpDesign
from microfab.identify.frf import estimate_frf
from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.sim.loop import simulate


def test_twin_is_built_once_and_limits_are_the_seed_scanners():
    assert slm_galvo.twin() is slm_galvo.twin(mirror_mode=False)
    assert slm_galvo.twin(mirror_mode=True).mirror_mode
    lim = slm_galvo.limits()
    assert lim.velocity == (10.0, 10.0)
    assert lim.workspace[0][1] == slm_galvo.twin().config.field_bit * 1.5e-6


def test_play_is_the_loop_with_or_without_noise():
    t = slm_galvo.twin()
    u = np.column_stack([np.linspace(0.0, 500.0, 300), np.zeros(300)])
    clean = slm_galvo.play(u)
    np.testing.assert_array_equal(clean, simulate(t, SetPoint(2), u, np.zeros((300, 2))).measured)
    noisy = slm_galvo.play(u, noise_seed=4)
    np.testing.assert_array_equal(noisy, simulate(t, SetPoint(2), u, t.noise(300, 4)).measured)
    assert not np.array_equal(clean, noisy)


def test_chirp_frf_is_the_played_chirps_frf():
    design = ChirpDesign(period_s=0.1, n_periods=3)
    chirp, y, frf = slm_galvo.chirp_frf(design, noise_seed=0)
    assert y.shape == chirp.input.shape
    np.testing.assert_array_equal(frf.response, estimate_frf(chirp, y).response)
    # the seed's G near DC: a gain of b0 / a0 = 0.976
    g0 = slm_galvo.SEED_MODEL_NUM[0] / slm_galvo.SEED_MODEL_DEN[-1]
    assert abs(abs(frf.response[0]) - g0) < 0.05
