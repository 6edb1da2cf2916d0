"""The XY stage twin's Table II column 1 fit: the shipped twin is the calibrated one."""

from __future__ import annotations

import json
import re
import tomllib
from importlib import resources

import pytest

from microfab.machines.xy_stage.calibration import (
    FREE_FIELDS,
    PLAUSIBLE_CAP,
    REFERENCE,
    SOURCE_PREFIX,
    TARGET_SIGMA_M,
    CalibrationSettings,
    XYCalibration,
    fit_scales,
    force_budget,
    scaled_changes,
    scales_of,
    write_twin_file,
)
from microfab.machines.xy_stage.identify import linear_checks
from microfab.plants.xy_stage_params import load_params


def _shipped_sigma_m() -> tuple[float, float]:
    """σ per axis that the data file's calibrated sources state (the full 600 s fit)."""
    text = resources.files("microfab.data").joinpath("xy_stage_twin.toml").read_text()
    data = tomllib.loads(text)["axes"]
    out = []
    for ax in ("x", "y"):
        m = re.search(r"is ([0-9.]+) um, seed", data[ax]["coulomb_n_source"])
        assert m is not None
        out.append(float(m.group(1)) * 1e-6)
    return out[0], out[1]


def test_default_twin_is_the_calibrated_one():
    p = load_params()
    sx, sy = scales_of(p)  # one scale per axis for every free field
    assert sx > 1.0 and sy == PLAUSIBLE_CAP[1]
    data = tomllib.loads(
        resources.files("microfab.data").joinpath("xy_stage_twin.toml").read_text()
    )["axes"]
    for ax in ("x", "y"):
        for key in FREE_FIELDS:
            assert data[ax][f"{key}_source"].startswith(SOURCE_PREFIX)
    assert "not reached" in data["y"]["coulomb_n_source"]
    assert "not reached" not in data["x"]["coulomb_n_source"]
    sig = _shipped_sigma_m()
    assert abs(sig[0] / TARGET_SIGMA_M[0] - 1) <= 0.01  # x fitted within rtol on 600 s
    assert sig[1] < TARGET_SIGMA_M[1]  # y held at the cap below the seed's


def test_shipped_twin_sigma_on_short_seeded_data_is_in_the_band():
    checks = linear_checks(60.0, seed=0, orders=())
    for got, full in zip(checks.sigma_m, _shipped_sigma_m(), strict=True):
        assert abs(got / full - 1) <= 0.15, (got, full)
    assert abs(checks.mu_m[0]) <= max(2e-6, checks.sigma_m[0] / 3)


def test_scaling_keeps_the_bristle_law():
    p = load_params().with_(**dict(scaled_changes((2.0, 3.0))))
    for i, s in enumerate((2.0, 3.0)):
        assert p.coulomb_n[i] == pytest.approx(s * REFERENCE["coulomb_n"][i])
        # the pre-sliding displacement F_c / sigma0 does not change
        assert p.coulomb_n[i] / p.bristle_stiffness_n_per_m[i] == pytest.approx(
            REFERENCE["coulomb_n"][i] / REFERENCE["bristle_stiffness_n_per_m"][i]
        )
    assert scales_of(p) == pytest.approx((2.0, 3.0))
    with pytest.raises(ValueError, match="not one scale"):
        scales_of(p.with_(cogging_n=(1.0, 12.0)))
    b = force_budget(p)
    assert b[0].coulomb_n == 40.0 and b[0].inertial_n == pytest.approx(150.0)


def test_fit_from_the_reference_on_short_data():
    fit = fit_scales(CalibrationSettings(total_s=30.0, search_s=None, start=(1.0, 1.0)))
    assert 2 <= fit.runs <= 6
    assert abs(fit.sigma_m[0] / TARGET_SIGMA_M[0] - 1) <= 0.01
    assert fit.capped == (False, True) and fit.scales[1] == PLAUSIBLE_CAP[1]
    # 30 s of data give the x scale of the 600 s fit within the band
    assert fit.scales[0] == pytest.approx(scales_of(load_params())[0], rel=0.15)
    assert fit.history[0][1:3] == (1.0, 1.0)


