"""The seed 004 disturbance fit: it reproduces the shipped scale and writes a valid file."""

from __future__ import annotations

import pytest

from microfab.machines.laser_stage.calibration import FIG3_JOB, fit_disturbance_scale, write_scale
from microfab.machines.laser_stage.machine import TwinSettings
from microfab.plants.lmw_stage import load_params


def test_fit_reproduces_the_shipped_scale_and_writes_it(tmp_path):
    shipped = load_params().disturbance_scale
    fit = fit_disturbance_scale()
    assert fit.runs == 1  # the shipped twin already meets the 0.8 µm peak within 2 %
    assert fit.scale == shipped
    assert abs(max(fit.peak_um) / 0.8 - 1) <= 0.02
    out = write_scale(fit, tmp_path / "twin.toml")
    assert load_params(out).disturbance_scale == pytest.approx(shipped, rel=1e-3)
    assert "calibrated: `microfab calibrate laser`" in out.read_text(encoding="utf-8")


def test_fit_from_another_start_converges(tmp_path):
    fit = fit_disturbance_scale(FIG3_JOB.with_(twin=TwinSettings(disturbance_scale=1.0)))
    assert 2 <= fit.runs <= 5
    assert fit.scale == pytest.approx(load_params().disturbance_scale, rel=0.05)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="rtol"):
        fit_disturbance_scale(rtol=0.5)
    with pytest.raises(ValueError, match="did not converge in 2 runs"):
        fit_disturbance_scale(
            FIG3_JOB.with_(twin=TwinSettings(disturbance_scale=0.2)), max_runs=2, rtol=1e-6
        )


def test_cli_calibrate_laser_writes_a_twin_file(tmp_path):
    from typer.testing import CliRunner

    from microfab.cli import app

    out = tmp_path / "twin.toml"
    res = CliRunner().invoke(app, ["calibrate", "laser", "--write", str(out)])
    assert res.exit_code == 0, res.output
    assert "within ±0.5 µm" in res.output
    assert load_params(out).disturbance_scale == pytest.approx(load_params().disturbance_scale)
