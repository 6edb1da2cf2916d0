"""Auto-fit of classic shapers to a measured FRF or PSD (Klipper's calibrate_shaper rules)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.control.shaper_fit import ShaperFitConfig, fit_shaper

F_MODE, Z_MODE = 3000.0, 0.02  # the assumed mirror mode of issue 16 §1
FREQ = np.linspace(100.0, 10000.0, 1000)
S = 2j * np.pi * FREQ
W = 2 * math.pi * F_MODE
MODE = W**2 / (S**2 + 2 * Z_MODE * W * S + W**2)
G = 1.242e11 / (S**3 + 9517 * S**2 + 5.773e7 * S + 1.272e11)  # seed 003 §1
CFG = ShaperFitConfig(
    freq_range_hz=(2000.0, 4500.0),
    n_freqs=60,
    design_dampings=(0.02,),
    test_dampings=(0.01, 0.02, 0.05),
)


@pytest.fixture(scope="module")
def frf_fit():
    # a servo FRF is flat in its passband: divide by the model without the mode
    return fit_shaper(FREQ, G * MODE, kind="frf", baseline=np.abs(G), config=CFG)


def test_each_type_suppresses_the_mode(frf_fit):
    assert set(frf_fit.per_type) == set(CFG.names)
    for name, c in frf_fit.per_type.items():
        v_mode = max(c.shaper.vibration(F_MODE, z)[0] for z in CFG.test_dampings)
        # what remains above the threshold (max / 20) of the weighted vibration
        assert c.vibrations < 0.01, name
        assert v_mode <= 1 / CFG.vibration_reduction + 0.01, name
    # the narrow ZV must sit near the mode
    assert frf_fit.per_type["zv"].shaper.freq_hz == pytest.approx(F_MODE, rel=0.03)
    assert frf_fit.best.vibrations < 0.01


def test_a_shaper_away_from_the_mode_leaves_more_vibration(frf_fit):
    scan = frf_fit.scans["zv"]
    far = min(scan, key=lambda c: abs(c.shaper.freq_hz - 2000.0))
    assert far.vibrations > 10 * frf_fit.per_type["zv"].vibrations + 0.05


def test_choice_trades_vibration_against_delay(frf_fit):
    for name, c in frf_fit.per_type.items():
        best_v = min(x.vibrations for x in frf_fit.scans[name])
        assert c.vibrations <= best_v * 1.1 + 0.0005
        assert c.score == pytest.approx(c.delay * (c.vibrations**1.5 + 0.2 * c.vibrations + 0.01))
        assert c.delay == pytest.approx(c.shaper.delay)
    assert frf_fit.best in frf_fit.per_type.values()


def test_psd_input_finds_the_same_zv():
    fit = fit_shaper(FREQ, np.abs(MODE) ** 2, kind="psd", config=CFG)
    zv = fit.per_type["zv"].shaper.freq_hz
    assert zv == pytest.approx(F_MODE, rel=0.03)


@pytest.mark.parametrize(
    "args, match",
    [
        ((FREQ[::-1], np.abs(MODE)), "increasing"),
        ((FREQ, -np.abs(MODE)), "PSD must be real"),
        ((FREQ, np.abs(MODE)[:-1]), "one length"),
    ],
)
def test_bad_inputs(args, match):
    with pytest.raises(ValueError, match=match):
        fit_shaper(*args, config=CFG)


def test_an_frf_whose_square_overflows_is_refused_without_a_warning():
    # the 0/0 and inf - inf of the scores came from this overflow (make fuzz, file-frf)
    with np.errstate(over="raise", invalid="raise"), pytest.raises(ValueError, match="overflows"):
        fit_shaper(FREQ, MODE * 1e200, kind="frf", config=CFG)
    with np.errstate(over="raise", invalid="raise"), pytest.raises(ValueError, match="overflows"):
        fit_shaper(FREQ, MODE, kind="frf", baseline=np.full(FREQ.shape, 1e-300), config=CFG)


def test_config_refusals():
    with pytest.raises(ValueError, match="unknown shaper"):
        ShaperFitConfig(names=("zz",))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="freq_range_hz"):
        ShaperFitConfig(freq_range_hz=(5000.0, 1000.0))
    with pytest.raises(ValueError, match="baseline"):
        fit_shaper(FREQ, MODE, kind="frf", baseline=np.zeros(FREQ.size), config=CFG)


def test_a_design_range_beyond_the_data_is_refused() -> None:
    """Issue 32: --freq-range 6000:7000 designed from FRF data that end at 5000 Hz."""
    top = float(FREQ[-1])
    cfg = ShaperFitConfig(names=("zv",), freq_range_hz=(top + 1000.0, top + 2000.0))
    with pytest.raises(ValueError, match="reaches beyond the data, which span"):
        fit_shaper(FREQ, np.abs(MODE) ** 2, kind="psd", config=cfg)
