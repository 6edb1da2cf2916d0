"""Every command checks its outputs before any work (issue 32, classes 1 and 2).

An output that is one of the inputs would destroy measured data; a folder where a file
goes (or the reverse) crashed after the work. Each case is refused on one ``error:``
line, exit 2, with every file as it was and nothing created.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from microfab.cli import app

runner = CliRunner()

Argv = Callable[[Path], list[str]]


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


#: (case, argv builder, what the error says). ``t`` is a measured file, ``d`` a folder,
#: ``j`` a job file, ``m`` a model file; all exist before the command runs.
CASES: list[tuple[str, Argv, str]] = [
    # class 1: an output that is an input
    (
        "ilc step --out TRIAL",
        lambda p: ["ilc", "step", f"{p}/t.csv", "--state", f"{p}/st", "--out", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "ilc step --out STATE FILE",
        lambda p: [
            "ilc",
            "step",
            f"{p}/t.csv",
            "--state",
            f"{p}/d",
            "--out",
            f"{p}/d/ilc_state.npz",
        ],
        "also an input",
    ),
    (
        "rc step --out TRIAL",
        lambda p: ["rc", "step", f"{p}/t.csv", "--state", f"{p}/st", "--out", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "identify chirp --json TRACE",
        lambda p: ["identify", "chirp", f"{p}/t.csv", "--json", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "identify chirp --plot = --json",
        lambda p: [
            "identify",
            "chirp",
            f"{p}/t.csv",
            "--json",
            f"{p}/m.json",
            "--plot",
            f"{p}/m.json",
        ],
        "the same path",
    ),
    (
        "identify linear --out RUN",
        lambda p: ["identify", "linear", f"{p}/t.csv", "--out", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "identify validate --json MODEL",
        lambda p: ["identify", "validate", f"{p}/m.json", f"{p}/t.csv", "--json", f"{p}/m.json"],
        "also an input",
    ),
    (
        "shaper design --out MODEL",
        lambda p: ["shaper", "design", f"{p}/m.json", "--kind", "inverse", "--out", f"{p}/m.json"],
        "also an input",
    ),
    (
        "slm scan-time --json SOURCE",
        lambda p: ["slm", "scan-time", f"{p}/t.csv", "--json", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "trajectory --out DRAWING",
        lambda p: ["trajectory", f"{p}/t.csv", "--out", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "path show --out DRAWING",
        lambda p: ["path", "show", f"{p}/t.csv", "--out", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "laser analyze --json TRACE",
        lambda p: [
            "laser",
            "analyze",
            f"{p}/t.csv",
            "--drawing",
            "circle:radius=1e-3",
            "--json",
            f"{p}/t.csv",
        ],
        "also an input",
    ),
    (
        "nanomanipulator analyze --json TRACE",
        lambda p: ["nanomanipulator", "analyze", f"{p}/t.csv", "--json", f"{p}/t.csv"],
        "also an input",
    ),
    (
        "calibrate nanomanipulator --write JOB",
        lambda p: [
            "calibrate",
            "nanomanipulator",
            "--job",
            f"{p}/j.toml",
            "--write",
            f"{p}/j.toml",
        ],
        "also an input",
    ),
    (
        "calibrate xy-stage --json = --write",
        lambda p: ["calibrate", "xy-stage", "--write", f"{p}/m.json", "--json", f"{p}/m.json"],
        "the same path",
    ),
    ("run --out JOB", lambda p: ["run", f"{p}/j.toml", "--out", f"{p}/j.toml"], "is a file"),
    # class 2: a folder where a file goes
    (
        "reproduce --json FOLDER",
        lambda p: ["reproduce", "msl-ilc", "--json", f"{p}/d"],
        "is a folder",
    ),
    (
        "droplet simulate --json FOLDER",
        lambda p: ["droplet", "simulate", "--json", f"{p}/d"],
        "is a folder",
    ),
    (
        "droplet analyze --out FOLDER",
        lambda p: ["droplet", "analyze", f"{p}/d", "--out", f"{p}/d"],
        "is a folder",
    ),
    (
        "calibrate nanomanipulator --contour-fit --write",
        lambda p: ["calibrate", "nanomanipulator", "--contour-fit", "--write", f"{p}/n.toml"],
        "--contour-fit is a diagnostic",
    ),
    (
        "calibrate laser --out FILE",
        lambda p: ["calibrate", "laser", "--out", f"{p}/t.csv"],
        "is a file",
    ),
    (
        "calibrate laser --json = --write",
        lambda p: ["calibrate", "laser", "--write", f"{p}/m.toml", "--json", f"{p}/m.toml"],
        "",
    ),
    (
        "calibrate galvo --write FOLDER",
        lambda p: ["calibrate", "galvo", "--write", f"{p}/d"],
        "is a folder",
    ),
    (
        "droplet calibrate --write FOLDER",
        lambda p: ["droplet", "calibrate", "--write", f"{p}/d"],
        "is a folder",
    ),
    (
        "shaper compare --json FOLDER",
        lambda p: ["shaper", "compare", "--json", f"{p}/d"],
        "is a folder",
    ),
    ("slm build --json FOLDER", lambda p: ["slm", "build", "--json", f"{p}/d"], "is a folder"),
    # class 2: a file where a folder goes
    (
        "ilc step --state FILE",
        lambda p: ["ilc", "step", f"{p}/t.csv", "--state", f"{p}/m.json", "--out", f"{p}/next.csv"],
        "is a file",
    ),
    (
        "rc step --state FILE",
        lambda p: ["rc", "step", f"{p}/t.csv", "--state", f"{p}/m.json", "--out", f"{p}/next.csv"],
        "is a file",
    ),
    (
        "droplet simulate --out FILE",
        lambda p: ["droplet", "simulate", "--out", f"{p}/m.json"],
        "is a file",
    ),
    ("droplet render OUT FILE", lambda p: ["droplet", "render", f"{p}/m.json"], "is a file"),
    (
        "droplet sweep --out FILE",
        lambda p: ["droplet", "sweep", "--out", f"{p}/m.json"],
        "is a file",
    ),
    (
        "droplet sensitivity --out FILE",
        lambda p: ["droplet", "sensitivity", "--out", f"{p}/m.json"],
        "is a file",
    ),
    ("stage excite --out FILE", lambda p: ["stage", "excite", "--out", f"{p}/m.json"], "is a file"),
    (
        "optimize --out FILE",
        lambda p: ["optimize", "circle:radius=1e-3", "--model", f"{p}/d", "--out", f"{p}/m.json"],
        "is a file",
    ),
    (
        "laser export --out FILE",
        lambda p: ["laser", "export", f"{p}/j.toml", "--out", f"{p}/m.json"],
        "is a file",
    ),
    (
        "identify ann --out FILE",
        lambda p: ["identify", "ann", f"{p}/t.csv", f"{p}/t.csv", "--out", f"{p}/m.json"],
        "is a file",
    ),
    (
        "slm build --results-dir FILE",
        lambda p: ["slm", "build", "--results-dir", f"{p}/m.json"],
        "is a file",
    ),
    (
        "laser analyze --out FILE",
        lambda p: [
            "laser",
            "analyze",
            f"{p}/t.csv",
            "--drawing",
            "circle:radius=1e-3",
            "--out",
            f"{p}/m.json",
        ],
        "is a file",
    ),
    # a file below a file
    (
        "identify chirp --json below a file",
        lambda p: ["identify", "chirp", f"{p}/t.csv", "--json", f"{p}/m.json/x.json"],
        "is a file, not a folder",
    ),
]


@pytest.mark.parametrize(("case", "argv", "says"), CASES, ids=[c[0] for c in CASES])
def test_a_wrong_output_is_refused_before_any_work(
    tmp_path: Path, case: str, argv: Argv, says: str
) -> None:
    (tmp_path / "t.csv").write_text("time,reference_x,input_x,output_x\n0,0,0,0\n")
    (tmp_path / "m.json").write_text('{"measured": true}')
    (tmp_path / "j.toml").write_text('[job]\nkind = "msl-ilc"\n')
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "ilc_state.npz").write_bytes(b"state")
    before = _files(tmp_path)
    res = runner.invoke(app, argv(tmp_path))
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert says in lines[0], lines[0]
    assert _files(tmp_path) == before  # nothing changed, nothing created
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "j.toml", "m.json", "t.csv"]


@pytest.mark.parametrize("damage", ["empty", "cut", "folder"])
def test_a_damaged_state_is_refused_on_one_line(tmp_path: Path, damage: str) -> None:
    """Class 5: an empty, cut-short or misplaced ILC state names the file and the fix.

    (The plug-in RC state is read by the same `microfab.io.checkpoint.read_state`;
    tests/cli/test_rc.py refuses a damaged one.)
    """
    import numpy as np

    from microfab.io.checkpoint import save_state
    from microfab.io.trace import write_columns

    command, name = "ilc", "ilc_state.npz"
    state = tmp_path / "st"
    path = save_state(state / name, kind="x", version=1, arrays={"a": np.arange(1000.0)})
    if damage == "empty":
        path.write_bytes(b"")
    elif damage == "cut":
        path.write_bytes(path.read_bytes()[:300])
    else:
        path.unlink()
        path.mkdir()
    n = 1000  # 10 ms at 10 µs: harmonics below the 8 kHz cutoff
    ref = np.sin(2 * np.pi * np.arange(n) / n)
    write_columns(tmp_path / "t.csv", {"time": np.arange(n) * 1e-5, "reference_x": ref,
                                       "input_x": ref, "output_x": 0.9 * ref})  # fmt: skip
    before = _files(tmp_path)
    res = runner.invoke(app, [command, "step", str(tmp_path / "t.csv"), "--state", str(state),
                              "--out", str(tmp_path / "next.csv")])  # fmt: skip
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), res.output
    assert name in lines[0] and "state" in lines[0], lines[0]
    assert _files(tmp_path) == before and not (tmp_path / "next.csv").exists()


def test_calibrate_xy_stage_on_too_little_data_is_one_line(tmp_path: Path) -> None:
    """Networks' data too short for a validation run: one error line naming the option
    (the progress of making the runs cleared), nothing written."""
    out = tmp_path / "twin.toml"
    res = runner.invoke(app, ["calibrate", "xy-stage", "--ann-duration", "6", "--write", str(out)])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert "--ann-duration" in lines[0] and not out.exists()
