"""The ``stage-identify`` job kind and the ``stage-models`` reproduction (seed 002 part 1)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS, load_job
from microfab.experiments.kinds import no_progress
from microfab.experiments.seed002_stage.job import STAGE_IDENTIFY, config_from_sections
from microfab.identify.stage_data import RunErrors, read_stage_model
from microfab.io.job import JobFileError, parse_job

EXAMPLE = Path(__file__).parents[3] / "examples" / "blackbox_stage_identify.toml"

TINY = """
[job]
kind = "stage-identify"
[linear]
total_s = 20.0
orders = [2, 4]
[ann]
total_s = 20.0
max_epochs = 1
epoch_windows = 4096
val_windows = 4096
workers = 1
[cases]
table_a_max = [1.0, 3.0]
sweep_a_max = [1.0]
"""


def _job(text: str):
    import tomllib

    file = parse_job(tomllib.loads(text), "job.toml")
    return JOB_KINDS["stage-identify"].config(file)


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    out = tmp_path_factory.mktemp("stage")
    cfg = _job(TINY)
    result = STAGE_IDENTIFY.run(cfg, out, no_progress)
    report = STAGE_IDENTIFY.write_report(result, out, "tiny")
    return out, result, report


def test_registered_with_its_example():
    assert JOB_KINDS["stage-identify"] is STAGE_IDENTIFY
    assert "stage-models" in REPRODUCTIONS
    job = load_job(EXAMPLE)
    s = job.config
    assert s.linear.total_s == 600.0 and s.linear.order == 4  # seed §III-C.1, §III-A
    assert s.ann is not None and s.ann.validation == 0.2  # seed §III-C
    assert s.cases.table_a_max == (1.0, 3.0)  # seed Fig. 8
    assert s.coupling and s.classic


@pytest.mark.parametrize(
    ("line", "whiten"), [("", 1e-3), ("whiten = 0.0\n", None), ("whiten = 0.01\n", 0.01)]
)
def test_the_networks_whitening_is_a_job_key(line: str, whiten: float | None):
    """[ann] whiten: the default, 0 (off: the training before whitening), or a shrinkage."""
    assert _job(TINY.replace("[ann]\n", f"[ann]\n{line}")).ann.whiten == whiten


@pytest.mark.parametrize("value", ["1e-9", "1.5", "-0.1"])
def test_a_whitening_out_of_its_range_is_refused(value: str):
    with pytest.raises((ValueError, JobFileError), match="whiten"):
        _job(TINY.replace("[ann]\n", f"[ann]\nwhiten = {value}\n"))


def test_config_refusals():
    with pytest.raises(ValueError, match="need the networks"):
        _job(TINY.replace("[ann]\n", "[ann]\nenabled = false\n"))
    with pytest.raises(JobFileError, match="bogus"):
        _job(TINY + "\n[twin]\nbogus = 1\n")
    with pytest.raises(ValueError, match="table_a_max"):
        _job(TINY.replace("table_a_max = [1.0, 3.0]", "table_a_max = []"))
    with pytest.raises(JobFileError):
        _job(TINY.replace("sweep_a_max = [1.0]", "sweep_a_max = [-1.0]"))
    sec = {
        "twin": {"seed": 0, "noise": True, "hold_s": 0.5, "magnitudes": "assumed"},
        "linear": {"total_s": 20.0, "a_max": 5.0, "order": 4, "decimate": 10,
                   "feedthrough": True, "orders": [], "seed": 0},
        "ann": {"enabled": False, "total_s": 1.0, "random_share": 0.6, "validation": 0.2,
                "max_epochs": 1, "epoch_windows": 0, "val_windows": 0, "threads": 1,
                "workers": 1, "seed": 0},
        "cases": {"table_a_max": [1.0], "sweep_a_max": [], "r_time_s": 0.807,
                  "airfoil_time_s": 1.322},
        "studies": {"coupling": False, "classic": False},
    }  # fmt: skip
    s = config_from_sections(sec)
    assert s.ann is None and s.orders == ()
    # the assumed magnitudes: the reference friction and cogging, before calibration
    assert dict(s.twin.changes)["coulomb_n"] == (20.0, 12.0)
    with pytest.raises(ValueError, match="magnitudes must be one of"):
        config_from_sections({**sec, "twin": {**sec["twin"], "magnitudes": "soft"}})


def test_the_job_writes_its_models_summary_and_report(ran):
    out, result, report = ran
    assert report == out / "report.html"
    for name in ("summary.json", "linear_model.json", "fig9.png", "fig8_histograms.png",
                 "bode.png", "excitation.png", "losses.png", "prediction.png"):  # fmt: skip
        assert (out / name).is_file(), name
    for folder in ("ann", "ann_coupled", "ann_classic"):
        assert (out / folder / "model").is_dir()
    summary = json.loads((out / "summary.json").read_text())
    ours = summary["table_ii"]["ours"]
    assert set(ours) == {"linear", "ann"}
    assert summary["table_ii"]["seed"]["linear"]["x"]["training"][1] == pytest.approx(48.0e-6)
    # the files read back as models `identify validate` takes
    lin = read_stage_model(out / "linear_model.json")
    assert lin.kind == "linear"
    ann = read_stage_model(out / "ann" / "model")
    assert ann.kind == "ann"
    study = result.study
    err = lin.errors(study.case("r", 1.0).record)
    assert np.allclose(err.std, study.case("r", 1.0).linear.std)


def test_table_ii_columns_pool_the_four_letters(ran):
    study = ran[1].study
    pooled = study.letters(3.0, "linear")
    parts = [study.case(ch, 3.0).linear for ch in "urch"]
    e = np.concatenate([p.samples for p in parts])
    assert pooled.n_samples == e.shape[0]
    assert np.allclose(pooled.mean, e.mean(axis=0))
    assert np.allclose(pooled.std, e.std(axis=0))
    # every case ran within Table I: the guard changed nothing
    assert all(c.limited == 0 for c in study.cases)
    assert {c.a_max for c in study.cases} == {1.0, 3.0}
    assert len(study.orders) == 2 and study.orders[1].order == 4


def test_a_rerun_resumes_the_trainings(ran, tmp_path):
    out, result, _ = ran
    again = STAGE_IDENTIFY.run(_job(TINY), out, no_progress).study
    for name in ("ann", "coupled", "classic"):
        a, b = getattr(result.study, name), getattr(again, name)
        assert a.validation == b.validation  # the finished trainings are read back


def test_run_errors_pooled_needs_kept_samples():
    e = RunErrors.of([("a", np.ones((3, 2)))], 1e3)
    with pytest.raises(ValueError, match="keep"):
        RunErrors.pooled([e])
    with pytest.raises(ValueError, match="no error samples"):
        RunErrors.of([], 1e3)


def test_reproduction_runs_the_seed_design():
    from microfab.experiments.seed002_stage.job import reproduction_settings

    rep = REPRODUCTIONS["stage-models"]
    opts = rep.parse_options({})
    assert opts == {"seed": 0, "noise": True, "magnitudes": "calibrated", "networks": True,
                    "studies": True, "checkpoints": ""}  # fmt: skip
    s = reproduction_settings(opts)
    assert s.linear.total_s == 600.0 and s.ann is not None and s.coupling and s.classic
    assert s.twin.changes == ()  # the twin file's (calibrated) magnitudes
    lin_only = reproduction_settings(rep.parse_options({"networks": False}))
    assert lin_only.ann is None and not lin_only.coupling and not lin_only.classic
    with pytest.raises(JobFileError, match="unknown key"):
        rep.parse_options({"epochs": 3})


def test_seed_values_only_beside_columns_at_the_seeds_a_max(ran):
    import dataclasses

    from microfab.experiments.seed002_stage.study import CaseSettings
    from microfab.experiments.seed002_stage.tables import cases_table, table_ii

    study = ran[1].study
    row = table_ii(study).rows[0]  # linear x: training, letters at 1 and 3 m/s²
    assert row[3].endswith("/ 48.0") and row[5].endswith("/ 30.1") and row[7].endswith("/ 57.2")
    swapped = dataclasses.replace(
        study,
        settings=dataclasses.replace(
            study.settings, cases=CaseSettings(table_a_max=(3.0, 1.0), sweep_a_max=(1.0,))
        ),
    )
    row = table_ii(swapped).rows[0]
    assert row[3].endswith("/ 48.0")  # training: no a_max
    assert row[5].endswith("/ —") and row[7].endswith("/ —")  # not the seed's a_max there
    r_row = next(r for r in cases_table(swapped).rows if r[0] == "r")
    assert r_row[1].endswith("/ 0.473") and r_row[2].endswith("/ 0.807")


def test_table_ii_labels_the_calibrated_sigma_fitted_and_the_networks_predicted(ran):
    import dataclasses

    from microfab.experiments.seed002_stage.tables import cases_table, table_ii
    from microfab.machines.xy_stage.calibration import assumed_changes, table_ii_quantity

    study = ran[1].study
    labels = table_ii(study).labels  # linear x, linear y, ANN x, ANN y
    # the core's fit: linear σ and μ and the networks' σ (through the proxy) on column 1;
    # the letters columns are predicted
    assert labels[0].origin == "mixed"
    assert set(labels[0].fitted) == {
        table_ii_quantity("linear", "x", "training", k) for k in ("sigma", "mu")
    }
    assert labels[0].by == ("microfab calibrate xy-stage",)
    assert [lab.origin for lab in labels[2:]] == ["mixed", "mixed"]
    assert labels[3].fitted == (table_ii_quantity("ann", "y", "training", "sigma"),)
    # the twin at its assumed magnitudes: the calibration did not act, nothing is fitted
    assumed = dataclasses.replace(
        study,
        settings=dataclasses.replace(
            study.settings,
            twin=dataclasses.replace(study.settings.twin, changes=assumed_changes()),
        ),
    )
    assert all(lab.origin == "predicted" for lab in table_ii(assumed).labels)
    cases = cases_table(study)
    by_case = dict(zip((r[0] for r in cases.rows), cases.labels, strict=True))
    assert by_case["r"].fitted and by_case["airfoil"].fitted  # the sizes are fitted to them
    assert not by_case["u"].fitted and by_case["u"].origin == "predicted"
