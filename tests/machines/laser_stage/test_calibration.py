"""`calibrate laser` on the calibration core: the problem, a tiny run, the twin file it writes."""

from __future__ import annotations

import tomllib

import pytest

from microfab.calibrate import calibrate
from microfab.machines.laser_stage import calibration as cal
from microfab.machines.laser_stage.machine import TwinSettings
from microfab.machines.twins import data_path
from microfab.plants.lmw_stage import load_params
from microfab.trajectory.contour_laps import ContourMotion

#: One short lap at 5 mm/s: the same model, about 0.1 s a run (a test's budget).
QUICK = cal.FIG3_JOB.with_(motion=ContourMotion(speed_m_s=5e-3, laps=1))


def test_the_problem_fits_the_fig3_numbers_and_holds_the_force_back():
    prob = cal.problem()
    by = {t.name: t for t in prob.targets}
    assert [n for n in by if by[n].role == "fit"] == list(cal.FIT_NAMES)
    assert [n for n in by if by[n].role == "check"] == list(cal.CHECK_NAMES)
    assert by["fig3_peak_um"].value == pytest.approx(0.8) and by["fig3_peak_um"].side == "both"
    for ax in "xy":
        t = by[f"fig3_share_{ax}"]
        assert (t.value, t.side) == (0.95, "at least")
    assert by["rms_force_n"].side == "at most" and by["rms_force_n"].value == 3.0
    for t in prob.targets:
        assert "seed 004" in t.source and "assumed" in t.source  # value cited, tolerance said
    assert "Fig. 3" in by["fig3_peak_um"].source and "Table I" in by["rms_force_n"].source
    for p in prob.parameters:
        assert p.low < p.high and p.source.startswith("assumed: ")
    assert {k.parameter for k in cal.TWIN_KEYS} == set(prob.parameter_names)
    # the identity holds the twin file's digest: another file is another model
    assert "sha256" in prob.identity
    # the provenance labels: both Fig. 3 numbers fitted, the force a check
    assert cal.CALIBRATION.targets == {cal.FIG3_PEAK_QUANTITY, cal.FIG3_SHARE_QUANTITY}
    assert cal.CALIBRATION.checks == {cal.FORCE_QUANTITY}


def test_the_identity_follows_the_file(tmp_path):
    other = tmp_path / "lmw_stage.toml"
    other.write_text(data_path("lmw_stage.toml").read_text(encoding="utf-8") + "\n")
    assert cal.problem(source=other).fingerprint() != cal.problem().fingerprint()


def test_a_job_that_fixes_the_twin_is_refused():
    for tw in (TwinSettings(disturbance_scale=2.0), TwinSettings(params_file="x.toml")):
        with pytest.raises(ValueError, match="leave disturbance_scale and params_file unset"):
            cal.problem(cal.FIG3_JOB.with_(twin=tw))


def test_the_model_runs_the_file_it_writes():
    # the packaged values through the same keys: the shipped twin's own numbers
    cfg = load_params()
    values = {
        "disturbance_scale": cfg.disturbance_scale,
        "static_ratio": cfg.static_n[0] / cfg.coulomb_n[0],
        "stribeck_m_s": cfg.stribeck_m_s[0],
        "bristle_rate_per_m": cfg.bristle_stiffness_n_per_m[0] / cfg.coulomb_n[0],
        "noise_rms_m": cfg.noise_rms_m[0],
    }
    from microfab.machines.laser_stage.contour import run_contour

    got = cal.problem(QUICK).evaluate(values)
    run = run_contour(QUICK)
    assert got["fig3_peak_um"] == pytest.approx(max(run.axis.peak_m) * 1e6, rel=1e-9)
    assert (got["fig3_share_x"], got["fig3_share_y"]) == pytest.approx(run.axis.fraction_below)


@pytest.fixture(scope="module")
def tiny():
    # DE on 10 points, no polish, no conflict sweep: about 20 runs of QUICK (~3 s)
    return cal.problem(QUICK), calibrate(
        cal.problem(QUICK), budget=10, seed=0, polish=False, conflict_budget=0
    )


def test_a_tiny_calibration_reports_every_target_and_parameter(tiny):
    prob, res = tiny
    assert [t.name for t in res.targets] == list(prob.target_names)
    assert [p.name for p in res.parameters] == list(prob.parameter_names)
    for row in res.parameters:
        assert row.low <= row.value <= row.high
    assert res.requested >= 10
    for t in res.targets:
        assert set(t.pinned_by) <= set(prob.parameter_names)


def test_write_twin_names_the_targets_and_a_refused_write_leaves_the_file(tiny, tmp_path):
    _prob, res = tiny
    out = cal.write_twin(res, tmp_path / "twin.toml")
    doc = tomllib.loads(out.read_text(encoding="utf-8"))
    fc = load_params().coulomb_n
    assert doc["disturbance"]["disturbance_scale"] == pytest.approx(
        res.values["disturbance_scale"], rel=1e-4
    )
    for i, ax in enumerate("xy"):
        sec = doc["axes"][ax]
        assert sec["static_n"] == pytest.approx(res.values["static_ratio"] * fc[i], rel=1e-4)
        assert sec["bristle_stiffness_n_per_m"] == pytest.approx(
            res.values["bristle_rate_per_m"] * fc[i], rel=1e-4
        )
        for key in ("static_n", "stribeck_m_s", "bristle_stiffness_n_per_m", "noise_rms_m"):
            src = sec[f"{key}_source"]
            assert src.startswith("calibrated: `microfab calibrate laser`")
            assert all(n in src for n in cal.FIT_NAMES) and "rms_force_n" in src
    load_params(out)  # a valid twin file
    # a file without the keys: refused, nothing written
    bad = tmp_path / "bad.toml"
    text = data_path("lmw_stage.toml").read_text(encoding="utf-8")
    bad.write_text(text.replace("stribeck_m_s_source", "stribeck_source"), encoding="utf-8")
    before = bad.read_bytes()
    with pytest.raises(ValueError):
        cal.write_twin(res, bad, source=bad)
    assert bad.read_bytes() == before


def test_the_packaged_twin_holds_the_calibration():
    doc = tomllib.loads(data_path("lmw_stage.toml").read_text(encoding="utf-8"))
    for key in cal.TWIN_KEYS:
        sec = doc
        for part in key.section.split("."):
            sec = sec[part]
        src = sec[f"{key.key}_source"]
        assert src.startswith(f"calibrated: `{cal.COMMAND}`"), (key, src)
        assert "fig3_peak_um" in src and "fig3_share_x" in src and "fig3_share_y" in src
        assert "every fit target met" in src
