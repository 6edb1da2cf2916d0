from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.process.exposure import (
    ENVISIONTEC_R11_ASSUMED,
    SEED000_BEAM,
    BeamParams,
    LineProfile,
    ResinParams,
    line_profile,
)

RESIN = ResinParams(penetration_depth_m=100e-6, critical_exposure_j_m2=100.0)


def _speed_for_ratio(ratio: float, beam: BeamParams, resin: ResinParams) -> float:
    """Speed at which E_max = ratio · E_c."""
    return (
        math.sqrt(2 / math.pi)
        * beam.power_w
        / (beam.waist_radius_m * ratio * resin.critical_exposure_j_m2)
    )


def test_defaults() -> None:
    assert SEED000_BEAM.power_w == pytest.approx(30e-3)
    assert SEED000_BEAM.wavelength_m == pytest.approx(405e-9)
    assert ENVISIONTEC_R11_ASSUMED.critical_exposure_j_m2 == pytest.approx(100.0)


def test_peak_exposure_formula() -> None:
    beam = BeamParams(power_w=0.03, waist_radius_m=5e-6)
    prof = line_profile(np.array([0.48]), beam, RESIN)
    assert isinstance(prof, LineProfile)
    expected = math.sqrt(2 / math.pi) * 0.03 / (5e-6 * 0.48)  # ≈ 9974 J/m²
    assert prof.peak_exposure_j_m2[0] == pytest.approx(expected, rel=1e-12)
    assert prof.cure_depth_m[0] == pytest.approx(100e-6 * math.log(expected / 100.0))


def test_width_at_e_times_critical_is_w0_sqrt2() -> None:
    beam = BeamParams(waist_radius_m=4e-6)
    v = _speed_for_ratio(math.e, beam, RESIN)
    prof = line_profile(np.array([v]), beam, RESIN)
    assert prof.width_m[0] == pytest.approx(4e-6 * math.sqrt(2), rel=1e-9)
    assert prof.cure_depth_m[0] == pytest.approx(RESIN.penetration_depth_m, rel=1e-9)


def test_below_threshold_is_uncured() -> None:
    v = _speed_for_ratio(0.5, SEED000_BEAM, RESIN)
    prof = line_profile(np.array([v, 2 * v]), SEED000_BEAM, RESIN)
    np.testing.assert_array_equal(prof.width_m, 0.0)
    np.testing.assert_array_equal(prof.cure_depth_m, 0.0)
    assert math.isnan(prof.uniformity)


def test_halving_speed_widens_line() -> None:
    v = np.array([0.96, 0.48, 0.24])
    prof = line_profile(v, SEED000_BEAM, RESIN)
    assert np.all(np.diff(prof.width_m) > 0)
    assert np.all(np.diff(prof.cure_depth_m) > 0)
    # Halving the speed adds D_p·ln 2 to the cure depth.
    np.testing.assert_allclose(np.diff(prof.cure_depth_m), 100e-6 * math.log(2), rtol=1e-9)


def test_width_monotonic_in_power() -> None:
    powers = [5e-3, 10e-3, 30e-3, 100e-3]
    widths = [line_profile(0.5, BeamParams(power_w=p), RESIN).width_m[0] for p in powers]
    assert np.all(np.diff(widths) > 0)


def test_statistics_and_uniformity() -> None:
    rng = np.random.default_rng(3)
    speeds = 0.48 * (1 + 0.1 * rng.standard_normal(1000))
    prof = line_profile(speeds, SEED000_BEAM, RESIN)
    w = prof.width_m
    assert prof.width_mean_m == pytest.approx(np.mean(w))
    assert prof.width_std_m == pytest.approx(np.std(w))
    assert prof.width_min_m == pytest.approx(w.min())
    assert prof.width_max_m == pytest.approx(w.max())
    assert prof.uniformity == pytest.approx(np.std(w) / np.mean(w))
    # Less speed variation gives a more uniform line.
    calm = line_profile(0.48 * (1 + 0.02 * rng.standard_normal(1000)), SEED000_BEAM, RESIN)
    assert calm.uniformity < prof.uniformity
    # A constant speed gives a perfectly uniform line.
    flat = line_profile(np.full(10, 0.48), SEED000_BEAM, RESIN)
    assert flat.uniformity == pytest.approx(0.0, abs=1e-12)


def test_speed_validation_names_sample() -> None:
    with pytest.raises(ValueError, match="sample 2"):
        line_profile(np.array([0.5, 0.4, 0.0, -1.0]), SEED000_BEAM, RESIN)
    with pytest.raises(ValueError, match="sample 1"):
        line_profile(np.array([0.5, np.nan]), SEED000_BEAM, RESIN)
    with pytest.raises(ValueError, match="at least one"):
        line_profile(np.array([]), SEED000_BEAM, RESIN)


@pytest.mark.parametrize(
    ("cls", "kwargs", "match"),
    [
        (BeamParams, {"power_w": 0.0}, "power_w"),
        (BeamParams, {"waist_radius_m": -1e-6}, "waist_radius_m"),
        (BeamParams, {"wavelength_m": math.inf}, "wavelength_m"),
        (ResinParams, {"penetration_depth_m": 0.0, "critical_exposure_j_m2": 1.0}, "penetr"),
        (ResinParams, {"penetration_depth_m": 1e-4, "critical_exposure_j_m2": -1.0}, "critical"),
    ],
)
def test_params_validation(cls: type, kwargs: dict[str, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        cls(**kwargs)
