"""Two writers on one folder (issue 44, cause E): one is refused (or waits), nothing is lost.

Real ``microfab`` processes. Each starts, imports the command line, says ``ready`` and
waits; all are then released at once, so that they reach the folder within milliseconds of
each other (a cold start alone takes seconds, and would run them one after the other).
Whatever the order the operating system then gives them, the outcome is checked against
the exit codes: every writer either finished (exit 0) or was refused on one line naming
the process that holds the folder (exit 2), and the folder holds exactly what the writers
that finished wrote.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.atomic import atomic_write_text
from microfab.io.lock import folder_lock
from microfab.io.runstore import open_run
from microfab.io.trace import write_columns

runner = CliRunner()

#: A ``microfab`` process that waits for one line on stdin before it runs its command.
STARTER = """
import sys
from microfab.cli import app
print("ready", flush=True)
sys.stdin.readline()
sys.argv[0] = "microfab"
app()
"""
#: Seconds a started process may take (a cold start on a loaded 2-core machine takes
#: about 7 s; assumed: ample).
TIMEOUT_S = 180


def _start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "COLUMNS": "200"}
    return subprocess.Popen(
        [sys.executable, "-c", STARTER, *args],
        cwd=cwd,
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _together(cwd: Path, *commands: list[str]) -> list[tuple[int, str, str]]:
    """Run the commands at once; (exit code, stdout, stderr) of each."""
    procs = [_start(c, cwd) for c in commands]
    for p in procs:
        assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    for p in procs:
        assert p.stdin is not None
        p.stdin.write("go\n")
        p.stdin.flush()
    out = []
    for p in procs:
        o, e = p.communicate(timeout=TIMEOUT_S)
        out.append((p.returncode, o, e))
    return out


def _busy(result: tuple[int, str, str]) -> bool:
    """Whether a result is the one-line refusal of a folder another process writes."""
    code, _out, err = result
    lines = [ln for ln in err.splitlines() if ln.strip()]
    return (
        code == 2
        and len(lines) == 1
        and lines[0].startswith("error: ")
        and "is being written by another microfab (pid " in lines[0]
    )


def _no_lock_files(root: Path) -> None:
    assert not [p for p in root.rglob(".*.lock")], list(root.rglob(".*.lock"))


# ----------------------------------------------------------------------------- ilc step
def _ilc_trial(path: Path, output_scale: float) -> None:
    """A square scan (400 Hz at 1 MHz) measured through a lag and a gain."""
    from microfab.trajectory.periodic import square_scan

    ref = square_scan(400, (1.0, 1.44), 1e6)
    y = output_scale * np.roll(ref, 40, axis=0)
    cols = {"time": np.arange(ref.shape[0]) * 1e-6}
    for i, a in enumerate(("x", "y")):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": ref[:, i], f"output_{a}": y[:, i]}
    write_columns(path, cols)


def test_four_ilc_steps_at_once_learn_from_exactly_the_trials_that_exited_0(
    tmp_path: Path,
) -> None:
    from microfab.control.ilc import FrequencyILC
    from microfab.machines.files import read_trial_file
    from microfab.machines.learning import RECORD_KEY, trial_digest

    _ilc_trial(tmp_path / "t0.csv", 0.9)
    first = runner.invoke(
        app,
        [
            "ilc",
            "step",
            str(tmp_path / "t0.csv"),
            "--state",
            str(tmp_path / "state"),
            "--out",
            str(tmp_path / "n0.csv"),
        ],
    )
    assert first.exit_code == 0, first.output
    _no_lock_files(tmp_path)  # the in-process command released and removed its lock
    trials = [tmp_path / f"t{k}.csv" for k in range(1, 5)]
    for k, t in enumerate(trials, start=1):
        _ilc_trial(t, 0.9 + 0.01 * k)  # four different measurements of the next input
    results = _together(
        tmp_path,
        *[
            ["ilc", "step", t.name, "--state", "state", "--out", f"n{k}.csv"]
            for k, t in enumerate(trials, start=1)
        ],
    )
    done = [t for t, r in zip(trials, results, strict=True) if r[0] == 0]
    for r in results:
        assert r[0] == 0 or _busy(r), r
    assert done, results
    ilc = FrequencyILC.load(tmp_path / "state")
    digests = list(ilc.meta[RECORD_KEY]["digests"])  # type: ignore[index]
    # learned from the first trial and from exactly those that exited 0, each once
    assert ilc.iteration == 1 + len(done)
    want = {trial_digest(read_trial_file(t)) for t in done}
    assert set(digests[1:]) == want and len(digests) == 1 + len(done)
    for k, (t, r) in enumerate(zip(trials, results, strict=True), start=1):
        assert (tmp_path / f"n{k}.csv").exists() == (r[0] == 0), t  # a refusal wrote nothing
    _no_lock_files(tmp_path)


# ------------------------------------------------------------------------------ rc step
def test_two_rc_steps_at_once_keep_every_update_of_those_that_exited_0(tmp_path: Path) -> None:
    from microfab.control.rc_memory import RCMemory
    from microfab.machines.nanomanipulator.files import STATE_FILE

    n, dt = 100, 1e-4  # one 100 Hz circle at 10 kHz (as tests/cli/test_rc.py)
    t = np.arange(n) * dt
    ref = 0.075 * np.column_stack(
        [np.cos(2 * np.pi * t / (n * dt)), np.sin(2 * np.pi * t / (n * dt))]
    )

    def trial(name: str, scale: float) -> np.ndarray:
        y = scale * np.roll(ref, 3, axis=0)
        write_columns(
            tmp_path / name,
            {"time": t, "ref_x": ref[:, 0], "ref_y": ref[:, 1], "x": y[:, 0], "y": y[:, 1]},
        )
        return ref - y

    trial("p0.csv", 0.95)
    first = runner.invoke(
        app,
        [
            "rc",
            "step",
            str(tmp_path / "p0.csv"),
            "--state",
            str(tmp_path / "state"),
            "--out",
            str(tmp_path / "c0.csv"),
        ],
    )
    assert first.exit_code == 0, first.output
    errors = [trial(f"p{k}.csv", 0.95 + 0.01 * k) for k in (1, 2)]
    results = _together(
        tmp_path,
        *[["rc", "step", f"p{k}.csv", "--state", "state", "--out", f"c{k}.csv"] for k in (1, 2)],
    )
    for r in results:
        assert r[0] == 0 or _busy(r), r
    done = [k for k, r in zip((1, 2), results, strict=True) if r[0] == 0]
    assert done, results
    mem = RCMemory.load(tmp_path / "state" / STATE_FILE)
    assert mem.samples == (1 + len(done)) * n  # no update lost
    if len(done) == 1:  # the state's last period is the one step that ran
        np.testing.assert_array_equal(mem.error, errors[done[0] - 1])
    _no_lock_files(tmp_path)


# ----------------------------------------------------------------------------- slm build
def test_two_slm_builds_into_one_folder_never_mix_their_layers(tmp_path: Path) -> None:
    common = ["slm", "build", "--layers", "2", "--outline-radius-mm", "1.5", "--results-dir", "r"]
    results = _together(tmp_path, [*common, "--hatch-um", "100"], [*common, "--hatch-um", "120"])
    codes = [r[0] for r in results]
    assert sorted(codes) == [0, 2], results
    winner, loser = (results[0], results[1]) if codes[0] == 0 else (results[1], results[0])
    # refused as busy, or (when it came after) as a folder of other settings
    assert _busy(loser) or "holds a sweep of other settings" in loser[2], loser
    hatch = 100e-6 if winner is results[0] else 120e-6
    saved = json.loads((tmp_path / "r" / "settings.json").read_text())
    assert abs(saved["settings"]["hatch_spacing_m"] - hatch) < 1e-12  # assumed: a float write
    assert len(list((tmp_path / "r" / "points").iterdir())) == 2  # the winner's two layers
    _no_lock_files(tmp_path)


# --------------------------------------------------------------------------- stage excite
def test_two_stage_excites_into_one_folder_leave_one_whole_set(tmp_path: Path) -> None:
    from microfab.identify import excitation as ex

    common = ["stage", "excite", "--duration", "1", "--out", "o"]
    results = _together(tmp_path, [*common, "--seed", "1"], [*common, "--seed", "2"])
    codes = [r[0] for r in results]
    assert sorted(codes) == [0, 2], results
    loser = results[codes.index(2)]
    assert _busy(loser) or f"already holds {ex.INDEX_FILE}" in loser[2], loser
    # the folder holds exactly the winner's set: its index and the files it lists
    index = json.loads((tmp_path / "o" / ex.INDEX_FILE).read_text())
    names = {r["file"] for r in index["runs"]}
    assert {p.name for p in (tmp_path / "o").iterdir()} == names | {ex.INDEX_FILE}
    # ... each file the command its index names (read back with its digest checked)
    assert [r.name for r in ex.read_runs(tmp_path / "o")] == [r["name"] for r in index["runs"]]
    _no_lock_files(tmp_path)


# ----------------------------------------------------------------------------------- run
def test_run_is_refused_while_another_writes_its_folder_and_waits_with_wait(
    tmp_path: Path,
) -> None:
    job = tmp_path / "job.toml"
    job.write_text('[job]\nkind = "msl-ilc"\n[scan]\nfeatures_per_s = 400\niterations = 2\n')
    rep = tmp_path / "rep"
    # the first writer (this test) holds the run folder and writes one recorded file
    with open_run(rep, {"first writer": 1}):
        atomic_write_text(rep / "result.txt", "the first writer's result\n")
        refused = _start(["run", str(job), "--out", str(rep)], tmp_path)
        waiting = _start(["run", str(job), "--out", str(rep), "--wait"], tmp_path)
        for p in (refused, waiting):
            assert p.stdout is not None and p.stdout.readline().strip() == "ready"
            assert p.stdin is not None
            p.stdin.write("go\n")
            p.stdin.flush()
        out, err = refused.communicate(timeout=TIMEOUT_S)
        assert _busy((refused.returncode, out, err)), (refused.returncode, out, err)
        assert f"(pid {os.getpid()})" in err and "rerun with --wait" in err
        assert waiting.stdout is not None
        line = waiting.stdout.readline()
        assert line.startswith(f"waiting for the run folder {rep}"), line
        assert waiting.poll() is None  # still waiting while this test holds the folder
    # released: the waiter reads the folder as the first writer left it, whole
    out, err = waiting.communicate(timeout=TIMEOUT_S)
    assert waiting.returncode == 2 and "holds a run of other settings" in err, (out, err)
    assert (rep / "result.txt").read_text() == "the first writer's result\n"
    manifest = json.loads((rep / "run.json").read_text())
    assert manifest["files"] == ["result.txt"] and manifest["settings"]["first writer"] == 1
    _no_lock_files(tmp_path)


def test_a_refused_writer_leaves_the_folder_and_its_parent_as_they_were(tmp_path: Path) -> None:
    """In process, as the fuzz driver runs commands: a busy refusal changes no file."""
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "mine.txt").write_text("x")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    with folder_lock(tmp_path / "o"):
        import threading

        res: list[object] = []
        t = threading.Thread(  # another thread: refused like another process
            target=lambda: res.append(
                runner.invoke(
                    app, ["stage", "excite", "--duration", "1", "--out", str(tmp_path / "o")]
                )
            )
        )
        t.start()
        t.join()
    r = res[0]
    assert r.exit_code == 2, r.output  # type: ignore[attr-defined]
    assert "is being written by another microfab" in r.output  # type: ignore[attr-defined]
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