def test_write_twin_file_round_trip(tmp_path):
    cal = XYCalibration(
        scales=(4.0, 5.0),
        capped=(False, True),
        sigma_m=(48.1e-6, 80e-6),
        mu_m=(0.0, 0.0),
        runs=3,
        history=(),
        total_s=600.0,
        seed=0,
    )
    out = write_twin_file(cal, tmp_path / "twin.toml")
    p = load_params(out)
    assert scales_of(p) == pytest.approx((4.0, 5.0))
    assert p.viscous_n_s_per_m == load_params().viscous_n_s_per_m  # not free
    text = out.read_text(encoding="utf-8")
    assert text.count(SOURCE_PREFIX) == 2 * len(FREE_FIELDS)
    assert text.count("not reached") == len(FREE_FIELDS)
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("cogging_n = 24.0\n", "", 1), encoding="utf-8")
    with pytest.raises(ValueError, match=r"\[axes.x\] must hold cogging_n"):
        write_twin_file(cal, tmp_path / "never.toml", source=bad)
    assert not (tmp_path / "never.toml").exists()


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="rtol"):
        CalibrationSettings(rtol=0.5)
    with pytest.raises(ValueError, match="max_runs"):
        CalibrationSettings(max_runs=1)
    with pytest.raises(ValueError, match=r"start\[y\]"):
        CalibrationSettings(start=(1.0, 1000.0))
    with pytest.raises(ValueError, match="did not converge in 2 runs"):
        fit_scales(CalibrationSettings(total_s=20.0, search_s=None, start=(1.0, 1.0), max_runs=2))


def test_cli_calibrate_xy_stage(tmp_path):
    from typer.testing import CliRunner

    from microfab.cli import app

    out, js = tmp_path / "twin.toml", tmp_path / "cal.json"
    res = CliRunner().invoke(
        app,
        ["calibrate", "xy-stage", "--duration", "20", "--search", "20", "--write", str(out),
         "--json", str(js)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "capped: y" in res.output and "Coulomb" in res.output
    d = json.loads(js.read_text(encoding="utf-8"))
    assert scales_of(load_params(out)) == pytest.approx(d["scales"], rel=1e-4)
    for argv, says in (
        (["--duration", "-1"], "-1 s is outside the allowed range"),
        # issue 32: --duration 1e308 ran until killed (it sized 1e312 samples at the end)
        (["--duration", "1e308"], "1e+308 s is outside the allowed range [0.5, 3600] s"),
        (["--duration", "60", "--search", "600"], "--search 600 s is longer than --duration 60 s"),
    ):
        bad = CliRunner().invoke(app, ["calibrate", "xy-stage", *argv])
        assert bad.exit_code == 2 and says in bad.output, bad.output


@pytest.fixture(scope="module")
def short_checks():
    return linear_checks(60.0, seed=0, orders=())


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="y cannot reach Table II's 156.3 µm with plausible friction: at the 6x cap (the "
    "carriage still settles) the linear model's sigma is 87.8 µm on 600 s (-44 %); the "
    "target needs about 10.9x, where y hunts 150 µm at rest (microfab calibrate xy-stage)",
)
def test_linear_sigma_of_y_matches_table_ii(short_checks):
    assert abs(short_checks.sigma_m[1] / TARGET_SIGMA_M[1] - 1) <= 0.15


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="on the calibrated twin the slowest identified time constant is 44.5 ms (600 s), "
    "outside the seed's 500 ms / 25 = 20 ms ± 50 %: the large friction slows the settling",
)
def test_slowest_time_constant_near_20_ms(short_checks):
    from microfab.experiments.seed002_stage.paper import SLOW_TIME_CONSTANT_S

    assert abs(short_checks.slowest_time_constant_s / SLOW_TIME_CONSTANT_S - 1) <= 0.5
