"""Every ``microfab`` command of README.md's fenced code blocks is run here (issue 43).

Each command line of the README (a line starting ``microfab`` or ``.venv/bin/microfab``,
after a ``$ `` or not, with its ``\\`` continuation lines) is either a `Case`, run in one
temporary working folder through typer's `CliRunner` in this process, checking exit 0
and the outputs the README names, or stands in `EXCLUDED` with the reason. A line in
neither fails `test_every_readme_command_is_run_or_excluded`, naming it; an entry for a
line the README no longer has fails `test_no_stale_entries`.

To stay within seconds a case may run a *reduced* form, said in its ``reduced`` field:
``run JOB`` reads a copy of the job file at the same relative path with smaller settings
(`_job_copy`; the ``out`` is the example's, so the default folders are the ones used),
``reproduce`` gets ``--set`` options, other commands smaller options appended or a
smaller value in place of the README's. Inputs a command reads (a trial file, a DXF
drawing, a chirp record, an FRF file) are made by `Case.setup`; an input another README
command writes is made by running that command first (`Case.after`).

All commands run in one folder in README order, the way a user would run them one after
another; the last test removes the default job's folder and runs ``microfab run`` again
after every other command has left its default output there (issue 43: `make run`
works whatever was run before).
"""

from __future__ import annotations

import json
import re
import shlex
import time
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
runner = CliRunner()

_COMMAND = re.compile(r"^\s*(?:\$\s+)?(?:\.venv/bin/)?microfab(?:\s|$)")


def readme_commands(text: str) -> list[str]:
    """The ``microfab`` command lines of the README's fenced code blocks, in order.

    Parameters
    ----------
    text : str
        The README's text.

    Returns
    -------
    list of str
        Each command as its arguments after ``microfab`` (shell-split, the comment
        dropped, continuation lines joined), joined by single spaces: the key of `CASES`
        and `EXCLUDED`.
    """
    found: list[str] = []
    fenced = False
    pending: str | None = None
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fenced, pending = not fenced, None
            continue
        if not fenced:
            continue
        if pending is not None:
            line, pending = pending + " " + line.strip(), None
        elif not _COMMAND.match(line):
            continue
        if line.rstrip().endswith("\\"):
            pending = line.rstrip()[:-1]
            continue
        words = shlex.split(_COMMAND.sub("", line, count=1), comments=True)
        found.append(" ".join(words))
    return found


# --- inputs the README's commands read ---------------------------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def _job_copy(src: Path, dest: Path, changes: Mapping[str, Mapping[str, Any]]) -> None:
    """Write ``src`` (a job file) to ``dest`` with ``changes`` (section -> key -> value)."""
    data = tomllib.loads(src.read_text(encoding="utf-8"))
    for section, keys in changes.items():
        data.setdefault(section, {}).update(keys)
    text = "".join(
        f"[{s}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in keys.items()) + "\n"
        for s, keys in data.items()
    )
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_text(text, encoding="utf-8")


def _example(name: str, changes: Mapping[str, Mapping[str, Any]]) -> Callable[[Path], None]:
    """Setup: a reduced copy of ``examples/NAME`` at ``examples/NAME`` in the work folder."""
    return lambda work: _job_copy(ROOT / "examples" / name, work / "examples" / name, changes)


#: The default job reduced (2 iterations, one rate): its out is the shipped default's.
DEFAULT_JOB_CHANGES = {"scan": {"iterations": 2, "learning_rates": [400]}}


def _trial(work: Path) -> None:
    """One period of the galvo twin at 400 features/s, u_1 = y_d (README: ilc step)."""
    from microfab.io.trace import write_columns
    from microfab.machines.galvo.machine import galvo_twin
    from microfab.trajectory.periodic import square_scan

    ref = square_scan(400, (1.0, 1.44), 1e6)
    y = galvo_twin(seed=3).run(ref).output
    cols: dict[str, Any] = {"time": np.arange(ref.shape[0]) * 1e-6}
    for i, a in enumerate(("x", "y")):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": ref[:, i], f"output_{a}": y[:, i]}
    write_columns(work / "trial.csv", cols)


def _part_dxf(work: Path) -> None:
    """A 10 x 5 mm rectangle with a 2 mm hole in a DXF in mm (README: part.dxf)."""
    import ezdxf

    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4  # mm
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 5), (0, 5)], close=True)
    msp.add_circle((5, 2.5), 1.0)
    doc.saveas(work / "part.dxf")


