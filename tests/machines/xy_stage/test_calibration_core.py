"""The XY stage twin's problem on the calibration core (issue 46 item 1)."""

from __future__ import annotations

import math

import pytest

from microfab.calibrate import calibrate
from microfab.machines.xy_stage import calibration_core as cc
from microfab.machines.xy_stage.proxy import ProxySettings
from microfab.plants.xy_stage_params import load_params

# The smallest data the problem runs on (a 2 s linear record; 10 s of the networks' data
# is the least that leaves a validation run) and a small proxy: the test checks the
# plumbing, not the figures.
_TINY = cc.XYCalData(linear_s=2.0, ann_s=10.0, proxy=ProxySettings(hidden=8, offsets=1, ridge=1e-2))

#: The data file's values of the free parameters.
_FILE = {
    "coulomb_x_n": load_params().coulomb_n[0],
    "coulomb_y_n": load_params().coulomb_n[1],
    "cogging_x_n": load_params().cogging_n[0],
    "cogging_y_n": load_params().cogging_n[1],
    "cable_link_n": load_params().cable_link_force_n,
    "cable_stiffness_n_per_m": load_params().cable_stiffness_n_per_m,
    "resonance_hz": load_params().resonance_hz,
    "reaction_coupling": load_params().reaction_coupling,
    "feedforward_mass_x_kg": load_params().feedforward_mass_kg[0],
    "feedforward_mass_y_kg": load_params().feedforward_mass_kg[1],
}


@pytest.fixture(scope="module")
def tiny_result():
    # budget 32: the least the core takes for 10 parameters (one population and a polish)
    return calibrate(cc.problem(_TINY), budget=32, seed=0, conflict_budget=0)


def test_targets_roles_and_sources():
    p = cc.problem(_TINY)
    fit = [t.name for t in p.targets if t.role == "fit"]
    check = [t.name for t in p.targets if t.role == "check"]
    assert tuple(fit) == cc.FIT_NAMES
    assert tuple(check) == cc.CHECK_NAMES
    for t in p.targets:
        assert "seed 002" in t.source and "Tolerance" in t.source
    # Table II column 1 (experiments/seed002_stage/paper.py TABLE_II), µm
    want = {"linear_sigma_x_um": 48.0, "linear_sigma_y_um": 156.3, "linear_mu_x_um": 3.0,
            "linear_mu_y_um": -13.2, "proxy_sigma_x_um": 3.2, "proxy_sigma_y_um": 6.0}  # fmt: skip
    assert {t.name: t.value for t in p.targets if t.role == "fit"} == want
    assert len(cc.CALIBRATION.targets) == len(cc.FIT_NAMES)
    assert len(cc.CALIBRATION.checks) == len(cc.CHECK_NAMES)


def test_bounds_are_sourced_and_hold_the_file_values():
    for par in cc.PARAMETERS:
        assert par.source.startswith("assumed: ")
        assert par.low <= _FILE[par.name] <= par.high, par.name


def test_changes_of_the_file_values_are_the_file_twin():
    cfg = load_params()
    for name, value in cc.changes_of(_FILE):
        got = getattr(cfg, name)
        if isinstance(value, tuple):
            assert value == pytest.approx(got, rel=1e-4), name
        else:
            assert value == pytest.approx(got, rel=1e-4), name


def test_tiny_run_returns_every_row(tiny_result):
    r = tiny_result
    assert tuple(t.name for t in r.targets) == (*cc.FIT_NAMES, *cc.CHECK_NAMES)
    assert {p.name for p in r.parameters} == {p.name for p in cc.PARAMETERS}
    for t in r.targets:
        assert math.isfinite(t.model), t.name
    for p in cc.PARAMETERS:
        assert p.low <= r.values[p.name] <= p.high


def test_write_twin_round_trip(tiny_result, tmp_path):
    out = cc.write_twin(tiny_result, tmp_path / "xy_stage_twin.toml")
    cfg = load_params(out)
    v = tiny_result.values
    for i, ax in enumerate(("x", "y")):
        fc = cfg.coulomb_n[i]
        assert fc == pytest.approx(v[f"coulomb_{ax}_n"], rel=1e-4)
        # the assumed twin's ratios: break-away 1.5 F_c, σ0 = F_c / 2 µm
        assert cfg.static_n[i] == pytest.approx(1.5 * fc, rel=1e-4)
        assert cfg.bristle_stiffness_n_per_m[i] == pytest.approx(fc / 2e-6, rel=1e-4)
        assert cfg.cogging_n[i] == pytest.approx(v[f"cogging_{ax}_n"], rel=1e-4)
    assert cfg.reaction_coupling == pytest.approx(v["reaction_coupling"], rel=1e-4, abs=1e-9)
    text = out.read_text(encoding="utf-8")
    assert "calibrated: `microfab calibrate xy-stage` fits coulomb_y_n" in text


def test_bad_data_is_refused():
    with pytest.raises(ValueError, match="linear_s"):
        cc.XYCalData(linear_s=0.0)
    with pytest.raises(ValueError, match="validation runs"):
        cc.evaluate(_FILE, data=cc.XYCalData(linear_s=2.0, ann_s=6.0))
