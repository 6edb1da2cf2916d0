"""One guard for all the outputs of a command (issue 44, cause B).

Every command names all the paths it writes and reads to `microfab.cli._kit.check_outputs`
before any work: two outputs on one path, an output inside another output folder or an
input folder, an output that is an input, a symbolic-link loop and a special file (FIFO)
are each refused on one ``error:`` line, exit 2, with every file as it was. The last test
checks that ``droplet render`` writes its frame folder whole.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from microfab.cli import app

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fuzz"))

from fuzz_workspace import RECIPES

runner = CliRunner()

Argv = Callable[[Path], list[str]]

#: What the guard's refusals say (any one of them): the refusal came from the guard, not
#: from a later check that happened to catch the case.
GUARD_SAYS = (
    "the same path",
    "is inside the",
    "is also an input",
    "is a folder; give a file",
    "is a file; give a folder",
    "loops",
    "FIFO",
)


def _snapshot(root: Path) -> dict[str, bytes | None]:
    """Every path below ``root``: a file's bytes, ``None`` for a folder or link."""
    snap: dict[str, bytes | None] = {}
    for p in sorted(root.rglob("*")):
        rel = str(p.relative_to(root))
        snap[rel] = p.read_bytes() if p.is_file() and not p.is_symlink() else None
    return snap


def _refused(res: object, root: Path, before: dict[str, bytes | None]) -> str:
    """The one error line of a clean refusal (exit 2, nothing changed)."""
    output = res.output  # type: ignore[attr-defined]
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert res.exit_code == 2, output  # type: ignore[attr-defined]
    assert len(lines) == 1 and lines[0].startswith("error: "), output
    assert _snapshot(root) == before
    return lines[0]


def _is_folder(rel: str) -> bool:
    """A workspace input without a suffix is a folder (``frames``, ``ilc_state``)."""
    return "." not in Path(rel).name


def _light_workspace(root: Path, rels: tuple[str, ...]) -> None:
    """Each input of a recipe as an empty file or folder: the guard refuses before reading."""
    for rel in rels:
        path = root / rel
        if _is_folder(rel):
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"")


def _run_in(root: Path, argv: list[str], monkeypatch: pytest.MonkeyPatch) -> object:
    monkeypatch.chdir(root)
    return runner.invoke(app, argv)


# --------------------------------------------------------------------------- the examples
#: Two outputs of one command on one path, or one inside the other's folder.
COLLIDING: list[tuple[str, Argv]] = [
    ("droplet simulate --out d --json d",
     lambda p: ["droplet", "simulate", "--out", f"{p}/d", "--json", f"{p}/d"]),
    ("laser analyze --out rep --json rep",
     lambda p: ["laser", "analyze", f"{p}/t.h5", "--drawing", "circle:radius=30e-6",
                "--out", f"{p}/rep", "--json", f"{p}/rep"]),
    ("slm build --json lay --results-dir lay",
     lambda p: ["slm", "build", "--layers", "1", "--json", f"{p}/lay", "--results-dir",
                f"{p}/lay"]),
    ("nanomanipulator analyze --out rep --json rep/report.html",
     lambda p: ["nanomanipulator", "analyze", f"{p}/t.h5", "--out", f"{p}/rep", "--json",
                f"{p}/rep/report.html"]),
    ("reproduce --check --json j.json --out j.json",
     lambda p: ["reproduce", "msl-ilc", "--check", "--json", f"{p}/j.json", "--out",
                f"{p}/j.json"]),
]  # fmt: skip


@pytest.mark.parametrize(("case", "argv"), COLLIDING, ids=[c[0] for c in COLLIDING])
def test_two_outputs_on_one_path_are_refused(tmp_path: Path, case: str, argv: Argv) -> None:
    (tmp_path / "t.h5").write_bytes(b"")  # never read: the guard comes first
    before = _snapshot(tmp_path)
    line = _refused(runner.invoke(app, argv(tmp_path)), tmp_path, before)
    assert "the same path" in line or "is inside the" in line, line


#: An output that overwrites an input.
ONTO_INPUT: list[tuple[str, Argv]] = [
    ("droplet analyze --out FRAMES/frame_0000.png",
     lambda p: ["droplet", "analyze", f"{p}/frames", "--out", f"{p}/frames/frame_0000.png"]),
    ("path show --out part.dxf",
     lambda p: ["path", "show", f"{p}/part.dxf", "--out", f"{p}/part.dxf"]),
]  # fmt: skip


@pytest.mark.parametrize(("case", "argv"), ONTO_INPUT, ids=[c[0] for c in ONTO_INPUT])
def test_an_output_onto_an_input_is_refused(tmp_path: Path, case: str, argv: Argv) -> None:
    """Valid inputs (rendered frames, a drawing): without the guard each run succeeds."""
    import ezdxf

    res = runner.invoke(app, ["droplet", "render", str(tmp_path / "frames"), "--duration",
                              "100", "--frame-interval", "25"])  # fmt: skip
    assert res.exit_code == 0, res.output
    doc = ezdxf.new("R2010", units=4)  # mm
    doc.modelspace().add_circle((1, 1), 0.5)
    doc.saveas(tmp_path / "part.dxf")
    before = _snapshot(tmp_path)
    line = _refused(runner.invoke(app, argv(tmp_path)), tmp_path, before)
    assert "input" in line, line


