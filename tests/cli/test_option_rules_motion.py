"""Issue 44, causes C and D for the motion commands (``trajectory``, ``path show``,
``optimize``, ``ilc step``, ``rc step``): every number in its declared range, options
tied to the mode or to the input refused before any work, one-shot folders written whole.

Each refusal is one ``error:`` line, exit code 2, and leaves every file as it was.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli.geometry import MIN_SAMPLES
from microfab.io.trace import read_columns, write_columns

runner = CliRunner()
SENTINEL = b"an earlier run's file"


def _files(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` (relative name -> bytes)."""
    if not d.exists():
        return {}
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _refused(
    one_error_line: Callable[[Any, str], None], where: Path, argv: list[str], says: str
) -> None:
    """``microfab argv`` is one ``error:`` line holding ``says``; ``where`` unchanged."""
    before = _files(where)
    one_error_line(runner.invoke(app, argv), says)
    assert _files(where) == before


# ------------------------------------------------------------------------- trajectory
@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--speed", "0.01", "--rate", "1"], "'--rate': 1 Hz is outside the allowed range [100,"),
        (["--speed", "0.01", "--rate", "1e9"], "'--rate': 1e+09 Hz is outside"),
        (["--speed", "2000"], "'--speed': 2000 m/s is outside the allowed range [1e-06, 1000]"),
        (["--speed", "0"], "'--speed': 0 m/s is outside"),
        (["--time-optimal", "--feed", "1e4"], "'--feed': 10000 m/s is outside"),
        (["--time-optimal", "--vmax", "0"], "'--vmax': 0 m/s is outside"),
        (["--time-optimal", "--amax", "1e9"], "'--amax': 1e+09 m/s² is outside"),
        (["--time-optimal", "--jmax", "1e14"], "'--jmax': 1e+14 m/s³ is outside"),
        (["--time-optimal", "--workspace", "100"], "'--workspace': 100 m is outside"),
        (["--time-optimal", "--n-grid", "5"], "'--n-grid': 5 is outside the allowed range [10,"),
        (["--time-optimal", "--contour", "-1"], "'--contour': -1 is outside"),
        (["--time-optimal", "--rate", "nan"], "nan is not a finite number"),
    ],
)
def test_trajectory_numbers_outside_their_range(
    tmp_path: Path, one_error_line: Any, extra: list[str], says: str
) -> None:
    (tmp_path / "ref.csv").write_bytes(SENTINEL)
    argv = ["trajectory", "circle:radius=0.001", *extra, "--out", str(tmp_path / "ref.csv")]
    _refused(one_error_line, tmp_path, argv, says)


def test_a_reference_too_coarse_to_follow_the_path(tmp_path: Path, one_error_line: Any) -> None:
    """Issue 44: ``--rate 1`` wrote a 2-sample reference; the rule is ``MIN_SAMPLES``."""
    out = tmp_path / "ref.csv"
    argv = ["trajectory", "circle:radius=0.001", "--speed", "0.01", "--out", str(out)]
    res = runner.invoke(app, [*argv, "--rate", "100"])
    one_error_line(res, f"a reference needs at least {MIN_SAMPLES} to follow the path")
    m = re.search(
        r"--rate 100 Hz gives (\d+) samples over the \S+ s motion.*--rate (\d+) Hz", res.output
    )
    assert m is not None and int(m[1]) < MIN_SAMPLES, res.output
    assert not out.exists() and not (tmp_path / "ref_profile.png").exists()
    # the rate it names is enough
    res = runner.invoke(app, [*argv, "--rate", m[2]])
    assert res.exit_code == 0, res.output
    assert read_columns(out)["time"].size >= MIN_SAMPLES
    # the time-optimal plan too: a 1 mm circle lasts 36 ms on the seed 002 stage
    argv = ["trajectory", "circle:radius=0.001", "--time-optimal", "--rate", "2000"]
    _refused(one_error_line, tmp_path, [*argv, "--out", str(out)], "samples over the")


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (
            ["circle:radius=0.01", "--speed", "0.1", "--feed", "0.1"],
            "--feed has no effect with --speed",
        ),
        (
            ["circle:radius=0.01", "--speed", "0.1", "--n-grid", "50"],
            "--n-grid has no effect with --speed",
        ),
        (
            ["circle:radius=0.01", "--speed", "0.1", "--chord", "0.05"],
            "--chord has no effect on this drawing",
        ),
        (
            ["airfoil:e344", "--speed", "0.1", "--text-height", "0.05"],
            "--text-height has no effect on this drawing",
        ),
        (["text:A", "--speed", "0.1", "--units", "mm"], "--units has no effect on this drawing"),
    ],
)
def test_trajectory_options_without_effect_are_refused(
    tmp_path: Path, one_error_line: Any, argv: list[str], says: str
) -> None:
    (tmp_path / "ref.csv").write_bytes(SENTINEL)
    _refused(
        one_error_line, tmp_path, ["trajectory", *argv, "--out", str(tmp_path / "ref.csv")], says
    )