#: The chirp of `_chirp_run`: the README's 10 Hz - 2 kHz band, sweeps of 0.1 s (not 1 s).
CHIRP_PERIOD_S = 0.1


def _chirp_run(work: Path) -> None:
    """The SLM twin's response to a 10 Hz - 2 kHz chirp, 3 sweeps (README: run.csv)."""
    import scipy.signal

    from microfab.identify.chirp import ChirpDesign
    from microfab.io.trace import write_columns
    from microfab.plants.galvo_slm import galvo_slm_twin

    design = ChirpDesign(
        f0_hz=10.0, f1_hz=2000.0, period_s=CHIRP_PERIOD_S, n_periods=3, n_dropped=1
    )
    u = design.signal().input
    ax = galvo_slm_twin().axis_model
    y = np.ravel(scipy.signal.dlsim((ax.A, ax.B, ax.C, ax.D, ax.dt), u)[1])
    write_columns(
        work / "run.csv",
        {"time": np.arange(u.size) * design.dt, "input_x": u, "output_x": y},
        unit="bit",
    )


def _mirror_frf(work: Path) -> None:
    """The mirror-mode SLM twin's FRF, 100 Hz - 8 kHz (README: measured_frf.csv)."""
    from microfab.io.frf import write_frf
    from microfab.plants.galvo_slm import galvo_slm_twin

    f = np.linspace(100.0, 8000.0, 400)
    tf = galvo_slm_twin(mirror_mode=True).transfer_function()
    h = np.array([complex(tf(2j * np.pi * x)) for x in f])
    write_frf(work / "measured_frf.csv", f, h[:, None], ("x",))


