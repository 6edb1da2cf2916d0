"""``microfab stage play``: excitation runs played on the twin, then identified from files.

The sequence of the README for a user's own stage, on a short record: ``stage excite
--kind shapes --duration 3`` (a few runs, ~4 s at 10 kHz), ``stage play`` on the twin,
then ``identify linear`` and ``identify ann`` (one epoch, one axis) on the measured files.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli.stage import PLAYED_INDEX
from microfab.identify.excitation import INDEX_FILE, read_runs
from microfab.identify.stage_runs import COLUMNS
from microfab.io.trace import read_trace, write_columns

runner = CliRunner()


def _ok(*args: str) -> str:
    res = runner.invoke(app, [*args])
    assert res.exit_code == 0, res.output
    return res.output


@pytest.fixture(scope="module")
def played(tmp_path_factory) -> tuple[Path, Path]:
    """The excitation folder and the measured folder ``stage play`` wrote from it."""
    root = tmp_path_factory.mktemp("stage_play")
    runs, measured = root / "runs", root / "measured"
    _ok("stage", "excite", "--kind", "shapes", "--duration", "3", "--seed", "2", "--out",
        str(runs))  # fmt: skip
    out = _ok("stage", "play", str(runs), "--out", str(measured), "--seed", "5")
    assert "runs played on the twin" in out and f"wrote {len(read_runs(runs))} files" in out
    return runs, measured


def test_play_writes_what_identify_reads(played):
    runs, measured = played
    commands = read_runs(runs)
    assert len(commands) >= 2
    meta = json.loads((measured / PLAYED_INDEX).read_text())
    assert meta["twin"] == {"seed": 5, "noise": True, "hold_s": 0.5}
    assert [e["name"] for e in meta["runs"]] == [r.name for r in commands]
    for run, entry in zip(commands, meta["runs"], strict=True):
        tr = read_trace(measured / entry["file"])
        assert tr.axes == COLUMNS and tr.unit == "m" and 1 / tr.dt == pytest.approx(1e4)
        # the command as given, then its last set-point held 0.5 s
        n = run.n_samples
        assert tr.n_samples == n + 5000 == entry["samples"] and entry["guard_limited"] == 0
        np.testing.assert_array_equal(tr.values[:n, :2], run.command)
        np.testing.assert_array_equal(tr.values[n:, :2], np.repeat(run.command[-1:], 5000, 0))
        # the twin follows: within 2 mm on the way, at rest within 50 µm at the end
        err = tr.values[:, 2:] - tr.values[:, :2]
        assert np.abs(err).max() < 2e-3 and np.abs(err[-1]).max() < 5e-5


def test_excite_play_identify_linear_and_ann(played, tmp_path):
    _, measured = played
    files = sorted(str(p) for p in measured.glob("*.csv"))
    out = _ok("identify", "linear", *files, "--out", str(tmp_path / "lin.json"))
    assert "Linear model of the stage" in out
    sigma = [float(line.split("\t")[3]) for line in out.splitlines()
             if line.startswith("Linear\t")]  # fmt: skip
    assert len(sigma) == 2 and max(sigma) < 150.0  # µm: the twin's linear part follows
    pytest.importorskip("torch")
    _ok("identify", "ann", *files, "--out", str(tmp_path / "ann"), "--epochs", "1", "--axis",
        "x", "--device", "cpu", "--epoch-windows", "2000")  # fmt: skip
    assert (tmp_path / "ann" / "model.json").is_file()
    _ok("identify", "validate", str(tmp_path / "lin.json"), files[0])


def test_identify_on_the_command_files_says_which_columns_and_to_play(
    played, tmp_path, one_error_line
):
    runs, _ = played
    files = sorted(str(p) for p in runs.glob("*.csv"))
    for cmd in ("linear", "ann"):
        res = runner.invoke(app, ["identify", cmd, *files, "--out", str(tmp_path / cmd)])
        one_error_line(res, "a stage run needs time, input_x, input_y, output_x, output_y (m)")
        assert "microfab stage play" in res.output
        assert not (tmp_path / cmd).exists()


def test_play_is_seeded_and_noise_can_be_off(played, tmp_path):
    runs, measured = played
    first = sorted(measured.glob("*.csv"))[0].name
    _ok("stage", "play", str(runs), "--out", str(tmp_path / "a"), "--seed", "5")
    _ok("stage", "play", str(runs / first), "--out", str(tmp_path / "b"), "--no-noise",
        "--hold", "0", "--format", "h5")  # fmt: skip
    assert (tmp_path / "a" / first).read_bytes() == (measured / first).read_bytes()
    quiet = read_trace(tmp_path / "b" / first.replace(".csv", ".h5"))
    noisy = read_trace(measured / first)
    assert quiet.n_samples == noisy.n_samples - 5000
    d = noisy.values[: quiet.n_samples, 2:] - quiet.values[:, 2:]
    assert 1e-6 < d.std() < 4e-6  # the 2 µm noise (seed 002 eq. 3), and only it


def _command_file(path: Path, **changes: object) -> Path:
    n = 6000
    x = 0.01 * (1 - np.cos(np.linspace(0, 2 * np.pi, n))) / 2
    cols = {"time": np.arange(n) * 1e-4, "input_x": x, "input_y": -x}
    cols.update(changes)  # type: ignore[arg-type]
    write_columns(path, {k: v for k, v in cols.items() if v is not None}, unit="m")
    return path


def test_play_takes_a_command_file(tmp_path):
    f = _command_file(tmp_path / "move.csv")
    _ok("stage", "play", str(f), "--out", str(tmp_path / "m"))
    tr = read_trace(tmp_path / "m" / "move.csv")
    assert tr.axes == COLUMNS and tr.n_samples == 6000 + 5000


@pytest.mark.parametrize(
    ("make", "args", "says"),
    [
        (
            "none",
            ["--format", "xls"],
            "Invalid value for '--format': 'xls' is not one of csv, h5, mat",
        ),
        ("none", ["--hold", "-1"], "'--hold': -1 s is outside the allowed range [0, 10] s"),
        ("none", ["--hold", "nan"], "'--hold': nan is not a finite number"),
        ("none", ["--seed", "-1"], "--seed"),
        ("empty_dir", [], "holds no runs.json"),
        ("no_input_y", [], "a command file needs time, input_x, input_y (m)"),
        ("rate", [], "not a whole multiple of 400 Hz"),
        ("fast", [], "Table I"),
        ("twice", [], "two runs are named 'move'"),
    ],
)
def test_play_refusals_write_nothing(tmp_path, one_error_line, make, args, says):
    src = [str(_command_file(tmp_path / "move.csv"))]
    if make == "empty_dir":
        (tmp_path / "empty").mkdir()
        src = [str(tmp_path / "empty")]
    elif make == "no_input_y":
        src = [str(_command_file(tmp_path / "move.csv", input_y=None))]
    elif make == "rate":
        src = [str(_command_file(tmp_path / "move.csv", time=np.arange(6000) * 3e-4))]
    elif make == "fast":  # 0.1 m in one sample
        jump = np.r_[np.zeros(3000), np.full(3000, 0.1)]
        src = [str(_command_file(tmp_path / "move.csv", input_x=jump))]
    elif make == "twice":
        (tmp_path / "b").mkdir()
        src += [str(_command_file(tmp_path / "b" / "move.csv"))]
    out = tmp_path / "measured"
    res = runner.invoke(app, ["stage", "play", *src, "--out", str(out), *args])
    one_error_line(res, says)
    assert not out.exists()


def test_play_refuses_to_overwrite_its_input(played, tmp_path, one_error_line):
    runs, measured = played
    before = {p.name: p.read_bytes() for p in runs.iterdir()}
    res = runner.invoke(app, ["stage", "play", str(runs), "--out", str(runs)])
    one_error_line(res, "is also an input")
    f = _command_file(tmp_path / "move.csv")
    kept = f.read_bytes()
    res = runner.invoke(app, ["stage", "play", str(f), "--out", str(tmp_path)])
    one_error_line(res, "is also an input")
    assert f.read_bytes() == kept
    assert {p.name: p.read_bytes() for p in runs.iterdir()} == before
    res = runner.invoke(app, ["stage", "play", str(runs), "--out", str(measured)])
    one_error_line(res, f"already holds {PLAYED_INDEX}")
    assert (runs / INDEX_FILE).is_file()


def test_ctrl_c_while_playing_writes_nothing(played, tmp_path, monkeypatch):
    runs, _ = played
    import microfab.machines.xy_stage.machine as xy_stage

    def interrupted(commands, settings, progress=None):
        progress(1, len(commands))
        raise KeyboardInterrupt

    monkeypatch.setattr(xy_stage, "play_runs", interrupted)
    out = tmp_path / "measured"
    res = runner.invoke(app, ["stage", "play", str(runs), "--out", str(out)])
    assert res.exit_code == 130, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("interrupted"), res.output
    assert not out.exists()
