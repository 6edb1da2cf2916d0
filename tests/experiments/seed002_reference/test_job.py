"""The stage-reference-opt job (seed 002 §V) on tiny models: points, resume, report."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("casadi")
pytest.importorskip("torch")

from microfab.experiments.catalog import KIND_ENTRIES, REPRODUCTIONS, load_job
from microfab.experiments.seed002_reference.job import STAGE_REFERENCE_OPT
from microfab.experiments.seed002_reference.study import (
    ReferenceSettings,
    run_reference,
)
from microfab.machines.xy_stage import reference as xy_stage_reference
from microfab.machines.xy_stage.cases import CaseSizes
from microfab.machines.xy_stage.machine import TwinSettings


def job_file(tmp_path, body: str):
    p = tmp_path / "j.toml"
    p.write_text('[job]\nkind = "stage-reference-opt"\n' + body, encoding="utf-8")
    return p


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ('[models]\ndir = "m"\n[cases]\nnames = "r,q"\n', "names must be"),
        ('[models]\ndir = "m"\n[cases]\na_max = [0.0]\n', "above 0"),
        ('[models]\ndir = "m"\n[cases]\nletter_height_mm = 5.0\n', "give both"),
        ('[models]\ndir = "m"\n[cases]\ntolerance_um = 0.0\n', "tolerance_um"),
        ('[models]\ndir = "m"\n[stage2]\nmax_iter = 0\n', "max_iter"),
        ('[models]\ndir = "m"\n[twin]\nspeed = 1\n', "speed"),
    ],
)
def test_bad_job_files_refused(tmp_path, body, says):
    with pytest.raises(Exception, match=says.replace("[", r"\[").replace("]", r"\]")):
        load_job(job_file(tmp_path, body))


def test_a_models_folder_is_found_beside_the_job_file(tmp_path, tiny_models, monkeypatch):
    """Issue 34: [models] dir named a folder relative to the working directory only."""
    import shutil

    d, _ = tiny_models
    shutil.copytree(d, tmp_path / "jobs" / "mine")
    p = tmp_path / "jobs" / "j.toml"
    p.write_text('[job]\nkind = "stage-reference-opt"\n[models]\ndir = "mine"\n', "utf-8")
    monkeypatch.chdir(tmp_path)  # "mine" is not in the working directory
    assert load_job(p).config.models_dir == str(tmp_path / "jobs" / "mine")


def test_settings_fingerprint_follows_the_model_files(tmp_path, tiny_models):
    """A retrained model in the same folder is another fingerprint (not the old points)."""
    import shutil

    d, _ = tiny_models
    mine = tmp_path / "m"
    shutil.copytree(d, mine)
    a = ReferenceSettings(models_dir=str(mine)).fingerprint()
    assert ReferenceSettings(models_dir=str(d)).fingerprint() == a  # same files elsewhere
    w = mine / "ann" / "model" / "weights.npz"
    w.write_bytes(w.read_bytes() + b"\0")
    assert ReferenceSettings(models_dir=str(mine)).fingerprint() != a


def test_example_and_registry():
    assert "reference-opt" in REPRODUCTIONS
    assert KIND_ENTRIES[STAGE_REFERENCE_OPT.name].example == "blackbox_stage_reference.toml"


@pytest.fixture(scope="module")
def small(tiny_models, tmp_path_factory):
    d, _ = tiny_models
    out = tmp_path_factory.mktemp("ref")
    settings = ReferenceSettings(
        models_dir=str(d),
        twin=TwinSettings(hold_s=0.51),
        cases=("r",),
        a_max=(2.0,),
        airfoil_extra=(),
        tolerance_m=100e-6,
        sizes=CaseSizes(5e-3, 20e-3),
        stage2_max_iter=3,
    )
    return settings, out, run_reference(settings, out)


def test_a_point_is_optimised_played_and_scored(small):
    _, out, study = small
    p = study.points[("r", 2.0)]
    assert "error" not in p, p
    for key in ("optimised_twin", "baseline_twin", "stretched_twin", "optimised_ann"):
        sc = p["scores"][key]
        assert 0 < sc["l1"] <= sc["l2"] <= sc["linf"]
    assert p["limited"]["optimised"] == 0 and p["limited"]["stretched"] == 0
    assert p["stage2"]["merit_end"] <= p["stage2"]["merit_start"]
    saved = json.loads((out / "points" / "r_a2.json").read_text())
    assert saved["improvement"] == p["improvement"]
    assert (out / "points" / "r_a2.npz").is_file()


def test_a_rerun_skips_finished_points(small, monkeypatch):
    settings, out, study = small

    def boom(*a, **k):
        raise AssertionError("a finished point was run again")

    monkeypatch.setattr(xy_stage_reference, "run_point", boom)
    again = run_reference(settings, out)
    assert again.points[("r", 2.0)]["improvement"] == study.points[("r", 2.0)]["improvement"]


def test_tables_and_report(small):
    from microfab.experiments.seed002_reference.job import ReferenceResult
    from microfab.experiments.seed002_reference.report import write_report

    _, out, study = small
    res = ReferenceResult(study=study)
    tables = res.comparison()
    assert tables[0].rows[0][0] == "r"
    assert "/ —" in tables[0].rows[0][2]  # no seed time at 2 m/s² for the letter r
    assert all(t.columns[-1] == "ours is" and len(t.labels) == len(t.rows) for t in tables)
    assert all(lab.origin == "predicted" for lab in tables[0].labels)  # Table III: a check
    page = write_report(study, out, "t")
    assert page.is_file() and "Table III" in page.read_text()
    json.dumps(res.summary())


def test_every_point_reports_what_its_stages_reached(small):
    """Issue 43: no point says converged with a broken constraint; the page and summary.json
    show each point's status, and for an infeasible one the constraint, residual, sample."""
    from microfab.experiments.seed002_reference.job import ReferenceResult
    from microfab.experiments.seed002_reference.report import write_report
    from microfab.experiments.seed002_reference.tables import reached_table

    _, out, study = small
    p = study.points[("r", 2.0)]
    s1, s2 = p["stage1"], p["stage2"]
    assert s1["converged"] is s1["feasibility"]["feasible"] is True
    res2 = s2["feasibility"]["residuals"]
    assert set(res2) == {"tolerance", "workspace", "velocity", "acceleration"}
    all_hold = all(r["holds"] for r in res2.values())
    assert s2["converged"] <= all_hold  # converged implies every constraint holds
    # the tiny networks' prediction turns at 10-20 m/s², far beyond a_max = 2 m/s² (14f)
    assert not all_hold and s2["status"] == "infeasible" and not s2["converged"]
    summary = ReferenceResult(study=study).summary()
    row = summary["reached"][0]
    assert row["stage2"] == s2["status"] and row["stop"] == s2["stop"]
    table = reached_table(study)
    page = write_report(study, out, "t").read_text()
    assert "What the optimisation reached" in page
    worst = s2["feasibility"]["worst"]
    assert (row["constraint"], row["excess"], row["sample"]) == (
        worst["constraint"], worst["excess"], worst["sample"])  # fmt: skip
    assert table.rows[0][3] == "infeasible" and worst["equation"] in table.rows[0][4]
    assert "stage 2 ended infeasible on 1 of 1 points" in page
    assert any("infeasible" in w for w in ReferenceResult(study=study).warnings())
    assert p["prediction"]["rms_m"]["x"] > 0 and "warnings" in summary