# --- the cases --------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """How one README command runs here.

    Attributes
    ----------
    argv : str
        The arguments after ``microfab`` as run (shell syntax); ``None``: the README's.
    reduced : str
        What differs from the README's command and why (empty: nothing).
    outputs : tuple of str
        Files the README names (relative to the work folder) that must exist afterwards.
    says : tuple of str
        Text the output must hold.
    setup : callable or None
        Makes the inputs in the work folder before the command runs.
    after : tuple of str
        README commands (keys) whose outputs this one reads; they run first.
    """

    argv: str | None = None
    reduced: str = ""
    outputs: tuple[str, ...] = ()
    says: tuple[str, ...] = ()
    setup: Callable[[Path], None] | None = None
    after: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)


_STAGE_ID = {
    "linear": {"total_s": 20.0, "orders": [4]},
    "ann": {"enabled": False},
    "cases": {"table_a_max": [1.0], "sweep_a_max": [1.0]},
    "studies": {"coupling": False, "classic": False},
}

CASES: dict[str, Case] = {
    # Usage
    "run": Case(
        reduced="the default job with 2 iterations at one rate (its shipped out)",
        outputs=("report/msl-ilc/report.html",),
    ),
    "run examples/galvo_msl_default.toml --out my_report": Case(
        reduced="a copy of the job file with 2 iterations at one rate",
        setup=_example("galvo_msl_default.toml", DEFAULT_JOB_CHANGES),
        outputs=("my_report/report.html", "my_report/run.json"),
    ),
    "kinds": Case(says=("msl-ilc", "laser-micromachining", "droplet-fig4")),
    "kinds laser-micromachining": Case(says=("[trajectory]", "speed_mm_s")),
    "run my_job.toml --fresh": Case(
        reduced="my_job.toml is a one-point inkjet job, run with another duration first",
        setup=lambda work: _my_job_ran(work),
        outputs=("my_job/report.html",),
        says=("moved the earlier run's files to",),
    ),
    "reproduce msl-ilc --json tables.json": Case(
        argv="reproduce msl-ilc --json tables.json --set iterations=2",
        reduced="--set iterations=2",
        outputs=("tables.json",),
    ),
    "reproduce msl-ilc --set iterations=10": Case(
        argv="reproduce msl-ilc --set iterations=3", reduced="iterations=3, not 10"
    ),
    "run examples/droplet_sweep.toml": Case(
        reduced="one point (1 %, 50 V) of 60 µs in this process",
        setup=_example(
            "droplet_sweep.toml",
            {
                "sweep": {"concentrations_pct": [1.0], "voltages_v": [], "duration_us": 60.0},
                "run": {"workers": 1},
            },
        ),
        outputs=("report/droplet-sweep/report.html",),
    ),
    "ilc step trial.csv --state ilc_state --out next.csv": Case(
        reduced="trial.csv is a period of the twin (the README's real hardware)",
        setup=_trial,
        outputs=("next.csv", "ilc_state"),
    ),
    "run examples/nanomanipulator_msl.toml": Case(
        reduced="one circle for 3 periods (the gate opens in period 3), not four for 6",
        setup=_example("nanomanipulator_msl.toml", {"pattern": {"n_circles": 1, "periods": 3}}),
        outputs=("report/nanomanipulator/report.html",),
    ),
    "calibrate laser --out cal_laser": Case(
        argv="calibrate laser --out cal_laser --budget 17 --conflict-budget 0",
        reduced="one population of the search (17 runs) and no conflict sweep, not 400 runs",
        outputs=("cal_laser/calibration.json", "cal_laser/memo.json"),
        says=("fig3_peak_um", "fig3_share_y", "rms_force_n"),
    ),
    "run examples/laser_micromachining.toml": Case(
        reduced="one lap, no comparison run, no speed sweep, no autofocus study",
        setup=_example(
            "laser_micromachining.toml",
            {
                "trajectory": {"laps": 1},
                "control": {"compare": False},
                "sweep": {"speeds_mm_s": []},
                "focus": {"run": False},
            },
        ),
        outputs=("report/laser/report.html",),
    ),
    "run examples/slm_shaping.toml": Case(
        reduced="a 0.2 s chirp, no shaper comparison, 2 layers in this process",
        setup=_example(
            "slm_shaping.toml",
            {
                "identify": {"period_s": 0.2},
                "shaper": {"compare": False},
                "build": {"layers": 2, "workers": 1},
            },
        ),
        outputs=("report/slm/report.html",),
    ),
    "run examples/blackbox_stage_identify.toml": Case(
        reduced="20 s of linear data, no networks (the README's optimize on these "
        "models is stage 1 only), the letters at 1 m/s² only, no studies",
        setup=_example("blackbox_stage_identify.toml", _STAGE_ID),
        outputs=(
            "report/stage_identify/report.html",
            "report/stage_identify/linear_model.json",
        ),
    ),
    # Drawings and trajectories
    "path show part.dxf --units mm": Case(setup=_part_dxf, outputs=("part.png",)),
    "path show text:urch --json": Case(says=("contours",)),
    "path show airfoil:e344 --chord 0.1": Case(),
    "path show square:side=0.01,corner_radius=0.002": Case(),
    "trajectory part.dxf --time-optimal --vmax 0.1 --amax 5 --jmax 500 --rate 10000 "
    "--out ref.csv": Case(
        argv="trajectory part.dxf --time-optimal --vmax 0.1 --amax 5 --jmax 500 --rate 10000 "
        "--out ref.csv --n-grid 200",
        reduced="--n-grid 200",
        setup=_part_dxf,
        outputs=("ref.csv", "ref_profile.png"),
    ),
    # Drop-on-demand inkjet
    "droplet simulate --concentration 1.0 --voltage 50 --json drop.json": Case(
        argv="droplet simulate --concentration 1.0 --voltage 50 --json drop.json --duration 60",
        reduced="--duration 60 (µs, not 400)",
        outputs=("drop.json", "report/droplet/simulate/droplet.json"),
    ),
    "droplet sweep --workers 2": Case(
        argv="droplet sweep --workers 1 --concentrations 1 --voltages '' --duration 40",
        reduced="one point of 40 µs in this process (--workers 1)",
        outputs=("report/droplet/sweep/sweep.json",),
    ),
    "droplet render FRAMES_DIR --concentration 1.0": Case(
        argv="droplet render FRAMES_DIR --concentration 1.0 --duration 120 --frame-interval 20",
        reduced="120 µs, a frame every 20 µs",
        outputs=("FRAMES_DIR/frames.json",),
    ),
    "droplet analyze FRAMES_DIR --pixel-size 2 --frame-interval 10 --json measured.json": Case(
        argv="droplet analyze FRAMES_DIR --pixel-size 2 --frame-interval 20 --json measured.json",
        reduced="--frame-interval 20, the frames' interval",
        outputs=("measured.json",),
        after=("droplet render FRAMES_DIR --concentration 1.0",),
    ),
    # SLM galvo scanner input shaping
    "identify chirp run.csv --band 10:2000 --poles 3 --zeros 0 --json model.json": Case(
        argv="identify chirp run.csv --band 10:2000 --poles 3 --zeros 0 --json model.json "
        f"--period {CHIRP_PERIOD_S}",
        reduced=f"sweeps of {CHIRP_PERIOD_S} s (--period), not 1 s",
        setup=_chirp_run,
        outputs=("model.json",),
    ),
    "shaper design model.json --kind inverse --poles-hz 4000 --order 4 --dt 1e-5 "
    "--out shaper.json": Case(
        outputs=("shaper.json",),
        after=("identify chirp run.csv --band 10:2000 --poles 3 --zeros 0 --json model.json",),
    ),
    "shaper design --kind zv --frf measured_frf.csv --out zv.json": Case(
        setup=_mirror_frf, outputs=("zv.json",)
    ),
    "slm scan-time lattice:z=8.2e-4,radius=8e-3 --shaper shaper.json": Case(
        after=(
            "shaper design model.json --kind inverse --poles-hz 4000 --order 4 --dt 1e-5 "
            "--out shaper.json",
        ),
    ),
    "slm scan-time part.dxf --hatch-um 100 --json times.json": Case(
        setup=_part_dxf, outputs=("times.json",)
    ),
    "slm build --layers 500 --results-dir build/ --workers 2": Case(
        argv="slm build --layers 2 --results-dir build/ --workers 1",
        reduced="2 layers in this process",
        outputs=("build",),
    ),
    "shaper compare --twin mirror": Case(
        argv="shaper compare --twin mirror --shapers zv", reduced="--shapers zv"
    ),
    # Black-box XY stage, part 1: the own-stage workflow
    "stage excite --kind random --duration 600 --out runs/": Case(
        argv="stage excite --kind random --duration 4 --out runs/",
        reduced="4 s of runs, not 600 s",
        outputs=("runs/runs.json",),
    ),
    "stage play runs/ --out measured/": Case(
        outputs=("measured",), after=("stage excite --kind random --duration 600 --out runs/",)
    ),
    "identify linear measured/*.csv --order 4 --out models/linear_model.json": Case(
        outputs=("models/linear_model.json",), after=("stage play runs/ --out measured/",)
    ),
    "identify ann measured/*.csv --axis both --out models/ann/model": Case(
        argv="identify ann measured/*.csv more_runs/*.csv --axis both --out models/ann/model "
        "--epochs 1 --epoch-windows 2000 --device cpu",
        reduced="one epoch of 2000 windows on the CPU; the networks need two runs and 4 s "
        "of random commands are one, so more_runs/ (the same run, other noise) is added",
        setup=lambda work: _more_runs(work),
        outputs=("models/ann/model",),
        after=("stage play runs/ --out measured/",),
    ),
    "identify validate models/linear_model.json more_runs/*.csv --json errors.json": Case(
        reduced="more_runs/ is a second play of runs/ with another noise seed",
        setup=lambda work: _more_runs(work),
        outputs=("errors.json",),
        after=("identify linear measured/*.csv --order 4 --out models/linear_model.json",),
    ),
    "identify validate models/ann/model more_runs/*.csv": Case(
        setup=lambda work: _more_runs(work),
        after=("identify ann measured/*.csv --axis both --out models/ann/model",),
    ),
    # Black-box XY stage, part 2: optimised references
    "optimize text:r --text-height 0.019 --amax 1 --tolerance 20e-6 --out opt_r/": Case(
        argv="optimize text:r --text-height 0.019 --amax 1 --tolerance 20e-6 --out opt_r/ --n 80",
        reduced="--n 80 stage-1 points",
        outputs=("opt_r/command.csv", "opt_r/input_400hz.csv"),
    ),
    "optimize text:r --text-height 0.019 --model models/ --amax 1 --out opt_own/": Case(
        argv="optimize text:r --text-height 0.019 --model models/ --amax 1 --out opt_own/ --n 80",
        reduced="--n 80 stage-1 points; the models of the reduced identify commands above",
        outputs=("opt_own/command.csv", "opt_own/baseline.csv"),
        after=(
            "identify linear measured/*.csv --order 4 --out models/linear_model.json",
            "identify ann measured/*.csv --axis both --out models/ann/model",
        ),
    ),
    "stage play opt_own/command.csv opt_own/baseline.csv --out played_own/": Case(
        outputs=("played_own/command.csv", "played_own/baseline.csv"),
        after=("optimize text:r --text-height 0.019 --model models/ --amax 1 --out opt_own/",),
    ),
    "stage score played_own/command.csv --drawing opt_own/ --baseline "
    "played_own/baseline.csv --json score.json": Case(
        outputs=("score.json",),
        after=("stage play opt_own/command.csv opt_own/baseline.csv --out played_own/",),
    ),
    "optimize airfoil:e344 --chord 0.106 --model report/stage_identify --stage 1 --amax 3 "
    "--out opt_airfoil/": Case(
        argv="optimize airfoil:e344 --chord 0.106 --model report/stage_identify --stage 1 "
        "--amax 3 --out opt_airfoil/ --n 80",
        reduced="--n 80; the models of the reduced stage-identify job",
        outputs=("opt_airfoil/command.csv",),
        after=("run examples/blackbox_stage_identify.toml",),
    ),
}


def _my_job_ran(work: Path) -> None:
    """my_job.toml (one 40 µs inkjet point) run once, then its duration changed to 50 µs."""
    text = (
        '[job]\nkind = "droplet-sweep"\nout = "my_job"\n[sweep]\nconcentrations_pct = [1.0]\n'
        "voltages_v = []\nduration_us = {}\n[run]\nworkers = 1\n"
    )
    (work / "my_job.toml").write_text(text.format(40.0), encoding="utf-8")
    res = _invoke(work, ["run", "my_job.toml"])
    assert res.exit_code == 0, res.output
    (work / "my_job.toml").write_text(text.format(50.0), encoding="utf-8")
    res = _invoke(work, ["run", "my_job.toml"])
    assert res.exit_code == 2 and "other settings" in res.output, res.output


def _more_runs(work: Path) -> None:
    """``more_runs/``: the runs of ``stage excite`` played again with noise seed 7."""
    if not (work / "more_runs").exists():
        res = _invoke(work, ["stage", "play", "runs/", "--out", "more_runs/", "--seed", "7"])
        assert res.exit_code == 0, res.output


#: README commands not run here, each with its reason.
EXCLUDED: dict[str, str] = {
    "reproduce droplet-fig4 --set workers=2": "13 breakup runs (24 s with 10 µs each); no "
    "setting cuts the points; seed 003 tests run the reproduction's points",
    "reproduce droplet-fig4": "as `reproduce droplet-fig4 --set workers=2`",
    "calibrate galvo": "600 model runs, 11 s of CPU; tests/cli/test_calibrate_galvo.py runs "
    "it on the least budget",
    "reproduce nanomanipulator --json s001.json": "35 s (23 s with --set fig8_sweep=octaves); "
    "tests/experiments/seed001_nanomanipulator run it with the octaves",
    "reproduce nanomanipulator --out s001": "as `reproduce nanomanipulator --json s001.json`",
    "calibrate nanomanipulator": "240 runs of the seed's job (minutes); tests/machines/"
    "nanomanipulator/test_calibration.py runs the fit",
    "reproduce laser-micromachining": "24 s even without its speed study; "
    "tests/experiments/seed004_laser run its parts",
    "reproduce slm-shaper": "10 s, no setting shortens it; tests/experiments/seed003_slm/"
    "test_reproduce.py runs it",
    "reproduce stage-models --set networks=false": "600 s of twin data for the linear "
    "model alone, no setting shortens it; tests/experiments/seed002_stage run its parts",
    "droplet sweep --scheduler tcp://10.0.0.5:8786": "needs a running Dask scheduler at "
    "that address",
    "droplet calibrate --workers 2 --out runs/ink --write src/microfab/data/naalg.toml": "120 "
    "evaluations of six runs each, 10-15 minutes; writes the package's property table "
    "(tests/machines/printhead/test_calibration.py runs the core on it with a tiny budget)",
    "droplet sensitivity": "dozens of 400 µs breakup runs and no option shortens them",
    "calibrate xy-stage --workers 2 --out runs/xy-cal": "120 evaluations of 3 s each and "
    "the sensitivity and conflict sweep (about 15 min on 2 cores); tests/cli/"
    "test_calibrate_xy_stage.py runs it on the least budget and the smallest data",
    "run examples/blackbox_stage_reference.toml": "even one letter at one a_max with one "
    "Gauss-Newton iteration and the sizing given took 27 s (14 s CPU); "
    "tests/experiments/seed002_reference and tests/optimize run its parts",
    "reproduce reference-opt --json r.json": "11 two-stage optimisations (minutes); "
    "tests/experiments/seed002_reference run its parts",
}


# --- running ----------------------------------------------------------------------------


def _invoke(work: Path, argv: list[str]) -> Any:
    import os

    cwd = os.getcwd()
    os.chdir(work)
    try:
        return runner.invoke(app, argv)
    finally:
        os.chdir(cwd)


COMMANDS = readme_commands(README.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> dict[str, Any]:
    """The one working folder all README commands run in, and which of them have run."""
    return {"dir": tmp_path_factory.mktemp("readme"), "done": {}, "times": {}}


def _default_job(work: Path) -> Any:
    """The shipped default job reduced (`DEFAULT_JOB_CHANGES`), read from a copy."""
    from microfab.experiments.catalog import load_job

    copy = work / ".default_job.toml"
    _job_copy(ROOT / "src" / "microfab" / "data" / "default_job.toml", copy, DEFAULT_JOB_CHANGES)
    return load_job(copy)


def _run_case(key: str, state: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> str:
    if key in state["done"]:
        return state["done"][key]
    case = CASES[key]
    for dep in case.after:
        _run_case(dep, state, monkeypatch)
    work: Path = state["dir"]
    if case.setup is not None:
        case.setup(work)
    argv = []
    for word in shlex.split(case.argv if case.argv is not None else key):
        # the shell expands a pattern (measured/*.csv) before microfab sees it
        argv += (
            sorted(p.relative_to(work).as_posix() for p in work.glob(word)) or [word]
            if "*" in word
            else [word]
        )
    if argv == ["run"]:
        import microfab.experiments.catalog as catalog

        monkeypatch.setattr(catalog, "default_job", lambda: _default_job(work))
    start = time.perf_counter()
    res = _invoke(work, argv)
    state["times"][key] = time.perf_counter() - start
    assert res.exit_code == 0, f"microfab {' '.join(argv)} (README: {key}):\n{res.output}"
    for name in case.outputs:
        p = work / name
        assert p.exists() and (p.is_dir() or p.stat().st_size > 0), f"{key}: no {name}"
    for text in case.says:
        assert text in res.output, f"{key}: output lacks {text!r}:\n{res.output}"
    state["done"][key] = res.output
    return res.output


def test_readme_has_commands() -> None:
    assert len(COMMANDS) > 30, COMMANDS


def test_every_readme_command_is_run_or_excluded() -> None:
    missing = [c for c in COMMANDS if c not in CASES and c not in EXCLUDED]
    assert not missing, (
        "README commands neither run by tests/test_readme.py (CASES) nor excluded with a "
        "reason (EXCLUDED):\n" + "\n".join(f"  microfab {c}" for c in missing)
    )


def test_no_stale_entries() -> None:
    stale = [c for c in [*CASES, *EXCLUDED] if c not in COMMANDS]
    assert not stale, "entries for commands the README no longer has:\n" + "\n".join(stale)


#: Run last, by `test_the_default_job_runs_after_every_readme_command`.
DEFAULT = "run"


@pytest.mark.parametrize("key", [c for c in dict.fromkeys(COMMANDS) if c in CASES and c != DEFAULT])
def test_readme_command_runs(key: str, work: dict[str, Any], monkeypatch) -> None:
    _run_case(key, work, monkeypatch)


def test_the_default_job_runs_after_every_readme_command(work, monkeypatch) -> None:
    """`make run` works whatever was run before: it runs after every other command.

    Each command above left its default output in the work folder (``report/laser``,
    ``report/droplet/simulate``, ...); ``microfab run`` (the default job, reduced) must
    then start its own folder and write its report.
    """
    for key in CASES:
        if key != DEFAULT:
            _run_case(key, work, monkeypatch)
    assert not (work["dir"] / "report" / "msl-ilc").exists()
    assert len([p for p in (work["dir"] / "report").iterdir() if p.is_dir()]) >= 5
    _run_case(DEFAULT, work, monkeypatch)
    slow = sorted(work["times"].items(), key=lambda kv: -kv[1])[:6]
    print("slowest README commands:", ", ".join(f"{k} {t:.1f} s" for k, t in slow))
