"""``microfab calibrate xy-stage`` on the calibration core: tables, files, resume, refusals."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from microfab.calibrate.solve import de_sized
from microfab.cli import app
from microfab.machines.xy_stage import calibration_core as cc
from microfab.plants.xy_stage_params import load_params

#: The least budget the core takes for the problem's parameters (one population of the
#: search and the polish; 26 for 8): with the sensitivity about 40 model runs.
LEAST = next(b for b in range(5, 1000) if de_sized(b, len(cc.PARAMETERS), True) >= 0)

#: The smallest data the problem runs on and a small proxy, about 0.08 s an evaluation:
#: 0.5 s of linear runs (the shortest run the identification reads) and 4 s of the
#: networks' data, which with runs seed 5 splits into two training runs and one validation
#: run (seed 0 needs 10 s for one). The test checks the command's plumbing, not figures.
TINY = ["--duration", "0.5", "--ann-duration", "4", "--runs-seed", "5", "--proxy-hidden", "8",
        "--proxy-offsets", "1"]  # fmt: skip


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """One tiny calibration with every file option; then the same run folder again."""
    tmp = tmp_path_factory.mktemp("xy")
    runner = CliRunner()
    argv = ["calibrate", "xy-stage", *TINY, "--budget", str(LEAST), "--conflict-budget", "0",
            "--out", str(tmp / "run"), "--json", str(tmp / "cal.json"),
            "--write", str(tmp / "twin.toml")]  # fmt: skip
    first = runner.invoke(app, argv)
    again = runner.invoke(app, argv)
    return tmp, first, again


def test_prints_the_fit_and_check_tables_and_writes_the_files(ran):
    tmp, res, _ = ran
    assert res.exit_code == 0, res.output
    out = res.output
    assert "seed 002 XY stage twin: targets" in out
    assert "seed 002 XY stage twin: free parameters" in out
    for name in cc.FIT_NAMES:
        assert f"{name}\tfit" in out, name
    assert f"{cc.CHECK_NAMES[0]}\tcheck" in out
    assert "coulomb_x_n\t" in out and "reaction_coupling\t" in out
    assert "fit targets met" in out  # the verdict, met or not, with its counts
    assert "forces at the answer:" in out and "x: Coulomb" in out
    report = json.loads((tmp / "cal.json").read_text())
    assert [t["name"] for t in report["targets"]] == [*cc.FIT_NAMES, *cc.CHECK_NAMES]
    assert (tmp / "run" / "calibration.json").exists()
    # the written twin reads back with the answer's values, each sourced to the command
    values = {p["name"]: p["value"] for p in report["parameters"]}
    cfg = load_params(tmp / "twin.toml")
    assert cfg.coulomb_n[0] == pytest.approx(values["coulomb_x_n"], rel=1e-4)
    assert cfg.resonance_hz == pytest.approx(values["resonance_hz"], rel=1e-4)
    text = (tmp / "twin.toml").read_text(encoding="utf-8")
    assert "calibrated: `microfab calibrate xy-stage` fits coulomb_x_n jointly to" in text
    assert "linear_sigma_y_um (" in text and "proxy_sigma_x_um (" in text
    assert "checks held back: slowest_time_constant_ms" in text


def test_the_same_run_folder_resumes_without_new_model_runs(ran):
    _, first, again = ran
    assert again.exit_code == 0, again.output
    assert " 0 evaluated" in again.output
    verdict = [ln for ln in first.output.splitlines() if "fit targets met" in ln]
    assert verdict and verdict[0].split(";")[0] in again.output


def test_refusals_are_one_error_line_and_write_nothing(tmp_path, one_error_line):
    runner = CliRunner()
    twin, folder = tmp_path / "twin.toml", tmp_path / "folder"
    folder.mkdir()
    cases = [
        (["--budget", str(LEAST - 1), "--write", str(twin)],
         f"budget {LEAST - 1} is below one population of the search over "
         f"{len(cc.PARAMETERS)} parameters"),
        (["--budget", "4"], "--budget"),
        (["--fresh"], "--fresh needs --out"),
        (["--write", str(folder)], "--write"),
        (["--json", str(twin), "--write", str(twin)], "the same path"),
        (["--out", str(twin)], "--out"),
    ]  # fmt: skip
    (tmp_path / "twin.toml").write_text("untouched")
    before = {p: p.read_bytes() if p.is_file() else None for p in tmp_path.rglob("*")}
    for argv, says in cases:
        res = runner.invoke(app, ["calibrate", "xy-stage", *TINY, *argv])
        one_error_line(res, says)
    assert {p: p.read_bytes() if p.is_file() else None for p in tmp_path.rglob("*")} == before
