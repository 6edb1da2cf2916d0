"""Dose map and warm-up compensation on the seed 001 circle (0.15 mm, §4.2).

The circle's period is 1 s (assumed in issue 14; the seed gives none), sampled at the
twin's 10 kHz (assumed). The laser is the default :class:`LaserDiode` (4 ms dead time +
1 ms rise: warm-up 5 ms, assumed in issue 14).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from microfab.process.cured_line import LoopMeasures, line_widths, measure_loop
from microfab.process.dose import (
    SEED001_LINE_WIDTH_M,
    DoseSettings,
    calibrate_threshold,
    dose_map,
    exposure_map,
)
from microfab.process.exposure import BeamParams, ResinParams, line_profile
from microfab.process.laser import (
    LaserDiode,
    advance_gate,
    straight_line_closing,
    tail_length_m,
)

FS = 10_000.0  # Hz, assumed twin sample rate (issue 14 contract)
DT = 1.0 / FS
RADIUS = 75e-6  # m, seed 001 §4.2: circle of 0.15 mm diameter
PERIOD = 1.0  # s, assumed (issue 14)
SPEED = 2 * math.pi * RADIUS / PERIOD  # 0.471 mm/s
SETTINGS = DoseSettings()
W = SETTINGS.spot_radius_m
CELL = SETTINGS.cell_m
LASER = LaserDiode()
IDEAL = LaserDiode(delay_s=0.0, rise_s=0.0)
THRESHOLD = calibrate_threshold(power_w=LASER.power_w, speed_m_s=SPEED)
RATIO = math.exp(-(SEED001_LINE_WIDTH_M**2) / (2 * W**2))  # E_th / E_max


def _circle(noise_m: float = 0.0, seed: int = 0) -> tuple[np.ndarray, ...]:
    """0.2 s on the circle before the gated period, 0.2 s after; gate = one period."""
    t = np.arange(-int(0.2 * FS), int(1.2 * FS)) * DT
    x = RADIUS * np.cos(2 * math.pi * t / PERIOD)
    y = RADIUS * np.sin(2 * math.pi * t / PERIOD)
    if noise_m:
        rng = np.random.default_rng(seed)
        a = math.exp(-2 * math.pi * 300.0 * DT)  # white noise through a 300 Hz low-pass
        for axis in (x, y):
            n = lfilter([1 - a], [1, -a], rng.standard_normal(t.size))
            axis += noise_m * n / n.std()
    gate = (t > -DT / 2) & (t < PERIOD - DT / 2)
    contour = np.column_stack((x[gate], y[gate])) if not noise_m else None
    return t, x, y, gate, contour


T, X, Y, GATE, CONTOUR = _circle()


@pytest.fixture(scope="module")
def ideal() -> LoopMeasures:
    return measure_loop(exposure_map(T, X, Y, GATE, IDEAL), CONTOUR, THRESHOLD)


@pytest.fixture(scope="module")
def uncompensated() -> LoopMeasures:
    return measure_loop(exposure_map(T, X, Y, GATE, LASER), CONTOUR, THRESHOLD)


@pytest.fixture(scope="module")
def compensated() -> LoopMeasures:
    gate = advance_gate(GATE, DT, LASER, period_s=PERIOD)
    return measure_loop(exposure_map(T, X, Y, gate, LASER), CONTOUR, THRESHOLD)


def test_threshold_is_the_working_curve_inverse() -> None:
    # Seed 000's Jacobs line model (exposure.py) with E_c = the calibrated threshold
    # must give the 2.5 µm line of seed 001 Fig. 15 at the nominal speed.
    beam = BeamParams(power_w=LASER.power_w, waist_radius_m=W)
    prof = line_profile(
        SPEED, beam, ResinParams(penetration_depth_m=1e-4, critical_exposure_j_m2=THRESHOLD)
    )
    assert prof.width_m[0] == pytest.approx(2.5e-6, rel=1e-12)
    assert THRESHOLD / prof.peak_exposure_j_m2[0] == pytest.approx(RATIO, rel=1e-12)
    assert calibrate_threshold(power_w=2e-3, speed_m_s=SPEED) == pytest.approx(2 * THRESHOLD)


def test_straight_line_map_is_2p5_um_wide() -> None:
    n = int(60e-6 / SPEED / DT)
    t = np.arange(n) * DT
    dmap = exposure_map(t, SPEED * t, np.zeros(n), np.ones(n, bool), IDEAL)
    lw = line_widths(dmap, np.array([[10e-6, 0.0], [50e-6, 0.0]]), THRESHOLD, closed=False)
    assert lw.width_m.mean() == pytest.approx(2.5e-6, rel=0.02)
    assert lw.width_m.min() > 0.98 * 2.5e-6 and lw.width_m.max() < 1.02 * 2.5e-6
    np.testing.assert_allclose(lw.offset_m, 0.0, atol=CELL / 10)


def test_energy_is_conserved() -> None:
    power = LASER.power(T, GATE, average=True)
    dmap = dose_map(T, X, Y, power)
    energy = dmap.dose_j_m2.sum() * dmap.cell_m**2
    assert energy == pytest.approx(power[:-1].sum() * DT, rel=1e-4)


def test_ideal_laser_closes_the_loop(ideal: LoopMeasures) -> None:
    assert ideal.closed and ideal.gap_m == 0.0
    assert ideal.mean_width_m == pytest.approx(2.5e-6, rel=0.02)
    assert ideal.min_width_m > 0.98 * 2.5e-6 and ideal.max_width_m < 1.02 * 2.5e-6
    assert ideal.closing_width_m == pytest.approx(2.5e-6, rel=0.02)


def test_uncompensated_warmup_opens_the_gap(uncompensated: LoopMeasures) -> None:
    m = uncompensated
    assert not m.closed
    # Exact 1-D prediction (closed form, straight line, same laser and threshold).
    pred = straight_line_closing(LASER, speed_m_s=SPEED, spot_radius_m=W, threshold_ratio=RATIO)
    assert m.gap_m == pytest.approx(pred.gap_m, abs=CELL)
    # "speed x warm-up" minus the two cure tails that reach past the switch points.
    tails = 2 * tail_length_m(RATIO, W)
    assert m.gap_m == pytest.approx(SPEED * LASER.warmup_s - tails, abs=CELL)
    assert m.closing_width_m == pytest.approx(pred.closing_width_m, abs=CELL)
    assert m.closing_min_width_m == 0.0


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 14 reads the gap as speed x warm-up (2.36 µm); the Gaussian spot cures "
    "2 x 0.51 µm past the switch points, so the uncured arc is 1.18 µm",
)
def test_uncompensated_gap_is_literally_speed_times_warmup(uncompensated: LoopMeasures) -> None:
    assert uncompensated.gap_m == pytest.approx(SPEED * LASER.warmup_s, abs=CELL)


def test_compensation_closes_the_loop_at_nominal_width(compensated: LoopMeasures) -> None:
    m = compensated
    assert m.closed and m.gap_m == 0.0
    assert m.closing_width_m == pytest.approx(2.5e-6, rel=0.10)
    assert 0.9 * 2.5e-6 < m.closing_min_width_m <= m.closing_max_width_m < 1.1 * 2.5e-6
    pred = straight_line_closing(
        LASER, speed_m_s=SPEED, spot_radius_m=W, threshold_ratio=RATIO, advance_s=LASER.warmup_s
    )
    assert m.closing_width_m == pytest.approx(pred.closing_width_m, abs=CELL / 4)
    assert m.mean_width_m == pytest.approx(2.5e-6, rel=0.02)


def test_jitter_widens_and_varies_the_line(ideal: LoopMeasures) -> None:
    t, x, y, gate, _ = _circle(noise_m=0.5e-6, seed=1)  # ~ the seed's axial errors
    m = measure_loop(exposure_map(t, x, y, gate, IDEAL), CONTOUR, THRESHOLD)
    assert m.mean_width_m > ideal.mean_width_m + 0.1e-6
    assert m.std_width_m > 0.1e-6 > 10 * ideal.std_width_m


def test_bad_inputs_refused() -> None:
    power = np.full(T.size, 1e-3)
    with pytest.raises(ValueError, match="at least 2 samples"):
        dose_map(np.array([]), np.array([]), np.array([]), np.array([]))
    with pytest.raises(ValueError, match="at least 2 samples"):
        dose_map(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))
    bad = X.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match="x_m must be finite; sample 7"):
        dose_map(T, bad, Y, power)
    neg = power.copy()
    neg[3] = -1e-3
    with pytest.raises(ValueError, match="power_w must be >= 0; sample 3"):
        dose_map(T, X, Y, neg)
    with pytest.raises(ValueError, match="shape"):
        dose_map(T, X, Y[:-1], power)
    with pytest.raises(ValueError, match="max_cells"):
        dose_map(T, X, Y, power, settings=DoseSettings(max_cells=1000))
    with pytest.raises(ValueError, match="bounds_m"):
        dose_map(T, X, Y, power, bounds_m=(1e-4, -1e-4, 0.0, 1e-4))
    with pytest.raises(ValueError, match="bounds_m"):
        dose_map(T, X, Y, power, bounds_m=(0.0, float("inf"), 0.0, 1e-4))
    with pytest.raises(ValueError, match="warm-up longer than a period"):
        advance_gate(GATE, DT, LaserDiode(delay_s=0.9, rise_s=0.2), period_s=PERIOD)
    with pytest.raises(ValueError, match="spot_diameter_m"):
        DoseSettings(spot_diameter_m=-3e-6)
    with pytest.raises(ValueError, match="cell_fraction"):
        DoseSettings(cell_fraction=0.0)
    with pytest.raises(ValueError, match="speed_m_s"):
        calibrate_threshold(power_w=1e-3, speed_m_s=float("nan"))
    with pytest.raises(ValueError, match="line_width_m"):
        calibrate_threshold(power_w=1e-3, speed_m_s=SPEED, line_width_m=0.0)
