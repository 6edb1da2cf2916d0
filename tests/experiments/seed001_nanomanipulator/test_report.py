"""The nanomanipulator-msl job through its kind: run, summary, report and reproduction."""

from __future__ import annotations

import json

from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS
from microfab.experiments.kinds import no_progress
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


def test_reproduction_gives_the_seed_table():
    rep = REPRODUCTIONS["nanomanipulator"]
    out = rep.run(rep.parse_options({"fig8_sweep": "octaves"}), no_progress)  # fine: ~1 min
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
