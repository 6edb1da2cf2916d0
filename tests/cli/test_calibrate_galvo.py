"""``microfab calibrate galvo`` on the calibration core: table, files, resume, refusals."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.plants.galvo import default_galvo_axes

#: The least budget the core takes for six parameters (one population and the polish);
#: about 85 model runs with the sensitivity and the conflict sweep, 2-3 s.
BUDGET = "20"


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """One small calibration with every file option; then the same run folder again."""
    tmp = tmp_path_factory.mktemp("galvo")
    runner = CliRunner()
    argv = [
        "calibrate",
        "galvo",
        "--budget",
        BUDGET,
        "--out",
        str(tmp / "run"),
        "--json",
        str(tmp / "cal.json"),
        "--write",
        str(tmp / "twin.toml"),
    ]
    first = runner.invoke(app, argv)
    again = runner.invoke(app, argv)
    return tmp, first, again


def test_prints_the_per_target_table_and_writes_the_files(ran):
    tmp, res, _ = ran
    assert res.exit_code == 0, res.output
    out = res.output
    assert "seed 000 galvo twin: targets" in out and "seed 000 galvo twin: free parameters" in out
    for row in ("x fb_rms @100\tfit", "y ilc_rms @100\tfit", "x ilc_pp @400\tcheck"):
        assert row in out, row
    assert "seed 000 Table 1 (y axis, FB PP, 400 features/s)" in out
    assert "converged" in out  # the one-line verdict, met or not, with its counts
    report = json.loads((tmp / "cal.json").read_text())
    assert len(report["targets"]) == 24
    assert (tmp / "run" / "calibration.json").exists()
    axes = default_galvo_axes(tmp / "twin.toml")  # the written twin reads back
    for a in ("x", "y"):
        values = {p["name"]: p["value"] for p in report["parameters"]}
        assert axes[a].rigid_pole_hz == pytest.approx(values[f"{a} rigid_pole_hz"], rel=1e-5)
    assert "calibrated: `microfab calibrate galvo`" in (tmp / "twin.toml").read_text()


def test_the_same_run_folder_resumes_without_new_model_runs(ran):
    _, first, again = ran
    assert again.exit_code == 0, again.output
    assert " 0 evaluated" in again.output
    verdict = [ln for ln in first.output.splitlines() if "fit targets met" in ln]
    assert verdict and verdict[0].split(";")[0] in again.output


def test_refusals_are_one_error_line_and_write_nothing(tmp_path, one_error_line):
    runner = CliRunner()
    twin = tmp_path / "twin.toml"
    res = runner.invoke(app, ["calibrate", "galvo", "--budget", "5", "--write", str(twin)])
    one_error_line(res, "budget 5 is below one population of the search over 6 parameters")
    res = runner.invoke(app, ["calibrate", "galvo", "--fresh"])
    one_error_line(res, "--fresh needs --out")
    res = runner.invoke(app, ["calibrate", "galvo", "--budget", "4"])
    one_error_line(res, "--budget")
    assert list(tmp_path.iterdir()) == []
