"""Seed 001 §4.2 calibration: noise fitted to the axial RMS; the contour RMS is a check."""

from __future__ import annotations

import pytest

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.experiments.seed001_nanomanipulator.calibration import fit_noise
from microfab.experiments.seed001_nanomanipulator.run import JobConfig, TwinSettings, run_job
from microfab.machines.nanomanipulator_calibration import write_noise
from microfab.plants.nanomanipulator import load_params
from microfab.trajectory.circle_pattern import PatternConfig


@pytest.fixture(scope="module")
def shipped():
    """Metrics of the default job on the shipped (calibrated) twin."""
    return run_job().metrics()


def test_shipped_twin_meets_the_seed_axial_rms(shipped):
    # seed 001 §4.2 / Fig. 13a: 485.8 nm (x), 885.8 nm (y); issue 14: ±5 %
    for a, name in enumerate("xy"):
        assert shipped.axial_rms_nm[a] == pytest.approx(paper.AXIAL_RMS_NM[name], rel=0.05)


@pytest.mark.xfail(strict=True, reason="contour RMS 613 nm predicted vs seed 769.5 nm (-20 %)")
def test_contour_rms_is_predicted_within_15_percent(shipped):
    # seed 001 §4.2 / Fig. 13b: 769.5 nm RMS; not fitted, so a check (issue 14: ±15 %)
    assert shipped.contour_rms_nm == pytest.approx(paper.CONTOUR_RMS_NM, rel=0.15)


def test_fit_converges_from_a_far_start():
    small = JobConfig(
        pattern=PatternConfig(n_circles=1, periods=4),
        twin=TwinSettings(noise_rms_mm=(1.5e-4, 1.5e-4)),
    )
    fit = fit_noise(small, rtol=0.01)
    assert all(abs(e) <= 1.0 for e in fit.axial_error_pct)
    assert fit.runs <= 5
    assert fit.history[0][:2] == pytest.approx((150.0, 150.0))


def test_fit_refuses_noise_off():
    with pytest.raises(ValueError, match="noise on"):
        fit_noise(JobConfig(twin=TwinSettings(noise=False)))


def test_write_noise_round_trips(tmp_path):
    fit = fit_noise(JobConfig(pattern=PatternConfig(n_circles=1, periods=3)), rtol=0.2, max_runs=2)
    p = write_noise(fit, tmp_path / "twin.toml")
    params = load_params(p)
    assert params.noise_rms_mm == pytest.approx(
        (fit.noise_rms_nm[0] * 1e-6, fit.noise_rms_nm[1] * 1e-6), rel=1e-4
    )
    assert "calibrated" in p.read_text(encoding="utf-8")
