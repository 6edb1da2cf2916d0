"""One valid, cheap invocation of every ``microfab`` command, and a folder of valid inputs.

`RECIPES` maps each leaf command of the CLI (as typed: ``"ilc step"``, ``"kinds"``) to a
`Recipe`: the arguments of ``microfab``, with paths relative to a workspace folder, the
workspace paths the command reads and those it writes. `build_workspace` fills a folder
with every input a recipe reads; run there, each recipe exits 0. An option generator
(``fuzz_options``) starts from these command lines and changes one option at a time.

The inputs are made once per process into a template folder (per PID: the fuzz runner
forks its workers) with the library and with ``microfab`` commands themselves, then copied:

=======================  =======================================================
workspace path           what it is, made by
=======================  =======================================================
``job.toml``             ``examples/galvo_msl_default.toml`` (``run``)
``laser_job.toml``       a laser-micromachining job, one lap (``laser export``)
``nano_job.toml``        ``examples/nanomanipulator_msl.toml`` (the seed's job)
``nano_small_job.toml``  the same, one circle of four periods (calibrate nanomanipulator)
``part.dxf``             a 2 mm square and a circle in mm (ezdxf)
``chirp.csv``            the SLM twin's chirp record (`fuzz_slm.base_chirp`)
``model.json``           the seed 003 model (`fuzz_slm.base_model`)
``frf.csv``              the seed model's FRF with a mirror mode (`fuzz_slm._frf_file`)
``shaper.json``          a ZV shaper (`fuzz_slm.base_shapers`)
``runs/r*.h5``           three 0.7 s stage runs at 2 kHz (``identify``)
``linear_model.json``    ``identify linear runs/*`` (``identify validate``)
``excited/``             ``stage excite --duration 0.6``: one command run (``stage play``)
``models/``              a stage model folder: ``linear_model.json`` (``optimize``)
``opt_done/``            ``optimize --stage 1`` on it, .h5 command files (``stage score``)
``opt_played/``          ``stage play`` of its command and baseline (``stage score``)
``ilc_trial.csv``        the next trial (`fuzz_cases.base_trial_csv`) on ...
``ilc_state/``           ... the ILC state after one ``ilc step``
``rc_trial.csv``         the next period on ...
``rc_state/``            ... the RC state after one ``rc step``
``nano_trace.h5``        a measured one-circle pattern (``nanomanipulator analyze``)
``laser_trace.h5``       a laser stage contour run with currents (``laser analyze``)
``frames/``              ``droplet render`` shadowgraph frames (``droplet analyze``)
``naalg.toml``           the package's NaAlg property table (``droplet calibrate``)
=======================  =======================================================

`SLOW` lists the commands whose cheapest valid run still takes more than about 3 s (the
seconds measured on a 2-core box); `check_recipes` runs every recipe and times it.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["RECIPES", "SLOW", "Recipe", "build_workspace", "check_recipes"]

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Recipe:
    """One valid invocation: ``microfab *argv`` run in a folder filled by `build_workspace`.

    Attributes
    ----------
    argv : tuple of str
        Arguments of ``microfab``, paths relative to the workspace folder.
    inputs : tuple of str
        Workspace paths (files or folders) this invocation reads.
    outputs : tuple of str
        Workspace paths (files or folders) it writes.
    """

    argv: tuple[str, ...]
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()


# --------------------------------------------------------------------------- the recipes
CHIRP_ARGS = ("--f0", "100", "--f1", "2000", "--period", "0.01", "--band", "100:2000")
RUNS = ("runs/r0.h5", "runs/r1.h5", "runs/r2.h5")
# a one-circle pattern, short (0.24 s, 480 samples at 2 kHz): nanomanipulator analyze's options
NANO_OPTS = ("--period", "0.05", "--periods", "3", "--circles", "1", "--pause-s", "0.02",
             "--move-s", "0.03", "--ramp-s", "0.02", "--sample-rate-hz", "2000")  # fmt: skip
NANO_PATTERN = {"n_circles": 1, "period_s": 0.05, "periods": 3, "pause_s": 0.02,
                "move_s": 0.03, "ramp_s": 0.02}  # fmt: skip
NANO_DT = 1 / 2000

RECIPES: dict[str, Recipe] = {
    "calibrate galvo": Recipe(
        ("calibrate", "galvo", "--budget", "20", "--conflict-budget", "0", "--out",
         "galvo_run", "--json", "galvo_cal.json", "--write", "galvo_cal.toml"),
        outputs=("galvo_run", "galvo_cal.json", "galvo_cal.toml")),
    "calibrate laser": Recipe(("calibrate", "laser", "--budget", "17", "--conflict-budget", "0",
                               "--write", "laser_twin.toml"),
                              outputs=("laser_twin.toml",)),
    "calibrate nanomanipulator": Recipe(
        ("calibrate", "nanomanipulator", "--job", "nano_small_job.toml", "--budget", "17",
         "--conflict-budget", "0", "--write", "nano_twin.toml"),
        inputs=("nano_small_job.toml",), outputs=("nano_twin.toml",)),
    # the smallest data (4 s of the networks' data leave a validation run with runs seed
    # 5) and a small proxy, about 0.08 s a model run; budget 32: one population and the
    # polish for the 10 free parameters (the least the core takes)
    "calibrate xy-stage": Recipe(
        ("calibrate", "xy-stage", "--duration", "0.5", "--ann-duration", "4", "--runs-seed",
         "5", "--proxy-hidden", "8", "--proxy-offsets", "1", "--budget", "32",
         "--conflict-budget", "0", "--out", "xy_run", "--json", "xy_cal.json", "--write",
         "xy_twin.toml"),
        outputs=("xy_run", "xy_cal.json", "xy_twin.toml")),
    "droplet analyze": Recipe(
        ("droplet", "analyze", "frames", "--out", "analysis.png", "--json", "analysis.json"),
        inputs=("frames",), outputs=("analysis.png", "analysis.json")),
    "droplet calibrate": Recipe(
        ("droplet", "calibrate", "--model", "eulerian", "--duration", "20", "--budget", "13",
         "--conflict-budget", "0", "--out", "ink_run", "--json", "ink_cal.json", "--write",
         "naalg.toml"),
        inputs=("naalg.toml",), outputs=("naalg.toml", "ink_run", "ink_cal.json")),
    "droplet render": Recipe(
        ("droplet", "render", "rendered", "--duration", "100", "--frame-interval", "25"),
        outputs=("rendered",)),
    "droplet sensitivity": Recipe(
        ("droplet", "sensitivity", "--concentrations", "0.15", "--model", "eulerian",
         "--out", "sensitivity"),
        outputs=("sensitivity",)),
    "droplet simulate": Recipe(
        ("droplet", "simulate", "--duration", "5", "--after-breakup", "1", "--out",
         "droplet", "--json", "droplet.json"),
        outputs=("droplet", "droplet.json")),
    "droplet sweep": Recipe(
        ("droplet", "sweep", "--concentrations", "0.15", "--voltages", "50", "--duration",
         "10", "--out", "sweep"),
        outputs=("sweep",)),
    "identify ann": Recipe(
        ("identify", "ann", *RUNS, "--out", "ann_model", "--epochs", "1", "--device", "cpu",
         "--axis", "x"),
        inputs=RUNS, outputs=("ann_model",)),
    "identify chirp": Recipe(
        ("identify", "chirp", "chirp.csv", *CHIRP_ARGS, "--json", "chirp_model.json",
         "--plot", "chirp_fit.png"),
        inputs=("chirp.csv",), outputs=("chirp_model.json", "chirp_fit.png")),
    "identify linear": Recipe(
        ("identify", "linear", *RUNS, "--out", "linear_out.json"),
        inputs=RUNS, outputs=("linear_out.json",)),
    "identify validate": Recipe(
        ("identify", "validate", "linear_model.json", RUNS[0], "--json", "validate.json"),
        inputs=("linear_model.json", RUNS[0]), outputs=("validate.json",)),
    "ilc step": Recipe(
        ("ilc", "step", "ilc_trial.csv", "--state", "ilc_state", "--out", "ilc_next.csv"),
        inputs=("ilc_trial.csv", "ilc_state"), outputs=("ilc_state", "ilc_next.csv")),
    "kinds": Recipe(("kinds", "msl-ilc")),
    "laser analyze": Recipe(
        ("laser", "analyze", "laser_trace.h5", "--drawing", "circle:radius=30e-6",
         "--replay", "--job", "laser_job.toml", "--out", "laser_report", "--json",
         "laser.json"),
        inputs=("laser_trace.h5", "laser_job.toml"), outputs=("laser_report", "laser.json")),
    "laser export": Recipe(("laser", "export", "laser_job.toml", "--out", "laser_target"),
                           inputs=("laser_job.toml",), outputs=("laser_target",)),
    "nanomanipulator analyze": Recipe(
        ("nanomanipulator", "analyze", "nano_trace.h5", *NANO_OPTS, "--out", "nano_report",
         "--json", "nano.json"),
        inputs=("nano_trace.h5",), outputs=("nano_report", "nano.json")),
    "optimize": Recipe(
        ("optimize", "circle:radius=0.002", "--model", "models", "--out", "optimized",
         "--stage", "1", "--n", "20"),
        inputs=("models",), outputs=("optimized",)),
    "path show": Recipe(("path", "show", "part.dxf", "--out", "part.png", "--json"),
                        inputs=("part.dxf",), outputs=("part.png",)),
    "rc step": Recipe(
        ("rc", "step", "rc_trial.csv", "--state", "rc_state", "--out", "rc_next.csv"),
        inputs=("rc_trial.csv", "rc_state"), outputs=("rc_state", "rc_next.csv")),
    "reproduce": Recipe(("reproduce", "msl-ilc", "--check", "--json", "reproduce.json"),
                        outputs=("reproduce.json",)),
    "run": Recipe(("run", "job.toml", "--check", "--out", "run_report"),
                  inputs=("job.toml",), outputs=("run_report",)),
    "shaper compare": Recipe(("shaper", "compare", "--json", "compare.json"),
                             outputs=("compare.json",)),
    "shaper design": Recipe(
        ("shaper", "design", "model.json", "--kind", "inverse", "--out", "designed.json"),
        inputs=("model.json",), outputs=("designed.json",)),
    "slm build": Recipe(
        ("slm", "build", "--layers", "1", "--outline-radius-mm", "1", "--results-dir",
         "slm_layers", "--json", "build.json"),
        outputs=("slm_layers", "build.json")),
    "slm scan-time": Recipe(
        ("slm", "scan-time", "part.dxf", "--shaper", "shaper.json", "--json", "scan.json"),
        inputs=("part.dxf", "shaper.json"), outputs=("scan.json",)),
    "stage excite": Recipe(("stage", "excite", "--duration", "1", "--out", "excite"),
                           outputs=("excite",)),
    "stage play": Recipe(("stage", "play", "excited", "--out", "played", "--seed", "1",
                          "--hold", "0.1", "--format", "csv"),
                         inputs=("excited",), outputs=("played",)),
    "stage score": Recipe(("stage", "score", "opt_played/command.h5", "--drawing", "opt_done",
                           "--baseline", "opt_played/baseline.h5", "--json", "score.json"),
                          inputs=("opt_played/command.h5", "opt_played/baseline.h5",
                                  "opt_done"), outputs=("score.json",)),
    "trajectory": Recipe(
        ("trajectory", "part.dxf", "--time-optimal", "--n-grid", "50", "--rate", "2000",
         "--out", "reference.csv", "--plot", "profile.png"),
        inputs=("part.dxf",), outputs=("reference.csv", "profile.png")),
}  # fmt: skip

#: Commands whose cheapest valid run takes about 3 s or more: seconds measured in process on
#: a 2-core box. droplet calibrate runs one population of the core's search and the
#: sensitivity (19 parameter sets of six 20 µs Eulerian runs); calibrate nanomanipulator
#: and calibrate laser run one population of the search and the sensitivity (about 27 runs
#: of the seed's job).
SLOW: dict[str, float] = {
    "droplet calibrate": 5.5,
    "calibrate nanomanipulator": 20.0,
    "calibrate laser": 20.0,  # one population and the sensitivity: 27 runs of Fig. 3
    # one population, the polish and the sensitivity: 45 model runs, 7.8 s CPU (10.4 s
    # wall, 2-core box shared); tests/cli/test_calibrate_xy_stage.py runs it in the suite
    "calibrate xy-stage": 10.0,
}


# --------------------------------------------------------------------------- the inputs
def _write(path: Path, data: bytes | str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        path.write_text(data, encoding="utf-8")
    else:
        path.write_bytes(data)


def _cli(work: Path, *argv: str) -> None:
    """Run ``microfab argv`` in ``work``; it must succeed."""
    from fuzz_driver import _in_folder, invoke

    with _in_folder(work):
        code, output, exc = invoke(argv)
    if code != 0 or exc is not None:
        raise RuntimeError(f"microfab {' '.join(argv)} failed ({code}): {output} {exc!r}")


def _jobs(work: Path) -> None:
    _write(work / "job.toml", (ROOT / "examples" / "galvo_msl_default.toml").read_bytes())
    _write(work / "laser_job.toml",
           '[job]\nkind = "laser-micromachining"\nout = "laser_run"\n'
           "[trajectory]\nlaps = 1\n")  # fmt: skip
    _write(
        work / "nano_job.toml", (ROOT / "examples" / "nanomanipulator_msl.toml").read_bytes()
    )  # the seed's job
    seed_job = (ROOT / "examples" / "nanomanipulator_msl.toml").read_text(encoding="utf-8")
    _write(  # one circle of four periods: a calibration's 27 runs in a few seconds
        work / "nano_small_job.toml",
        seed_job.replace("n_circles = 4", "n_circles = 1").replace("periods = 6", "periods = 4"),
    )
    _write(work / "naalg.toml", (ROOT / "src" / "microfab" / "data" / "naalg.toml").read_bytes())


def _drawing(work: Path) -> None:
    import ezdxf

    doc = ezdxf.new("R2010", units=4)  # mm
    msp = doc.modelspace()
    msp.add_lwpolyline([(0, 0), (2, 0), (2, 2), (0, 2)], close=True)
    msp.add_circle((1, 1), 0.5)
    doc.saveas(work / "part.dxf")


def _slm(work: Path) -> None:
    import fuzz_cases  # noqa: F401  (imports fuzz_slm, which needs it first)
    from fuzz_slm import _frf_file, _model_dict, base_chirp, base_shapers

    from microfab.io.trace import write_columns

    write_columns(work / "chirp.csv", dict(base_chirp()), unit="bit")
    _write(work / "model.json", _model_dict())
    _write(work / "frf.csv", _frf_file())
    _write(work / "shaper.json", dict(base_shapers())["zv"])


def _stage_runs(work: Path) -> None:
    """Three smooth set-point runs from rest at 2 kHz, 0.7 s, and a lagged measurement."""
    from microfab.io.trace import write_columns

    n, dt = 1400, 1 / 2000
    for i, name in enumerate(RUNS):
        rng = np.random.default_rng(i)
        u = 0.01 * np.cumsum(np.cumsum(rng.standard_normal((n, 2)), axis=0), axis=0) / n**1.5
        u -= u[0]
        y = np.vstack([u[:1], u[:-1]]) + 1e-6 * rng.standard_normal(u.shape)
        cols = {"time": np.arange(n) * dt, "input_x": u[:, 0], "input_y": u[:, 1],
                "output_x": y[:, 0], "output_y": y[:, 1]}  # fmt: skip
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        write_columns(work / name, cols, unit="m")
    _cli(work, "identify", "linear", *RUNS, "--out", "linear_model.json")
    _cli(work, "stage", "excite", "--duration", "0.6", "--out", "excited")


def _models(work: Path) -> None:
    """A stage-identify output folder with only its linear model (``optimize --stage 1``)."""
    import scipy.signal

    from microfab.identify.stage_data import StageLinearModel, write_stage_model
    from microfab.identify.subspace_model import SubspaceModel

    def axis(wn: float, zeta: float, wz: float, d: float) -> tuple[np.ndarray, ...]:
        a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
        c = np.array([[wn**2 - d * wn**2, wz - d * 2 * zeta * wn]])
        return a, np.array([[0.0], [1.0]]), c

    (ax, bx, cx), (ay, by, cy) = axis(70.0, 0.5, 40.0, 0.9), axis(60.0, 0.6, 30.0, 0.9)
    z2, z1 = np.zeros((2, 2)), np.zeros((2, 1))
    a = np.block([[ax, z2], [z2, ay]])
    b = np.block([[bx, z1], [z1, by]])
    c = np.block([[cx, np.zeros((1, 2))], [np.zeros((1, 2)), cy]])
    dsys = scipy.signal.StateSpace(a, b, c, np.diag([0.9, 0.9])).to_discrete(1e-3)
    sub = SubspaceModel(a=dsys.A, b=dsys.B, c=dsys.C, d=dsys.D, dt=1e-3, x0=np.zeros((1, 4)),
                        singular_values=np.ones(4), block_rows=10, weighting="n4sid",
                        fit_mean=np.zeros(4), fit_std=np.ones(4))  # fmt: skip
    (work / "models").mkdir()
    write_stage_model(work / "models" / "linear_model.json",
                      StageLinearModel(model=sub, input_dt=1e-4, decimate=10))  # fmt: skip
    _cli(work, "optimize", "circle:radius=0.002", "--model", "models", "--out", "opt_done",
         "--stage", "1", "--n", "20", "--format", "h5")  # fmt: skip
    _cli(work, "stage", "play", "opt_done/command.h5", "opt_done/baseline.h5", "--out",
         "opt_played", "--format", "h5")  # fmt: skip


def _ilc(work: Path) -> None:
    from fuzz_cases import base_trial_csv

    _write(work / "ilc_first.csv", base_trial_csv(second=False))
    _cli(work, "ilc", "step", "ilc_first.csv", "--state", "ilc_state", "--out", "ilc_next.csv")
    (work / "ilc_first.csv").unlink()
    (work / "ilc_next.csv").unlink()
    _write(work / "ilc_trial.csv", base_trial_csv(second=True))


def _rc(work: Path) -> None:
    """Two periods of a 100 Hz circle at 10 kHz: the first makes ``rc_state``."""
    from microfab.io.trace import write_columns

    n, dt = 100, 1e-4
    t = np.arange(2 * n) * dt
    w = 2 * np.pi / (n * dt)
    pos = 0.075 * np.column_stack([np.cos(w * t), np.sin(w * t)])
    for name, sl, k in (
        ("rc_first.csv", slice(0, n), 0.9),
        ("rc_trial.csv", slice(n, 2 * n), 0.95),
    ):
        y = k * pos[sl]
        write_columns(work / name, {"time": t[sl], "ref_x": pos[sl, 0], "ref_y": pos[sl, 1],
                                    "x": y[:, 0], "y": y[:, 1]})  # fmt: skip
    _cli(work, "rc", "step", "rc_first.csv", "--state", "rc_state", "--out", "rc_next.csv",
         "--tau-ms", "0.5", "--lead-samples", "4")  # fmt: skip
    (work / "rc_first.csv").unlink()
    (work / "rc_next.csv").unlink()


def _nano(work: Path) -> None:
    """The one-circle pattern run 300 nm outside its circle, the laser on in period 3."""
    from microfab.io.trace import write_columns
    from microfab.trajectory.circle_pattern import PatternConfig, pattern_reference

    ref = pattern_reference(PatternConfig(**NANO_PATTERN), NANO_DT)
    y = ref.position.copy()
    laser = np.zeros(ref.n_samples)
    n = ref.period_samples
    for i, c in enumerate(ref.centres):
        sl = ref.circle_slice(i)
        u = (ref.position[sl] - c) / ref.radius_mm
        y[sl] = c + (ref.radius_mm + 3e-4) * u
        laser[ref.starts[i] + 2 * n : ref.starts[i] + 3 * n] = 1.0
    write_columns(work / "nano_trace.h5", {
        "time": np.arange(ref.n_samples) * NANO_DT, "ref_x": ref.position[:, 0],
        "ref_y": ref.position[:, 1], "x": y[:, 0], "y": y[:, 1], "laser": laser})  # fmt: skip


def _laser(work: Path) -> None:
    """A one-lap run of the seed 004 circle on the twin, with currents and derivatives."""
    from microfab.core.signals import Trace
    from microfab.io.trace import write_trace
    from microfab.machines.laser_stage.contour import run_contour
    from microfab.machines.laser_stage.machine import ContourJob
    from microfab.trajectory.contour_laps import ContourMotion

    run = run_contour(ContourJob(motion=ContourMotion(laps=1)))
    tr = run.reference.trajectory
    pos, vel, acc = (np.asarray(a) for a in (tr.position, tr.velocity, tr.acceleration))
    cols = {"ref_x": pos[:, 0], "ref_y": pos[:, 1], "x": run.measured[:, 0],
            "y": run.measured[:, 1], "current_x": run.command[:, 0],
            "current_y": run.command[:, 1], "ref_vx": vel[:, 0], "ref_vy": vel[:, 1],
            "ref_ax": acc[:, 0], "ref_ay": acc[:, 1]}  # fmt: skip
    trace = Trace(dt=run.dt, values=np.column_stack(list(cols.values())), axes=tuple(cols))
    write_trace(trace, work / "laser_trace.h5")


def _frames(work: Path) -> None:
    _cli(work, "droplet", "render", "frames", "--duration", "100", "--frame-interval", "25")


BUILDERS = (_jobs, _drawing, _slm, _stage_runs, _models, _ilc, _rc, _nano, _laser, _frames)


def template() -> Path:
    """This process's template workspace, built on the first call.

    It lives in `fuzz_driver._template_dir` (one per PID, so a forked worker builds its
    own; removed at exit, or by a pool worker when it stops).
    """
    from fuzz_driver import _template_dir

    tpl = _template_dir() / "workspace"
    if not tpl.is_dir():
        work = Path(tempfile.mkdtemp(prefix="workspace-", dir=_template_dir()))
        for build in BUILDERS:
            build(work)
        work.rename(tpl)
    return tpl


def build_workspace(dest: Path) -> None:
    """Fill the (empty, existing) folder ``dest`` with every input a recipe reads."""
    shutil.copytree(template(), dest, dirs_exist_ok=True)


# --------------------------------------------------------------------------- the check
def _under(rel: str, paths: list[str]) -> bool:
    return any(rel == p or rel.startswith(p.rstrip("/") + "/") for p in paths)


def run_recipe(name: str, timeout_s: float = 60.0) -> tuple[str, float, str]:
    """Run one recipe in a fresh workspace: (outcome, seconds, detail)."""
    from fuzz_driver import _alarm, _hashes, _in_folder, classify, invoke

    recipe = RECIPES[name]
    with tempfile.TemporaryDirectory(prefix="microfab-ws-") as tmp:
        work = Path(tmp)
        build_workspace(work)
        missing = [p for p in recipe.inputs if not (work / p).exists()]
        if missing:
            return "missing", 0.0, f"inputs not in the workspace: {missing}"
        before = _hashes(work)
        t0 = time.perf_counter()
        with _in_folder(work), _alarm(timeout_s):
            code, output, exc = invoke(recipe.argv)
        seconds = time.perf_counter() - t0
        outcome = classify(code, output, exc)
        if outcome == "accepted":
            absent = [p for p in recipe.outputs if not (work / p).exists()]
            if absent and name not in ("run", "reproduce"):  # --check writes nothing
                return "no-output", seconds, f"outputs not written: {absent}"
            after = _hashes(work)
            kept = [p for p in recipe.inputs if p not in recipe.outputs]
            changed = [k for k in before if after.get(k) != before[k] and _under(k, kept)]
            if changed:
                return "input-changed", seconds, f"inputs changed: {changed}"
        detail = f"{exc!r}" if exc is not None else output[-800:]
        return outcome, seconds, detail


def check_recipes(names: list[str] | None = None) -> dict[str, float]:
    """Run every recipe (or ``names``) in its own fresh workspace; seconds per command."""
    times = {}
    for name in names or sorted(RECIPES):
        outcome, seconds, detail = run_recipe(name)
        assert outcome == "accepted", f"{name}: {outcome}: {detail}"
        times[name] = seconds
    return times


if __name__ == "__main__":
    import sys

    t0 = time.perf_counter()
    tpl = template()
    size = sum(p.stat().st_size for p in tpl.rglob("*") if p.is_file())
    print(f"template built in {time.perf_counter() - t0:.1f} s, {size / 1e3:.0f} kB")
    for name in sys.argv[1:] or sorted(RECIPES):
        outcome, seconds, detail = run_recipe(name)
        flag = "" if outcome == "accepted" else f"  <-- {outcome}: {detail}"
        print(f"{seconds:7.2f} s  {name}{flag}", flush=True)
