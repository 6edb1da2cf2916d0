"""The shared part of ``microfab calibrate <machine>``: run folder, tables, files."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from typer.testing import CliRunner

from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.cli._calibrate_kit import (
    BudgetOption,
    FreshOption,
    JsonOption,
    OutOption,
    SeedOption,
    WorkersOption,
    run_calibration,
)

from ..calibrate.test_solve import consistent

TWIN = '[axes]\ngain = 0.5\ngain_source = "assumed: toy"\n'


def _app(twin: Path) -> typer.Typer:
    app = typer.Typer()

    @app.command()
    def toy(
        out: OutOption = None,
        fresh: FreshOption = False,
        json_out: JsonOption = None,
        write: Path | None = None,
        budget: BudgetOption = None,
        seed: SeedOption = 1,
        workers: WorkersOption = 1,
    ) -> None:
        run_calibration(
            consistent(),
            title="toy",
            budget=budget or 150,
            seed=seed,
            workers=workers,
            out=out,
            fresh=fresh,
            json_out=json_out,
            write=write,
            write_twin=lambda r, p: write_calibrated(
                r,
                [TwinKey("x", "axes", "gain")],
                command="microfab calibrate toy",
                data_file="x.toml",
                path=p,
                source=twin,
            ),
        )

    @app.command()
    def other(out: OutOption = None) -> None:  # another problem on the same folder
        run_calibration(
            consistent(high=6.0),
            title="toy",
            budget=20,
            seed=1,
            workers=1,
            out=out,
            fresh=False,
            json_out=None,
            write=None,
            write_twin=lambda r, p: p,
        )

    return app


def test_tables_files_resume_and_refusals(tmp_path, one_error_line):
    twin = tmp_path / "twin.toml"
    twin.write_text(TWIN)
    app, run = _app(twin), CliRunner().invoke
    out = tmp_path / "run"
    res = run(app, ["toy", "--out", str(out), "--json", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    assert "chk" in res.output and "check" in res.output and "converged" in res.output
    assert (out / "memo.json").is_file() and (out / "calibration.json").is_file()
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["converged"] is True and len(doc["targets"]) == 3
    assert doc["evaluated"] > 0
    # rerun on the same folder: every point comes from the memo
    res = run(app, ["toy", "--out", str(out), "--json", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "r.json").read_text())["evaluated"] == 0
    # another problem in that folder is refused, nothing changed
    before = (out / "memo.json").read_bytes()
    one_error_line(run(app, ["other", "--out", str(out)]), "--out")
    assert (out / "memo.json").read_bytes() == before
    # --fresh without --out, and a budget below 5, are refused before any work
    one_error_line(run(app, ["toy", "--fresh"]), "--fresh needs --out")
    res = run(app, ["toy", "--budget", "2"])  # the option's range (one line under `microfab`)
    assert res.exit_code == 2 and "outside the allowed range [5, 100000]" in res.output
    # the twin file: written with the calibrated value; a refused write leaves it
    res = run(app, ["toy", "--write", str(twin)])
    assert res.exit_code == 0, res.output
    assert "calibrated: `microfab calibrate toy`" in twin.read_text()
    one_error_line(run(app, ["toy", "--write", str(tmp_path)]), "--write")
