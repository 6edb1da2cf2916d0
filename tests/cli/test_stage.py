"""``microfab stage excite`` (seed 002 §III-C): command files for the XY stage."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.identify.excitation import INDEX_FILE, read_runs
from microfab.io.trace import read_trace
from microfab.plants.xy_stage import xy_stage_twin

runner = CliRunner()


@pytest.mark.parametrize(
    ("kind", "duration", "fmt", "n_runs"),
    [("random", "2", "csv", 1), ("shapes", "2", "h5", None), ("prbs", "2", "csv", 2),
     ("chirp", "4", "h5", 2)],
)  # fmt: skip
def test_excite_writes_runs_that_read_back_and_pass_the_twins_guard(
    tmp_path: Path, kind: str, duration: str, fmt: str, n_runs: int | None
):
    out = tmp_path / "runs"
    res = runner.invoke(
        app,
        ["stage", "excite", "--kind", kind, "--duration", duration, "--format", fmt,
         "--amax", "5", *([] if kind == "chirp" else ["--seed", "3"]), "--out", str(out)],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    runs = read_runs(out)  # digests checked against the index
    assert runs and (n_runs is None or len(runs) == n_runs)
    meta = json.loads((out / INDEX_FILE).read_text())
    files = sorted(p.name for p in out.iterdir() if p.name != INDEX_FILE)
    assert files == sorted(e["file"] for e in meta["runs"])
    assert all(f.endswith("." + fmt) for f in files)
    tr = read_trace(out / files[0])
    assert tr.axes == ("input_x", "input_y") and tr.unit == "m"
    assert 1 / tr.dt == pytest.approx(1e4)
    total = sum(r.duration for r in runs)
    assert total == pytest.approx(float(duration), abs=1.5 if kind == "shapes" else 0.1)
    twin = xy_stage_twin()
    for r in runs:
        guarded, counts = twin.guard(r.command)
        assert counts.limited == 0, r.name
        np.testing.assert_array_equal(guarded, r.command)
        assert max(r.peaks()["acceleration_m_s2"]) <= 5.0 * (1 + 1e-9)
    assert f"{len(runs)} {kind} runs" in res.output and "wrote" in res.output


def test_excite_is_seeded(tmp_path: Path):
    for name, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        args = ["stage", "excite", "--duration", "1", "--seed", seed, "--out", str(tmp_path / name)]
        assert runner.invoke(app, args).exit_code == 0
    a, b, c = (read_runs(tmp_path / n)[0].command for n in "abc")
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (
            ["--kind", "sine"],
            "Invalid value for '--kind': 'sine' is not one of random, shapes, prbs, chirp",
        ),
        (["--format", "xls"], "Invalid value for '--format': 'xls' is not one of csv, h5, mat"),
        (["--duration", "0"], "'--duration': 0 s is outside the allowed range [0.5, 3600] s"),
        (["--duration", "nan"], "'--duration': nan is not a finite number"),
        (["--duration", "1e9"], "outside the allowed range [0.5, 3600] s"),
        (["--amax", "0"], "'--amax': 0 m/s² is outside the allowed range [0.001, 40] m/s²"),
        (["--amax", "41"], "outside the allowed range [0.001, 40] m/s²"),
        (["--seed", "-1"], "--seed"),
        (["--kind", "shapes", "--duration", "0.6"], "shapes runs: no runs to write"),
    ],
)
def test_excite_refusals_write_nothing(tmp_path: Path, one_error_line, args, says):
    out = tmp_path / "runs"
    res = runner.invoke(app, ["stage", "excite", *args, "--out", str(out)])
    one_error_line(res, says)
    assert not out.exists()


def test_excite_refuses_an_existing_set_and_a_file(tmp_path: Path, one_error_line):
    out = tmp_path / "runs"
    assert (
        runner.invoke(app, ["stage", "excite", "--duration", "1", "--out", str(out)]).exit_code == 0
    )
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    res = runner.invoke(
        app, ["stage", "excite", "--duration", "1", "--seed", "4", "--out", str(out)]
    )
    one_error_line(res, "already holds runs.json")
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    f = tmp_path / "file"
    f.write_text("x")
    res = runner.invoke(app, ["stage", "excite", "--duration", "1", "--out", str(f)])
    one_error_line(res, "is a file")
    assert f.read_text() == "x"


def test_stage_is_listed_in_the_help():
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0 and "stage" in res.output
    res = runner.invoke(app, ["stage", "--help"])
    assert res.exit_code == 0 and "excite" in res.output
