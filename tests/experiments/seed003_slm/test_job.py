"""The ``slm-shaping`` job kind: settings, refusals, a short run with its report."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from microfab.experiments.catalog import JOB_KINDS, load_job
from microfab.experiments.kinds import no_progress
from microfab.experiments.seed003_slm.job import SLM_SHAPING
from microfab.io.job import JobFileError

EXAMPLE = Path(__file__).parents[3] / "examples" / "slm_shaping.toml"

SHORT = """
[job]
kind = "slm-shaping"
out = "{out}"
[identify]
period_s = 0.1
periods = 3
dropped = 1
[shaper]
compare = false
[layer]
source = "lattice:z=8.2e-4,radius=2e-3"
[build]
layers = {layers}
workers = 1
outline_radius_mm = 2.0
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "job.toml"
    p.write_text(text)
    return p


def test_kind_is_registered_with_its_example():
    assert JOB_KINDS["slm-shaping"] is SLM_SHAPING
    job = load_job(EXAMPLE)
    assert job.config.run.shaper.discretization == "zpetc"
    assert job.config.build is not None and job.config.build.n_layers == 60


@pytest.mark.parametrize(
    ("section", "line", "match"),
    [
        ("identify", "colour = 1", "colour"),
        ("scan", "jump_delay_us = 255.0", "260"),
        ("scan", "mark_speed_m_s = 0.0", "mark"),
        ("identify", "f1_hz = 60000.0", "Nyquist"),
        ("identify", "band_hz = [500.0, 100.0]", "band_hz"),
        ("shaper", "pole_hz = 500.0", "pole"),
        ("layer", 'source = "lattice:z=1e-4,colour=2"', "colour"),
    ],
)
def test_bad_settings_are_refused_naming_the_fix(tmp_path, section, line, match):
    text = f'[job]\nkind = "slm-shaping"\n[{section}]\n{line}\n'
    with pytest.raises((JobFileError, ValueError), match=match):
        load_job(_write(tmp_path, text))


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    out = tmp_path_factory.mktemp("slm")
    path = out / "job.toml"
    path.write_text(SHORT.format(out=(out / "report").as_posix(), layers=3))
    job = load_job(path)
    result = job.kind.run(job.config, job.out, no_progress)
    report = job.kind.write_report(result, job.out, job.title)
    return job, result, report


def test_short_run_writes_model_shaper_summary_and_report(finished):
    job, _result, report = finished
    assert report.exists() and report.name == "report.html"
    summary = json.loads((job.out / "summary.json").read_text())
    assert summary["failures"] == []
    model = json.loads((job.out / "model.json").read_text())
    shaper = json.loads((job.out / "shaper.json").read_text())
    assert shaper["kind"] == "inverse"
    # the short chirp still finds the seed's model within 2 % (0.3 bit noise)
    seed = np.array([1.242e11, 9517.0, 5.773e7, 1.272e11])
    np.testing.assert_allclose(summary["fit"]["coefficients"], seed, rtol=0.02)
    assert model["num"] and model["den"]
    for png in ("frf_fit.png", "shaper_bode.png", "jump_position.png", "jump_speed.png",
                "scan_time.png", "build.png"):  # fmt: skip
        assert (job.out / png).stat().st_size > 1000


def test_shaper_halves_the_jump_and_cuts_the_layer(finished):
    _job, result, _report = finished
    run = result.run
    jd = run.jump_delay_s
    assert jd["zpetc"] < 0.5 * jd["unshaped"]
    assert run.scan_cut > 0
    # the validation jump settles: final position within the band on both runs
    for r in run.jumps.values():
        L = r.command[-1]
        assert abs(r.position[-50:].mean() - L) < 0.02 * L


def test_build_is_resumed_not_rerun(finished, tmp_path):
    job, result, _ = finished
    b = result.build
    assert b is not None and len(b.layers) == 3
    again = job.kind.run(job.config, job.out, no_progress)
    assert again.build is not None
    assert [r["shaped_s"] for r in again.build.layers] == [r["shaped_s"] for r in b.layers]


def test_example_sections_are_all_in_the_schema():
    text = tomllib.loads(EXAMPLE.read_text())
    for section, keys in text.items():
        if section == "job":
            continue
        known = {k.name for k in SLM_SHAPING.schema[section]}
        assert set(keys) <= known, (section, set(keys) - known)
