"""The nanomanipulator-msl job through its kind: run, summary, report and reproduction."""

from __future__ import annotations

import json

import pytest

from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS
from microfab.experiments.kinds import ReproductionResult, no_progress
from microfab.experiments.seed001_nanomanipulator import paper
from microfab.machines.nanomanipulator.job import JobConfig
from microfab.trajectory.circle_pattern import PatternConfig


def test_job_writes_summary_and_report(tmp_path):
    kind = JOB_KINDS["nanomanipulator-msl"]
    cfg = JobConfig(pattern=PatternConfig(n_circles=1, periods=4))
    res = kind.run(cfg, tmp_path, no_progress)
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert summary["tracking"]["gate_period"] == [c.gate_period for c in res.run.circles]
    assert set(summary["cured_lines"][0]) >= {"gated", "compensated", "ungated"}
    page = kind.write_report(res, tmp_path, "t")
    text = page.read_text(encoding="utf-8")
    for name in ("xy.png", "error_time.png", "contour_phase.png", "learning.png", "cure_1.png"):
        assert (tmp_path / name).stat().st_size > 1000
        assert name in text
    assert "485.8" not in text  # one circle is not the seed's set-up: ours alone
    assert "ours alone" in text and summary["seed"] is None
    assert not res.failures()


@pytest.fixture(scope="module")
def out() -> ReproductionResult:
    rep = REPRODUCTIONS["nanomanipulator"]
    return rep.run(rep.parse_options({"fig8_sweep": "octaves"}), no_progress)  # fine: ~1 min


def test_reproduction_gives_the_seed_table(out: ReproductionResult) -> None:
    rows = {r[0]: r[1] for r in out.tables[0].rows}
    assert rows["axial RMS x [nm]"].endswith("/ 485.8")
    # the proposed controller (issue 45), the twin's current noise: submicron from period 1
    assert out.data["gate_period"] == [2, 2, 2, 2]
    titles = [t.title for t in out.tables]
    assert any("RBF per period" in t for t in titles) and any("Fig. 8" in t for t in titles)
    assert set(out.data["rbf_study"]["rms_nm"]) >= {"seed adaptive", "proposed adaptive"}
    assert [r["bandwidth_hz"] for r in out.data["fig8_fair"]["rows"]] == [100.0, 200.0, 400.0]
    assert out.data["fig8_fair"]["divergences"] == []
    json.dumps(out.to_json(), allow_nan=False)  # what --json writes (an oracle has no weights)
    # the axial RMS is what the noise calibration fits; the contour RMS is predicted
    labels = {r[0]: lab for r, lab in zip(out.tables[0].rows, out.tables[0].labels, strict=True)}
    assert labels["axial RMS x [nm]"].origin == labels["axial RMS y [nm]"].origin == "fitted"
    assert labels["axial RMS x [nm]"].by == ("microfab calibrate nanomanipulator",)
    assert labels["contour RMS [nm]"].origin == "predicted"
    assert all(len(t.labels) == len(t.rows) for t in out.tables)


def test_figs_8_to_10_on_the_paper_model_with_the_calibrated_twin_beside_them(
    out: ReproductionResult,
) -> None:
    """Issue 45 item 2: each §4.1 figure on the paper's model, the twin's as a prediction."""
    titles = [t.title for t in out.tables]
    for fig in ("Fig. 8", "Fig. 9", "Fig. 10"):
        model = [i for i, t in enumerate(titles) if fig + "," in t and "paper's model" in t]
        twin = [i for i, t in enumerate(titles) if fig + "," in t and "calibrated twin" in t]
        assert len(model) == len(twin) == 1, (fig, titles)
        assert twin[0] == model[0] + 1, titles  # the prediction right beside the model
        for i in model + twin:
            labels = out.tables[i].labels
            assert labels and all(lab.origin == "predicted" for lab in labels), titles[i]
            assert all(q.startswith(f"seed 001 {fig} /") for lab in labels for q in lab.quantities)
    fig9 = out.tables[titles.index(next(t for t in titles if "Fig. 9" in t))]
    assert [r[0] for r in fig9.rows] == ["200", "400"]
    fig10 = out.tables[titles.index(next(t for t in titles if "Fig. 10" in t))]
    assert [r[0] for r in fig10.rows] == ["RBF", "RBF state"]
    # the numbers in --json, both runs of each figure
    d = out.data
    assert [r["bandwidth_hz"] for r in d["fig8_twin"]["rows"]] == [100.0, 200.0, 400.0]
    for run in ("paper_model", "twin"):
        assert d["fig9"][run]["bandwidths_hz"] == [200.0, 400.0]
        assert set(d["fig9"][run]["final_rms_nm"]) == {"PID", "RBF"}
        assert set(d["fig10"][run]["gain"]) == {"RBF", "RBF state"}
        assert all(len(v) == 8 for v in d["fig10"][run]["rms_nm"].values())
    # the twin differs by the sensor noise alone: it raises the PID's error at every
    # crossover (measured on Fig. 9: 190 -> 434 nm at 200 Hz, 25 -> 511 nm at 400 Hz)
    for m, t in zip(
        d["fig9"]["paper_model"]["final_rms_nm"]["PID"],
        d["fig9"]["twin"]["final_rms_nm"]["PID"],
        strict=True,
    ):
        assert t > m
    notes = " ".join(out.notes)
    assert "paper's model -> calibrated twin" in notes and "sensor noise" in notes
    assert "d0 per axis jointly to the §4.2 axial RMS" in notes  # the calibration as it is
    assert "contour RMS and the gate period are held back as checks" in notes


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 45: on the paper's model (noise off) the plug-in RC around the proposed "
    "controller (200 Hz linear part + state-model network) does not reduce the error on "
    "compare.py's circle: 132 nm alone, 156 nm with RC in the last of 8 periods (gain 0.85; "
    "best RC period 142 nm), where the seed's network gains 12.8x (463 -> 36 nm); on the "
    "calibrated twin 0.63 (462 -> 731 nm)",
)
def test_fig10_rc_cuts_the_proposed_controller_error_fivefold(out: ReproductionResult) -> None:
    gain = out.data["fig10"]["paper_model"]["gain"]["RBF state"]
    assert gain >= paper.FIG_TARGETS["fig10_rc_gain_min"], out.data["fig10"]
