"""``microfab optimize`` (seed 002 §IV): both stages on a drawing, files, refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.core.limits import MachineLimits, check_trajectory
from microfab.io.trace import read_columns
from microfab.trajectory.base import Trajectory

pytest.importorskip("casadi")
pytest.importorskip("torch")
runner = CliRunner()


def test_optimize_writes_a_checked_command_and_resumes(tiny_models, tmp_path):
    d, _ = tiny_models
    out = tmp_path / "opt"
    args = ["optimize", "circle:radius=0.002", "--model", str(d), "--out", str(out),
            "--amax", "2", "--n", "80"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.iterdir()}
    assert {"command.csv", "baseline.csv", "input_400hz.csv", "predicted.csv", "stage1.npz",
            "summary.json", "contour.png", "deviation.png",
            "stage2_checkpoint.npz"} <= names  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    # the stage's command files (what `stage play` reads): time, input_x, input_y at 10 kHz
    for f in ("command.csv", "baseline.csv"):
        cols = read_columns(out / f)
        assert list(cols) == ["time", "input_x", "input_y"]
        pos = np.column_stack([cols["input_x"], cols["input_y"]])
        check_trajectory(Trajectory(dt=1e-4, position=pos, at_rest=True),
                         MachineLimits.seed002_stage())  # fmt: skip
    # the baseline reaches t_M (the reference job scores t_1 … t_M), the command starts 2
    # input samples early (LEAD)
    assert cols["time"][-1] == pytest.approx(summary["m"] / 400, abs=1e-9)
    cmds = summary["commands"]
    assert cmds["optimised"] == {"file": "command.csv", "t0_sample": 50, "lead": 2}
    assert cmds["baseline"]["t0_sample"] == 0
    assert summary["stage2"]["merit_end"] <= summary["stage2"]["merit_start"]
    assert summary["predicted"]["linf"] > 0
    # a rerun resumes stage 2 from its checkpoint
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    again = json.loads((out / "summary.json").read_text())
    assert again["stage2"]["resumed_from"] == summary["stage2"]["iterations"]


def test_stage_one_needs_only_the_linear_model(tiny_models, tmp_path):
    d, _ = tiny_models
    lin_only = tmp_path / "lin"
    lin_only.mkdir()
    (lin_only / "linear_model.json").write_text((d / "linear_model.json").read_text())
    out = tmp_path / "s1"
    args = ["optimize", "circle:radius=0.002", "--model", str(lin_only), "--out", str(out),
            "--stage", "1", "--n", "60", "--format", "h5"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert (out / "command.h5").is_file() and not (out / "predicted.csv").exists()


def test_stage_one_worse_than_the_baseline_says_so(tiny_models, tmp_path, monkeypatch):
    """When stage 1 alone is predicted worse than the stretched command, the user is told."""
    from microfab.optimize import pipeline

    monkeypatch.setattr(pipeline.Stage1Check, "worse", property(lambda self: True))
    d, _ = tiny_models
    out = tmp_path / "s1"
    args = ["optimize", "circle:radius=0.002", "--model", str(d), "--out", str(out),
            "--stage", "1", "--n", "60"]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert "stretched to the same T" in summary["warning"]
    assert "warning:" in res.output and "stretched" in res.output


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--amax", "0"], "'--amax': 0 m/s² is outside the allowed range [0.001, 40] m/s²"),
        (["--amax", "1e-12"], "is outside the allowed range [0.001, 40] m/s²"),
        (["--amax", "41"], "is outside the allowed range [0.001, 40] m/s²"),
        (["--tolerance", "-1e-6"], "is outside the allowed range [1e-09, 0.001] m"),
        (["--tolerance", "5e-324"], "is outside the allowed range [1e-09, 0.001] m"),
        (["--n", "5"], "'--n': 5 is outside the allowed range [10, 5000]"),
        (["--n", "2147483648"], "'--n': 2147483648 is outside the allowed range [10, 5000]"),
        (["--stage", "3"], "Invalid value for '--stage': '3' is not one of 1, both"),
        (["--format", "xls"], "Invalid value for '--format': 'xls' is not one of csv, h5, mat"),
    ],
)
def test_bad_options_refused_and_nothing_written(tiny_models, tmp_path, one_error_line, extra,
                                                 says):  # fmt: skip
    d, _ = tiny_models
    out = tmp_path / "o"
    res = runner.invoke(app, ["optimize", "circle:radius=0.002", "--model", str(d),
                              "--out", str(out), *extra])  # fmt: skip
    one_error_line(res, says)
    assert not out.exists()


def test_bad_drawing_and_model_refused(tiny_models, tmp_path, one_error_line):
    d, _ = tiny_models
    out = tmp_path / "o"
    res = runner.invoke(app, ["optimize", "circle:radius=0.3", "--model", str(d), "--out",
                              str(out)])  # fmt: skip
    one_error_line(res, "leaves the workspace")
    res = runner.invoke(app, ["optimize", "text:ab", "--model", str(d), "--out", str(out)])
    one_error_line(res, "contours: choose one with --contour")
    res = runner.invoke(app, ["optimize", "circle:radius=0.002", "--model", str(tmp_path),
                              "--out", str(out)])  # fmt: skip
    one_error_line(res, "linear_model.json; make it with `microfab identify linear RUNS")
    assert not out.exists()


def test_the_shipped_models_folder_is_an_input_even_when_not_named():
    """Without --model the shipped models are read: --out there is refused, nothing written."""
    from microfab.optimize.models import builtin_models_dir

    d = builtin_models_dir()
    before = sorted(p.name for p in d.rglob("*"))
    res = runner.invoke(app, ["optimize", "circle:radius=0.002", "--out", str(d), "--stage", "1"])
    assert res.exit_code == 2 and "is also an input" in res.output, res.output
    assert sorted(p.name for p in d.rglob("*")) == before
