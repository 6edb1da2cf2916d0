"""The registry of job kinds and reproductions."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from microfab.experiments.catalog import (
    JOB_KINDS,
    KIND_ENTRIES,
    REPRODUCTION_ENTRIES,
    REPRODUCTIONS,
    KindEntry,
    _Lazy,
    default_job,
    job_kind,
    load_job,
    reproduction,
)
from microfab.io.job import JobFileError

EXAMPLES = Path(__file__).parents[2] / "examples"


def test_every_kind_has_an_example_that_loads():
    assert "msl-ilc" in JOB_KINDS
    for name, entry in KIND_ENTRIES.items():
        job = load_job(EXAMPLES / entry.example)
        assert job.kind is JOB_KINDS[name] and job.kind.name == name
        assert entry.description and len(entry.seed) == 3 and entry.seed.isdigit()


def test_every_registered_target_is_the_object_of_that_name():
    for name, entry in REPRODUCTION_ENTRIES.items():
        assert REPRODUCTIONS[name].name == name and entry.description
    assert set(JOB_KINDS) == set(KIND_ENTRIES) and len(REPRODUCTIONS) == 7
    bad = KindEntry(name="x", seed="000", description="d", example="e.toml",
                    target=KIND_ENTRIES["msl-ilc"].target)  # fmt: skip
    with pytest.raises(LookupError, match="registered as 'x'"):
        _Lazy({"x": bad})["x"]


def test_listing_and_checking_load_no_machine():
    # microfab kinds and a broken job file answer without importing any kind's modules
    code = (
        "import sys, json\n"
        "from typer.testing import CliRunner\n"
        "from microfab.cli import app\n"
        "r = CliRunner()\n"
        "assert r.invoke(app, ['kinds']).exit_code == 0\n"
        "open('broken.toml', 'w').write('[job')\n"
        "assert r.invoke(app, ['run', 'broken.toml', '--check']).exit_code == 2\n"
        "heavy = ('scipy', 'matplotlib', 'control', 'casadi', 'torch', 'numba')\n"
        # a seed's keys.py (the job keys its options share, microfab.cli._options) and
        # the package above it are light by design; anything else of a seed is not
        "light = lambda m: m.endswith('.keys') or m.count('.') == 2\n"
        "loaded = [m for m in sys.modules if m.split('.')[0] in heavy\n"
        "          or (m.startswith('microfab.experiments.seed') and not light(m))]\n"
        "print(json.dumps(loaded))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=tempfile.mkdtemp())  # fmt: skip
    assert json.loads(out.stdout) == []


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
