"""The registry of job kinds and reproductions."""

from __future__ import annotations

from pathlib import Path

import pytest

from microfab.experiments.catalog import (
    JOB_KINDS,
    REPRODUCTIONS,
    default_job,
    job_kind,
    load_job,
    reproduction,
)
from microfab.io.job import JobFileError

EXAMPLES = Path(__file__).parents[2] / "examples"


def test_every_kind_has_an_example_that_loads():
    assert "msl-ilc" in JOB_KINDS
    for kind in JOB_KINDS.values():
        job = load_job(EXAMPLES / kind.example)
        assert job.kind is kind
        assert kind.description and kind.seed


def test_every_example_job_file_loads():
    files = sorted(EXAMPLES.glob("*.toml"))
    assert len(files) >= len(JOB_KINDS)
    for f in files:
        assert load_job(f).kind.name in JOB_KINDS, f.name


def test_unknown_names_list_the_known_ones(tmp_path):
    with pytest.raises(KeyError, match=r"known: .*msl-ilc"):
        job_kind("nope")
    with pytest.raises(KeyError, match=r"known: .*msl-ilc"):
        reproduction("nope")
    p = tmp_path / "j.toml"
    p.write_text('[job]\nkind = "nope"\n', encoding="utf-8")
    with pytest.raises(JobFileError, match="unknown job kind 'nope'"):
        load_job(p)


def test_default_job_is_seed000():
    job = default_job()
    assert job.kind.name == "msl-ilc"
    assert job.config.features_per_s == 400
    assert job.config.rates == [100, 200, 400]


def test_msl_config_refuses_a_rate_that_does_not_divide_1mhz(tmp_path):
    p = tmp_path / "j.toml"
    p.write_text('[job]\nkind = "msl-ilc"\n[scan]\nfeatures_per_s = 300\n', encoding="utf-8")
    with pytest.raises(ValueError, match=r"j.toml: features_per_s 300 must divide"):
        load_job(p)


def test_reproduction_options_are_checked():
    rep = REPRODUCTIONS["msl-ilc"]
    assert rep.parse_options({}) == {"iterations": 30, "seed": 0}
    with pytest.raises(JobFileError, match="unknown key"):
        rep.parse_options({"speed": 1})
