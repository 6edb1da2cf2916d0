"""The nanomanipulator-msl job file: defaults, example, refusals (issue 14 'Bad input')."""

from __future__ import annotations

from pathlib import Path

import pytest

from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS, load_job
from microfab.io.job import JobFileError
from microfab.machines.nanomanipulator.job import JobConfig

EXAMPLE = Path(__file__).parents[3] / "examples" / "nanomanipulator_msl.toml"


def _job(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "job.toml"
    p.write_text('[job]\nkind = "nanomanipulator-msl"\n' + body, encoding="utf-8")
    return p


def test_registered_with_its_reproduction():
    assert "nanomanipulator-msl" in JOB_KINDS
    assert "nanomanipulator" in REPRODUCTIONS


def test_example_is_the_default_config():
    cfg = load_job(EXAMPLE).config
    assert isinstance(cfg, JobConfig)
    d = JobConfig()
    assert cfg.pattern == d.pattern
    assert cfg.rbf == d.rbf
    assert cfg.gate_threshold_mm == d.gate_threshold_mm
    assert cfg.laser == d.laser
    assert cfg.rc.lead_samples == d.rc.lead_samples
    assert abs(cfg.rc.tau_s - d.rc.tau_s) < 1e-6


def test_empty_sections_give_the_defaults(tmp_path):
    cfg = load_job(_job(tmp_path, "")).config
    assert cfg.fingerprint() == JobConfig().fingerprint()
    assert cfg.controller == "proposed"


def test_the_seed_network_is_a_job_setting(tmp_path):
    cfg = load_job(_job(tmp_path, '[rbf]\ncontroller = "seed"\n')).config
    assert cfg.controller == "seed" and cfg.rbf == JobConfig().rbf
    assert cfg.fingerprint() != JobConfig().fingerprint()  # a saved run resumes only as it ran


@pytest.mark.parametrize(
    ("body", "match"),
    [
        ("[rbf]\nspeed = 1\n", r"unknown key\(s\) \['speed'\] in \[rbf\]"),
        ('[rbf]\ncontroller = "pid"\n', r"expected one of proposed, seed"),
        ("[lasers]\n", r"unknown section"),
        ("[rbf]\ngamma = 0.0\n", r"gamma \(Γ\)"),
        ("[rbf]\nsigma = -1.0\n", r"sigma \(σ\)"),
        ("[rbf]\neps = 0.0\n", r"eps \(ε\)"),
        ("[rbf]\nlam = 0.0\n", r"lam \(λ"),
        ("[rbf]\nwidth_factor = 0.0\n", r"width_factor"),
        ("[rc]\ntau_ms = 0.0\n", r"tau_ms = 0.0: outside the allowed range \(0, "),
        ("[gate]\nthreshold_um = 0.0\n", r"threshold"),
        ("[gate]\nthreshold_um = nan\n", r"nan"),
        ("[pattern]\nperiod_s = 1.00005\n", r"whole number"),
        ("[pattern]\nperiod_s = 0.02\n", r"velocity|speed"),
        ("[pattern]\nfield_mm = 3.5\n", r"field_mm = 3.5"),
        ("[laser]\ndelay_ms = 1500.0\n", r"warm-up longer than a period"),
        ("[twin]\nnoise_rms_nm = [1.0]\n", r"two values"),
    ],
)
def test_bad_input_is_refused_naming_the_file(tmp_path, body, match):
    p = _job(tmp_path, body)
    with pytest.raises((ValueError, JobFileError), match=match) as info:
        load_job(p)
    assert "job.toml" in str(info.value)


def test_beta_below_beta_min_is_refused(tmp_path):
    """A twin whose β falls below β_min in the workspace is refused at load."""
    src = Path(__file__).parents[3] / "src" / "microfab" / "data" / "nanomanipulator_twin.toml"
    text = src.read_text(encoding="utf-8").replace(
        "beta_cross_gain = 1.0", "beta_cross_gain = 50.0"
    )
    bad = tmp_path / "twin.toml"
    bad.write_text(text, encoding="utf-8")
    p = _job(tmp_path, f'[twin]\nparams_file = "{bad.as_posix()}"\n')
    with pytest.raises(ValueError, match="beta"):
        load_job(p)