def test_path_show_sizing_for_another_drawing_is_refused(
    tmp_path: Path, one_error_line: Any
) -> None:
    png = tmp_path / "p.png"
    for argv, says in (
        (["circle:radius=0.01", "--chord", "0.1"], "--chord has no effect"),
        (["airfoil:e344", "--chord", "20"], "'--chord': 20 m is outside"),
        (["text:A", "--text-height", "0"], "'--text-height': 0 m is outside"),
    ):
        _refused(one_error_line, tmp_path, ["path", "show", *argv, "--out", str(png)], says)
    res = runner.invoke(
        app, ["path", "show", "text:A", "--text-height", "0.002", "--out", str(png)]
    )
    assert res.exit_code == 0 and png.is_file(), res.output


# -------------------------------------------------------------------------- optimize
@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--amax", "41"], "'--amax': 41 m/s² is outside the allowed range [0.001, 40] m/s²"),
        (["--tolerance", "0.01"], "'--tolerance': 0.01 m is outside"),
        (["--n", "9"], "'--n': 9 is outside the allowed range [10, 5000]"),
        (["--contour", "-2"], "'--contour': -2 is outside"),
        (["--chord", "0.1"], "--chord has no effect on this drawing"),
        (["--units", "mm"], "--units has no effect on this drawing"),
    ],
)
def test_optimize_numbers_and_sizing_refused_before_any_work(
    tmp_path: Path, one_error_line: Any, extra: list[str], says: str
) -> None:
    out = tmp_path / "opt"
    out.mkdir()
    (out / "predicted.csv").write_bytes(SENTINEL)  # an earlier run's, left as it was
    argv = ["optimize", "circle:radius=0.002", "--out", str(out), "--stage", "1", *extra]
    _refused(one_error_line, tmp_path, argv, says)


def test_optimize_writes_its_folder_whole(tmp_path: Path) -> None:
    """Issue 44: ``--stage 1`` into a ``--stage both`` folder left its predicted.csv and
    stage-2 checkpoint beside the new files; files the command does not own stay."""
    pytest.importorskip("casadi")
    out = tmp_path / "opt"
    out.mkdir()
    earlier = (
        "predicted.csv",
        "stage2_checkpoint.npz",
        "command.csv",
        "baseline.csv",
        "summary.json",
    )
    for name in earlier:
        (out / name).write_bytes(SENTINEL)
    (out / "notes.txt").write_bytes(b"the user's")
    argv = [
        "optimize",
        "circle:radius=0.002",
        "--out",
        str(out),
        "--stage",
        "1",
        "--n",
        "20",
        "--format",
        "h5",
    ]
    res = runner.invoke(app, argv)
    assert res.exit_code == 0, res.output
    names = {p.name for p in out.iterdir()}
    assert names == {
        "command.h5",
        "baseline.h5",
        "input_400hz.csv",
        "stage1.npz",
        "summary.json",
        "contour.png",
        "deviation.png",
        "notes.txt",
    }
    assert (out / "notes.txt").read_bytes() == b"the user's"
    assert (out / "summary.json").read_bytes() != SENTINEL


# -------------------------------------------------------------------------- ilc step
def _ilc_trial(path: Path, command: Path | None = None) -> None:
    """One 2.5 ms period at 1 MHz (seed 000 §4: a 400 Hz square) measured on the twin.

    The input is the reference, or the input file ``command`` of an earlier step.
    """
    from microfab.machines.galvo.machine import galvo_twin
    from microfab.trajectory.periodic import square_scan

    ref = square_scan(400, (1.0, 1.44), 1e6)
    u = ref
    if command is not None:
        cols = read_columns(command)
        u = np.column_stack([cols["input_x"], cols["input_y"]])
    y = galvo_twin(seed=3).run(u).output
    cols = {"time": np.arange(ref.shape[0]) * 1e-6}
    for i, a in enumerate(("x", "y")):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": u[:, i], f"output_{a}": y[:, i]}
    write_columns(path, cols)


