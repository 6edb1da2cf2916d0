"""The machine's sensor-noise fit: on a synthetic job (RMS² = c + g σ² per axis) and on the
nanomanipulator job (seed 001 §4.2: noise fitted to the axial RMS; the contour RMS a check)."""

from __future__ import annotations

import math

import pytest

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.machines.nanomanipulator.calibration import (
    SEED_AXIAL_RMS_NM,
    fit_noise,
    fit_sensor_noise,
    write_noise,
)
from microfab.machines.nanomanipulator.job import JobConfig, TwinSettings, run_job
from microfab.plants.nanomanipulator import load_params
from microfab.trajectory.circle_pattern import PatternConfig


def _job(c: tuple[float, float], g: tuple[float, float]):
    def run(s: tuple[float, float]) -> tuple[tuple[float, float], float]:
        ax = tuple(math.sqrt(c[a] + g[a] * s[a] ** 2) for a in range(2))
        return ax, math.sqrt((ax[0] ** 2 + ax[1] ** 2) / 2)  # type: ignore[return-value]

    return run


def test_the_secant_meets_the_seed_axial_rms() -> None:
    seen = []
    fit = fit_sensor_noise(
        _job((200.0**2, 300.0**2), (0.8, 1.3)),
        (100.0, 100.0),
        rtol=1e-4,
        progress=lambda k, s, a: seen.append(k),
    )
    for a in range(2):
        assert fit.axial_rms_nm[a] == pytest.approx(SEED_AXIAL_RMS_NM[a], rel=1e-4)
    assert all(abs(e) <= 1e-2 for e in fit.axial_error_pct)
    assert fit.runs == len(fit.history) == len(seen) and fit.runs <= 5
    assert fit.history[0][:2] == (100.0, 100.0)


def test_refusals() -> None:
    with pytest.raises(ValueError, match="already exceeds"):
        fit_sensor_noise(_job((600.0**2, 0.0), (1.0, 1.0)), (100.0, 100.0))
    with pytest.raises(ValueError, match="did not converge in 2 runs"):
        fit_sensor_noise(_job((4e4, 9e4), (1.0, 1.0)), (1.0, 1.0), rtol=1e-9, max_runs=2)
    with pytest.raises(ValueError, match="rtol"):
        fit_sensor_noise(_job((0.0, 0.0), (1.0, 1.0)), (1.0, 1.0), rtol=0.5)


def test_write_noise_keeps_the_source(tmp_path) -> None:
    fit = fit_sensor_noise(_job((0.0, 0.0), (1.0, 1.0)), (400.0, 800.0), rtol=0.2)
    p = write_noise(fit, tmp_path / "twin.toml")
    assert load_params(p).noise_rms_mm == pytest.approx(
        (fit.noise_rms_nm[0] * 1e-6, fit.noise_rms_nm[1] * 1e-6), rel=1e-4
    )
    assert "microfab calibrate nanomanipulator" in p.read_text(encoding="utf-8")


# ------------------------------------------------------- on the nanomanipulator job
@pytest.fixture(scope="module")
def shipped():
    """Metrics of the default job on the shipped (calibrated) twin."""
    return run_job().metrics()


def test_shipped_twin_meets_the_seed_axial_rms(shipped):
    # seed 001 §4.2 / Fig. 13a: 485.8 nm (x), 885.8 nm (y); issue 14: ±5 %
    for a, name in enumerate("xy"):
        assert shipped.axial_rms_nm[a] == pytest.approx(paper.AXIAL_RMS_NM[name], rel=0.05)


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="contour RMS 613 nm predicted vs seed 769.5 nm (-20 %)",
)
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
