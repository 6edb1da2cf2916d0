"""The own-stage loop of the README, through files, on the twin (issue 43).

``stage excite`` → ``stage play`` → ``identify linear`` / ``identify ann`` into one models
folder → ``optimize --model`` → ``stage play`` of its command and baseline → ``stage
score`` with the baseline: the README's commands, with smaller options (3 s of shapes, one
epoch of 2000 windows per axis, a 2 mm circle at N = 80) so that the loop takes seconds.
The networks are trained by ``identify ann`` itself (not the ``tiny_models`` fixture), so
the models folder is the one the README's commands write.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import read_trace, write_columns

pytest.importorskip("casadi")
pytest.importorskip("torch")
runner = CliRunner()

DRAWING = "circle:radius=0.002"
OPT = ["--amax", "2", "--n", "80"]


def _ok(*args: str) -> str:
    res = runner.invoke(app, [*args])
    assert res.exit_code == 0, res.output
    return res.output


@pytest.fixture(scope="module")
def loop(tmp_path_factory) -> tuple[Path, str]:
    """The README's loop run in one folder; the folder and ``stage score``'s output."""
    root = tmp_path_factory.mktemp("own_stage")
    runs, measured, models = root / "runs", root / "measured", root / "models"
    _ok("stage", "excite", "--kind", "shapes", "--duration", "3", "--seed", "2", "--out",
        str(runs))  # fmt: skip
    _ok("stage", "play", str(runs), "--out", str(measured))
    files = sorted(str(p) for p in measured.glob("*.csv"))
    _ok("identify", "linear", *files, "--order", "4", "--out", str(models / "linear_model.json"))
    _ok("identify", "ann", *files, "--axis", "both", "--out", str(models / "ann" / "model"),
        "--epochs", "1", "--epoch-windows", "2000", "--device", "cpu")  # fmt: skip
    opt, played = root / "opt", root / "played"
    _ok("optimize", DRAWING, "--model", str(models), *OPT, "--out", str(opt))
    _ok("stage", "play", str(opt / "command.csv"), str(opt / "baseline.csv"), "--out",
        str(played))  # fmt: skip
    out = _ok("stage", "score", str(played / "command.csv"), "--drawing", str(opt),
              "--baseline", str(played / "baseline.csv"),
              "--json", str(root / "score.json"))  # fmt: skip
    return root, out


def test_score_prints_the_three_norms_of_both_runs_and_the_improvement(loop):
    root, out = loop
    data = json.loads((root / "score.json").read_text())
    runs = data["runs"]
    assert runs["run"]["command"] == "command.csv"
    assert runs["baseline"]["command"] == "baseline.csv"
    for label in ("run", "baseline"):
        r = runs[label]
        assert 0 < r["l1"] <= r["l2"] <= r["linf"] < 1e-3  # m: ordered norms, within 1 mm
        row = next(line for line in out.splitlines() if line.startswith(f"{label}: "))
        cells = row.split("\t")
        for cell, key in zip(cells[2:5], ("l1", "l2", "linf"), strict=True):
            assert float(cell) == pytest.approx(r[key] * 1e6, abs=0.006)  # printed at 0.01 µm
    imp = data["improvement_percent"]
    row = next(line for line in out.splitlines() if line.startswith("improvement"))
    for cell, key in zip(row.split("\t")[2:5], ("l1", "l2", "linf"), strict=True):
        want = 100 * (runs["baseline"][key] - runs["run"][key]) / runs["baseline"][key]
        assert imp[key] == pytest.approx(want, rel=1e-12)  # the same formula: round-off only
        assert float(cell) == pytest.approx(want, abs=0.06)  # printed at 0.1 %


def test_score_equals_the_reference_jobs_scorer_on_the_same_files(loop):
    """`stage score` reads M, t_0 and the contour as `run_point` scores its twin runs."""
    from microfab.geometry.load import load_drawing
    from microfab.machines.xy_stage.reference import TAIL
    from microfab.optimize.command import LEAD
    from microfab.optimize.metrics import DeviationNorms
    from microfab.optimize.pipeline import at_model_rate

    root, _ = loop
    data = json.loads((root / "score.json").read_text())
    summary = json.loads((root / "opt" / "summary.json").read_text())
    path = load_drawing(DRAWING)[0]
    m = summary["m"]
    for label, name, lead in (("run", "command", LEAD), ("baseline", "baseline", 0)):
        tr = read_trace(root / "played" / f"{name}.csv")
        y = tr.values[:, [tr.axes.index("output_x"), tr.axes.index("output_y")]]
        # run_point's lines: the outputs at t_1 … t_{M+TAIL}, the tail scored apart
        want = DeviationNorms.of(path, at_model_rate(y, m, lead, TAIL), tail_from=m).as_dict()
        got = data["runs"][label]
        for key in ("l1", "l2", "linf", "tail_linf", "n"):
            # the same arrays through the same functions in one process: equal but for
            # round-off of another summation order (1e-12 relative)
            assert got[key] == pytest.approx(want[key], rel=1e-12), (label, key)


def test_score_equals_run_point_on_the_same_twin_run(loop):
    """The optimised command played by `run_point` (seed 0, hold 0.5 s) scores alike."""
    from microfab.geometry.load import load_drawing
    from microfab.machines.xy_stage.machine import TwinSettings
    from microfab.machines.xy_stage.reference import run_point
    from microfab.optimize.models import load_models
    from microfab.optimize.problem import ContourProblem
    from microfab.optimize.stage1 import Stage1Settings

    root, _ = loop
    data = json.loads((root / "score.json").read_text())
    problem = ContourProblem(load_drawing(DRAWING)[0], a_max=2.0, tolerance_m=20e-6)
    res = run_point("circle", problem, load_models(root / "models"),
                    twin=TwinSettings(seed=0, hold_s=0.5), stage1=Stage1Settings(n=80))  # fmt: skip
    cmd = read_trace(root / "opt" / "command.csv").values
    # the same optimisation (IPOPT, then PIQP on the networks) twice in one process:
    # measured equal to the last bit (command and all four norms); the tolerances only
    # allow round-off of another summation order, far below what the test tells apart
    np.testing.assert_allclose(res.reference.command.position, cmd, rtol=0, atol=1e-9)
    ours = res.scores["optimised_twin"].as_dict()
    for key in ("l1", "l2", "linf", "tail_linf"):
        assert data["runs"]["run"][key] == pytest.approx(ours[key], rel=1e-6, abs=1e-10), key


def test_models_folder_errors_name_the_file_and_the_command(loop, tmp_path, one_error_line):
    root, _ = loop
    empty = tmp_path / "models"
    empty.mkdir()
    res = runner.invoke(app, ["optimize", DRAWING, "--model", str(empty), *OPT, "--out",
                              str(tmp_path / "o")])  # fmt: skip
    one_error_line(res, "linear_model.json; make it with `microfab identify linear RUNS --out")
    (empty / "linear_model.json").write_text((root / "models" / "linear_model.json").read_text())
    res = runner.invoke(app, ["optimize", DRAWING, "--model", str(empty), *OPT, "--out",
                              str(tmp_path / "o")])  # fmt: skip
    one_error_line(res, "make it with `microfab identify ann RUNS --out")
    assert "ann/model" in res.output and not (tmp_path / "o").exists()


def test_score_refusals_are_one_line_and_write_nothing(loop, tmp_path, one_error_line):
    root, _ = loop
    played, opt = root / "played", root / "opt"
    js = tmp_path / "s.json"

    def refused(says: str, *args: str) -> None:
        res = runner.invoke(app, ["stage", "score", *args, "--json", str(js)])
        one_error_line(res, says)
        assert not js.exists()

    refused("no column 'output_x'", str(opt / "command.csv"), "--drawing", str(opt))
    refused("give the folder `microfab optimize --out` wrote", str(played / "command.csv"),
            "--drawing", str(played))  # fmt: skip
    # a run of another command (an excitation run) is not scored against this drawing
    other = next((root / "measured").glob("*.csv"))
    refused("not those of a command file", str(other), "--drawing", str(opt))
    # a run cut before the tail's last instant
    tr = read_trace(played / "command.csv")
    cut = tmp_path / "cut.csv"
    write_columns(cut, {"time": np.arange(tr.n_samples - 1000) * tr.dt,
                        **{a: tr.values[:-1000, k] for k, a in enumerate(tr.axes)}},
                  unit="m")  # fmt: skip
    refused("the score needs", str(cut), "--drawing", str(opt))
    # a summary of another drawing length
    bad = tmp_path / "opt"
    bad.mkdir()
    summary = json.loads((opt / "summary.json").read_text())
    for f in ("command.csv", "baseline.csv"):
        (bad / f).write_bytes((opt / f).read_bytes())
    (bad / "summary.json").write_text(json.dumps({**summary, "path_length_m": 1.0}))
    refused("not the drawing it was optimised on", str(played / "command.csv"), "--drawing",
            str(bad))  # fmt: skip