#: A symbolic link to itself, ``loop``, as an input, an output and a state folder.
LOOPED: list[tuple[str, Argv]] = [
    ("path show LOOP (input)", lambda p: ["path", "show", f"{p}/loop", "--out", f"{p}/x.png"]),
    ("identify chirp --json LOOP (output)",
     lambda p: ["identify", "chirp", f"{p}/t.csv", "--json", f"{p}/loop"]),
    ("ilc step --state LOOP",
     lambda p: ["ilc", "step", f"{p}/t.csv", "--state", f"{p}/loop", "--out", f"{p}/n.csv"]),
    ("rc step --state LOOP",
     lambda p: ["rc", "step", f"{p}/t.csv", "--state", f"{p}/loop", "--out", f"{p}/n.csv"]),
]  # fmt: skip


@pytest.mark.parametrize(("case", "argv"), LOOPED, ids=[c[0] for c in LOOPED])
def test_a_symlink_loop_is_refused(tmp_path: Path, case: str, argv: Argv) -> None:
    (tmp_path / "loop").symlink_to("loop")
    (tmp_path / "t.csv").write_text("time,input_x,output_x\n0,0,0\n")
    before = _snapshot(tmp_path)
    line = _refused(runner.invoke(app, argv(tmp_path)), tmp_path, before)
    assert "loop" in line, line


@pytest.mark.parametrize(
    "argv",
    [["path", "show", "fifo", "--out", "x.png"], ["identify", "chirp", "t.csv", "--json", "fifo"]],
    ids=["as input", "as output"],
)
def test_a_fifo_is_refused_not_opened(tmp_path: Path, argv: list[str]) -> None:
    """A FIFO opened for reading blocks until a writer comes: a child process, with a
    time limit (30 s: the refusal takes the ~3 s of importing microfab on a loaded 2-core
    box; a hang is unbounded)."""
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "t.csv").write_text("time,input_x,output_x\n0,0,0\n")
    before = _snapshot(tmp_path)
    code = "import sys; from microfab.cli import main; sys.argv[0] = 'microfab'; main()"
    res = subprocess.run(
        [sys.executable, "-c", code, *argv],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    lines = [ln for ln in (res.stdout + res.stderr).splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stdout + res.stderr
    assert lines[0].startswith("error: ") and "FIFO" in lines[0], lines[0]
    assert _snapshot(tmp_path) == before


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs a /proc file system")
@pytest.mark.parametrize(
    "argv",
    [
        ["reproduce", "reference-opt", "--set", "checkpoints=/proc/x", "--check"],
        ["reproduce", "reference-opt", "--out", "/proc/x", "--check"],
        ["trajectory", "part.dxf", "--out", "/proc/x/ref.csv"],
    ],
    ids=["checkpoint folder", "page folder", "file"],
)
def test_an_output_where_nothing_can_be_written_is_refused(argv: list[str]) -> None:
    """``os.access`` says yes to root in /proc: the file system is asked by a probe."""
    res = runner.invoke(app, argv)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.output
    assert "/proc" in lines[0] and lines[0].startswith("error: "), lines[0]


# --------------------------------------------------------------------------- generated
def _pairs() -> list[tuple[str, str, str]]:
    """``(command, option A, option B)`` for every pair of a recipe's path outputs."""
    found = []
    for name, recipe in RECIPES.items():
        if len(recipe.outputs) < 2:
            continue
        for a, b in itertools.combinations(recipe.outputs, 2):
            found.append((name, a, b))
    return found


PAIRS = _pairs()


def test_the_generator_finds_the_multi_output_commands() -> None:
    assert {"droplet simulate", "laser analyze", "slm build", "ilc step", "trajectory"} <= {
        name for name, _, _ in PAIRS
    }


@pytest.mark.parametrize(("command", "a", "b"), PAIRS, ids=[f"{c}:{a}={b}" for c, a, b in PAIRS])
@pytest.mark.parametrize("direction", ["a->b", "b->a"])
def test_every_pair_of_outputs_on_one_path_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str, a: str, b: str, direction: str
) -> None:
    """Each output of a pair given the other's path: a clean refusal by the guard."""
    recipe = RECIPES[command]
    _light_workspace(tmp_path, recipe.inputs)
    src, dst = (a, b) if direction == "a->b" else (b, a)
    words = len(command.split())  # the command's own words are never paths
    argv = [*recipe.argv[:words], *(src if arg == dst else arg for arg in recipe.argv[words:])]
    before = _snapshot(tmp_path)
    line = _refused(_run_in(tmp_path, argv, monkeypatch), tmp_path, before)
    assert any(s in line for s in GUARD_SAYS), line


# --------------------------------------------------------------------------- one-shot folder
def test_droplet_render_writes_its_folder_whole(tmp_path: Path) -> None:
    """A second render with fewer frames leaves exactly its own frames (no stale ones from
    the first), and a file of another name that was there stays."""
    out = tmp_path / "frames"
    common = ["droplet", "render", str(out), "--duration", "100"]
    first = runner.invoke(app, [*common, "--frame-interval", "20"])
    assert first.exit_code == 0, first.output
    n_first = len(json.loads((out / "frames.json").read_text())["files"])
    (out / "notes.txt").write_text("mine")
    second = runner.invoke(app, [*common, "--frame-interval", "50"])
    assert second.exit_code == 0, second.output
    listed = json.loads((out / "frames.json").read_text())["files"]
    assert len(listed) < n_first
    frames = sorted(p.name for p in out.glob("frame_*"))
    assert frames == sorted(listed)
    assert (out / "notes.txt").read_text() == "mine"