@pytest.fixture(scope="module")
def ilc_started(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder after one ``ilc step``: ``state/`` and the next trial, ``trial.csv``."""
    d = tmp_path_factory.mktemp("ilc")
    _ilc_trial(d / "first.csv")
    res = runner.invoke(
        app,
        ["ilc", "step", str(d / "first.csv"), "--state", str(d / "state"), "--out",
         str(d / "input.csv")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    _ilc_trial(d / "trial.csv", command=d / "input.csv")  # measured on the input it wrote
    return d


def _ilc(d: Path, *extra: str) -> list[str]:
    return [
        "ilc",
        "step",
        str(d / "trial.csv"),
        "--state",
        str(d / "state"),
        "--out",
        str(d / "next.csv"),
        *extra,
    ]


@pytest.mark.parametrize(
    "extra",
    [
        ["--cutoff-hz", "2000"],
        ["--gain", "0.3"],
        ["--law", "p-type"],
        ["--law", "inverse"],
        ["--axis-gain", "y=0.2"],
        ["--advance-us", "10"],
        ["--frf", "frf.csv"],
    ],
)
def test_ilc_first_call_options_on_a_later_step(
    ilc_started: Path, tmp_path: Path, one_error_line: Any, extra: list[str]
) -> None:
    d = tmp_path / "w"
    shutil.copytree(ilc_started, d)
    extra = [str(d / e) if e == "frf.csv" else e for e in extra]
    (d / "frf.csv").write_text("freq_hz,re_x,im_x\n")
    _refused(one_error_line, d, _ilc(d, *extra), f"{extra[0]} has no effect on a later step")


def test_ilc_later_step_takes_its_limits(ilc_started: Path, tmp_path: Path) -> None:
    """The later step the refusals above are made on runs; the limits may be given again."""
    d = tmp_path / "w"
    shutil.copytree(ilc_started, d)
    res = runner.invoke(app, _ilc(d, "--max-position", "9"))
    assert res.exit_code == 0, res.output
    assert "iteration 2" in res.output and (d / "next.csv").is_file()


def test_ilc_advance_with_the_inverse_law_or_beyond_the_period(
    tmp_path: Path, one_error_line: Any
) -> None:
    _ilc_trial(tmp_path / "trial.csv")
    says = "--advance-us has no effect with --law inverse"
    _refused(one_error_line, tmp_path, _ilc(tmp_path, "--advance-us", "10"), says)
    _refused(
        one_error_line, tmp_path, _ilc(tmp_path, "--law", "inverse", "--advance-us", "10"), says
    )
    # issue 44: 1e9 µs on a period of milliseconds
    _refused(
        one_error_line,
        tmp_path,
        _ilc(tmp_path, "--law", "p-type", "--advance-us", "1e9"),
        "'--advance-us': 1e+09 µs is outside the allowed range [0, 1e+06] µs",
    )
    _refused(
        one_error_line,
        tmp_path,
        _ilc(tmp_path, "--law", "p-type", "--advance-us", "2500"),
        "--advance-us 2500 µs is not shorter than the trial's period of 2500 µs",
    )
    assert not (tmp_path / "state").exists()
    argv = _ilc(tmp_path, "--law", "p-type", "--advance-us", "20", "--cutoff-hz", "2000")
    res = runner.invoke(app, argv)
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (
            ["--cutoff-hz", "6e5"],
            "'--cutoff-hz': 600000 Hz is outside the allowed range [1, 500000]",
        ),
        (["--gain", "0"], "'--gain': 0 is outside"),
        (["--max-position", "1e7"], "'--max-position': 1e+07 (input unit) is outside"),
        (["--max-acceleration", "-1"], "'--max-acceleration': -1 (input unit)/s² is outside"),
        (["--axis-gain", "x=2.5"], "--axis-gain x=2.5: the gain is outside"),
    ],
)
def test_ilc_numbers_outside_their_range(
    tmp_path: Path, one_error_line: Any, extra: list[str], says: str
) -> None:
    (tmp_path / "trial.csv").write_bytes(SENTINEL)  # refused before it is read
    _refused(one_error_line, tmp_path, _ilc(tmp_path, *extra), says)


def test_ilc_limit_bounds_follow_the_galvo_limits() -> None:
    """The bounds of the declared limits are 1e5 times the galvo twin's (see `cli.ilc`)."""
    from microfab.cli import ilc
    from microfab.machines.galvo.machine import limits

    lim = limits()["x"]
    assert (ilc.MAX_POSITION, ilc.MAX_VELOCITY, ilc.MAX_ACCELERATION) == pytest.approx(
        (1e5 * lim.position, 1e5 * lim.velocity, 1e5 * lim.acceleration), rel=1e-12
    )


# --------------------------------------------------------------------------- rc step
RC_N, RC_DT = 100, 1e-4  # a 100-sample period at 10 kHz (the seed 001 twin's rate)


def _rc_trial(path: Path) -> None:
    t = np.arange(RC_N) * RC_DT
    w = 2 * np.pi / (RC_N * RC_DT)
    pos = 0.075 * np.column_stack([np.cos(w * t), np.sin(w * t)])
    y = 0.9 * pos
    write_columns(
        path, {"time": t, "ref_x": pos[:, 0], "ref_y": pos[:, 1], "x": y[:, 0], "y": y[:, 1]}
    )


def _rc(d: Path, *extra: str, out: str = "next.csv") -> list[str]:
    return [
        "rc",
        "step",
        str(d / "trial.csv"),
        "--state",
        str(d / "state"),
        "--out",
        str(d / out),
        *extra,
    ]


@pytest.mark.parametrize("extra", [["--tau-ms", "0.5"], ["--gain", "1"], ["--lead-samples", "4"]])
def test_rc_first_call_options_on_a_later_step(
    tmp_path: Path, one_error_line: Any, extra: list[str]
) -> None:
    _rc_trial(tmp_path / "trial.csv")
    res = runner.invoke(
        app, _rc(tmp_path, "--tau-ms", "0.5", "--lead-samples", "4", out="first.csv")
    )
    assert res.exit_code == 0, res.output
    # even the value the state holds: the option has no effect on a later step
    _refused(
        one_error_line, tmp_path, _rc(tmp_path, *extra), f"{extra[0]} has no effect on a later step"
    )


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--tau-ms", "2e4"], "'--tau-ms': 20000 ms is outside the allowed range (0, 10000] ms"),
        (["--gain", "0"], "'--gain': 0 is outside the allowed range (0, 2]"),
        (["--lead-samples", "-1"], "'--lead-samples': -1 samples is outside"),
        (["--period-s", "0"], "'--period-s': 0 s is outside the allowed range (0, 60] s"),
        (["--period-s", "61"], "'--period-s': 61 s is outside"),
        (
            ["--lead-samples", "100"],
            "--lead-samples 100 is not below the trial's period of 100 samples",
        ),
    ],
)
def test_rc_numbers_outside_their_range_or_the_period(
    tmp_path: Path, one_error_line: Any, extra: list[str], says: str
) -> None:
    _rc_trial(tmp_path / "trial.csv")
    _refused(one_error_line, tmp_path, _rc(tmp_path, *extra), says)
    assert not (tmp_path / "state").exists()


def test_shared_keys_are_the_job_files() -> None:
    """The options set what the job keys set: one declaration for both."""
    import typer.main

    from microfab.cli._options import declared
    from microfab.experiments.seed000_msl.job import SCHEMA as MSL
    from microfab.experiments.seed001_nanomanipulator.job import SCHEMA as NANO

    root = typer.main.get_command(app)

    def keys(group: str) -> dict[str, Any]:
        return {p.name: declared(p) for p in root.commands[group].commands["step"].params}

    ilc_keys, rc_keys = keys("ilc"), keys("rc")
    msl = {k.name: k for k in MSL["ilc"]}
    assert ilc_keys["cutoff_hz"] is msl["cutoff_hz"] and ilc_keys["gain"] is msl["gain"]
    rc = {k.name: k for k in NANO["rc"]}
    assert rc_keys["tau_ms"] is rc["tau_ms"] and rc_keys["gain"] is rc["gain"]
    assert rc_keys["lead_samples"] is rc["lead_samples"]
    assert rc_keys["period_s"] is {k.name: k for k in NANO["pattern"]}["period_s"]
