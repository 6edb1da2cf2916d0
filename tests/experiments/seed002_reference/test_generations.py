"""The reference study with the networks' generations (seed 002 Fig. 7) on a small setting.

Tiny networks, 10 s of generation-1 data, two 3 mm shapes, the letter r at 2 m/s², two
stage-2 iterations and two epochs per retraining: the study's mechanics and its tables.
"""

from __future__ import annotations

import json

import pytest

pytest.importorskip("casadi")
pytest.importorskip("torch")

from microfab.experiments.catalog import REPRODUCTIONS, load_job
from microfab.experiments.kinds import ReproductionResult
from microfab.experiments.seed002_reference import job as job_mod
from microfab.experiments.seed002_reference.job import ReferenceResult
from microfab.experiments.seed002_reference.study import (
    ReferenceSettings,
    run_reference,
)
from microfab.experiments.seed002_reference.tables import NOTES
from microfab.identify import stage_ann
from microfab.machines.xy_stage import reference as xy_stage_reference
from microfab.machines.xy_stage.cases import CaseSizes
from microfab.machines.xy_stage.machine import TwinSettings


def small(models_dir, **kw) -> ReferenceSettings:
    base = dict(models_dir=str(models_dir), twin=TwinSettings(hold_s=0.51), cases=("r",),
                a_max=(2.0,), airfoil_extra=(), tolerance_m=100e-6, sizes=CaseSizes(5e-3, 20e-3),
                stage2_max_iter=2, generations=2, generation_shapes=("circle", "square"),
                generation_size_m=3e-3, generation_a_max=(2.0,), retrain_epochs=2,
                generation_data_s=10.0, retrain_workers=1)  # fmt: skip
    return ReferenceSettings(**{**base, **kw})


@pytest.fixture(scope="module")
def study(tiny_models, tmp_path_factory):
    d, _ = tiny_models
    out = tmp_path_factory.mktemp("refgen")
    st = small(d)
    return st, out, run_reference(st, out)


def test_table_iii_runs_with_each_generations_models(study):
    st, out, s = study
    assert s.generations is not None and len(s.generations.generations) == 2
    assert len(s.earlier) == 1 and s.settings == st
    first, last = s.earlier[0].points[("r", 2.0)], s.points[("r", 2.0)]
    assert "error" not in first and "error" not in last
    assert first["fingerprint"] != last["fingerprint"]  # other models
    assert first["scores"]["optimised_ann"] != last["scores"]["optimised_ann"]
    assert (out / "generation1" / "points" / "r_a2.json").is_file()
    assert (out / "points" / "r_a2.json").is_file()
    assert (out / "generations" / "gen2" / "models" / "ann" / "model" / "model.json").is_file()


def test_per_generation_tables_exist_and_are_labelled(study):
    _, _, s = study
    res = ReferenceResult(study=s)
    tables = res.comparison()
    titles = [t.title for t in tables]
    assert titles[0].startswith("Generation 2 of 2: Table III")
    assert any(t.startswith("Generation 1 of 2: Table III") for t in titles)
    gen = next(t for t in tables if t.title.startswith("Networks against the twin"))
    assert [r[0] for r in gen.rows] == ["1", "2"]
    g1 = s.generations.generations[0]
    assert gen.rows[0][1] == f"{g1.network_error['x']['sigma_um']:.1f} / " + (
        f"{g1.network_error['y']['sigma_um']:.1f}"
    )
    assert gen.rows[0][6] == "—" and gen.rows[1][6] != "—"  # only generation 2 retrained
    assert all(t.columns[-1] == "ours is" and len(t.labels) == len(t.rows) for t in tables)
    ReproductionResult(tables=tables, notes=NOTES, data=res.summary())  # refuses unlabelled
    summary = json.loads(json.dumps(res.summary()))
    assert [g["generation"] for g in summary["generations"]] == [1, 2]
    assert summary["generations"][1]["training"]["epochs"] == {"x": 2, "y": 2}


def test_report_shows_both(study, page_check):
    from microfab.experiments.seed002_reference.report import write_report

    _, out, s = study
    page = write_report(s, out, "t")
    text = page.read_text()
    assert "Generation 1 of 2: Table III" in text
    assert "Networks against the twin per generation" in text
    assert "Generations (seed 002" in text and "generations.png" in text
    if page_check is not None:  # every image decodes, the console stays silent
        page_check(page)


def test_a_rerun_skips_finished_generations_and_points(study, monkeypatch):
    st, out, s = study

    def boom(*a, **k):
        raise AssertionError("finished work was run again")

    monkeypatch.setattr(xy_stage_reference, "run_point", boom)
    monkeypatch.setattr(stage_ann, "train_stage_ann", boom)
    again = run_reference(st, out)
    assert again.points[("r", 2.0)]["improvement"] == s.points[("r", 2.0)]["improvement"]
    assert again.earlier[0].points == s.earlier[0].points
    assert [g.network_error for g in again.generations.generations] == [
        g.network_error for g in s.generations.generations
    ]


def test_other_generation_settings_in_the_same_folder_refused(study):
    from microfab.io.runstore import RunRefusedError

    st, out, _ = study
    with pytest.raises(RunRefusedError, match=r"size_m 0\.003 -> 0\.004"):
        run_reference(small(st.models_dir, generation_size_m=4e-3), out)


def test_job_file_and_reproduction_options(tmp_path, monkeypatch):
    p = tmp_path / "j.toml"
    p.write_text(
        '[job]\nkind = "stage-reference-opt"\n[models]\ndir = "m"\n[generations]\ncount = 3\n'
        'shapes = "circle,spiral"\nsize_mm = 10.0\na_max = [2.0]\nretrain_epochs = 5\n',
        "utf-8",
    )
    cfg = load_job(p).config
    assert (cfg.generations, cfg.generation_shapes, cfg.generation_a_max) == (
        3, ("circle", "spiral"), (2.0,),
    )  # fmt: skip
    assert cfg.generation_size_m == pytest.approx(10e-3) and cfg.retrain_epochs == 5
    assert cfg.generation_data_s is None
    p.write_text('[job]\nkind = "stage-reference-opt"\n[generations]\nshapes = "star"\n')
    with pytest.raises(Exception, match=r"\[generations\] shapes"):
        load_job(p)
    default = tmp_path / "d.toml"
    default.write_text('[job]\nkind = "stage-reference-opt"\n', "utf-8")
    assert load_job(default).config.generations == 1  # today's behaviour
    # the reproduction passes its option through
    seen = {}

    def fake(settings, out, progress):
        seen["settings"] = settings
        raise RuntimeError("stop")

    monkeypatch.setattr(job_mod, "run_reference", fake)
    monkeypatch.setattr(job_mod, "_reproduce_preflight", lambda options: None)
    rep = REPRODUCTIONS["reference-opt"]
    options = {k.name: k.default for k in rep.options}
    with pytest.raises(RuntimeError, match="stop"):
        rep.run({**options, "generations": 3}, lambda *a: None)
    assert seen["settings"].generations == 3
