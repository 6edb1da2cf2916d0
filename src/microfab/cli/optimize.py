"""``microfab optimize``: the two-stage reference optimisation of seed 002 on a drawing.

Stage 1 (eqs. 8-12, linear model, minimum time within the tolerance) and stage 2 (eqs.
13-14, the networks refine the 400 Hz input), then the 10 kHz command, checked against
Table I. The models are read from one folder (``--model DIR``, default the shipped ones,
`microfab.optimize.models.resolve_models_dir`): ``DIR/linear_model.json`` (``identify
linear RUNS --out DIR/linear_model.json``) and ``DIR/ann/model`` (``identify ann RUNS --out
DIR/ann/model``), the layout a ``stage-identify`` job writes too; a missing one is refused
naming the file and the command that makes it.

Writes into ``--out``: ``command.<fmt>`` (the stage's command file, as ``stage excite``
writes and ``stage play`` reads: time, input_x, input_y, m, 10 kHz), ``baseline.<fmt>``
(the time-optimal command under Table I stretched to the same ``T``, the reference job's
stronger baseline, held to ``t_M``; eq. (15)'s baseline breaks Table I and no machine
plays it as given), ``input_400hz.csv`` (``r``), ``predicted.csv`` (the networks' output
and the target at 400 Hz), ``stage1.npz``, ``summary.json`` (with the drawing's sizing and
each command file's ``t_0`` sample, which ``stage score`` reads) and two figures (the
contour with the input and the predicted output, the deviation along ``s``). Stage 2 saves
a checkpoint (``stage2_checkpoint.npz``) every few iterations and a rerun resumes it;
``--stage 1`` stops after stage 1 (no networks needed). A refusal is one ``error:``
line, exit code 2, and nothing is written (a stage-2 checkpoint already saved is kept
for the resume). The folder is written whole: the results go into a temporary folder
inside it and are moved in at the end, and the files an earlier run left that this one
does not write (``predicted.csv`` and the checkpoint after ``--stage 1``, a command file of
another ``--format``) are removed; other files in the folder are left alone.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import check_outputs, console, fail
from microfab.cli._options import choice, integer, number
from microfab.cli.geometry import ChordOpt, HeightOpt, UnitsOpt, refuse_unused_sizing
from microfab.io.lock import hold_for_command

__all__ = ["optimize_cmd"]

_FORMATS = ("csv", "h5", "mat")
_CHECKPOINT = "stage2_checkpoint.npz"
_STAGES = ("1", "both")
_A_MAX = 40.0  # seed 002 Table I: the machine's acceleration limit, m/s²
#: Assumed floors: below 1 mm/s² a contour of millimetres takes minutes and stage 2's M
#: (400 Hz) grows past 1e5 samples; a tolerance under 1 nm is 2000x below the twin's 2 µm
#: noise (seed 002 eq. 3) and only makes the solvers meet infinities.
_A_MIN = 1e-3
_TOL_MIN = 1e-9
#: Assumed ceiling: 1 mm is 50x the seed's 20 µm (seed 002 §V) and wider than the smallest
#: features of the drawings it traces; the contour is then no longer what is tracked.
_TOL_MAX = 1e-3
#: Most stage-1 points: 2.5x the largest default (seed 002 §IV-A: spacing μ, 200-2000).
_N_MAX = 5000
#: Fewest stage-1 points (assumed: fewer do not resolve a contour's corners at all).
_N_MIN = 10


def optimize_cmd(
    ctx: typer.Context,
    drawing: Annotated[
        str,
        typer.Argument(
            help="A .dxf/.svg/.dat file, a shape (circle:radius=0.01, ...), text:LETTERS or "
            "airfoil:e344; one closed or open contour (see --contour)."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="Directory for the results.")],
    model: Annotated[
        Path | None,
        typer.Option(
            "--model",
            help="Models folder: DIR/linear_model.json (identify linear --out "
            "DIR/linear_model.json) and DIR/ann/model (identify ann --out DIR/ann/model), "
            "as a stage-identify job writes them; default: the models shipped with microfab "
            "(the built-in twin's).",
        ),
    ] = None,
    amax: Annotated[
        float,
        number(
            help="Output acceleration bound a_max (seed 002: 1-3).",
            unit="m/s²",
            low=_A_MIN,
            high=_A_MAX,
        ),
    ] = 1.0,
    tolerance: Annotated[
        float,
        number(
            help="Tolerance μ around the contour (seed 002: 20e-6).",
            unit="m",
            low=_TOL_MIN,
            high=_TOL_MAX,
        ),
    ] = 20e-6,
    stage: Annotated[
        str, choice(choices=_STAGES, help="Stages run: both, or 1 (stage 1 only, no networks).")
    ] = "both",
    n: Annotated[
        int | None,
        integer(help="Stage-1 points N (default: spacing μ, 200-2000).", low=_N_MIN, high=_N_MAX),
    ] = None,
    contour: Annotated[
        int | None,
        integer(help="The contour to trace when the drawing has several.", low=0),
    ] = None,
    fmt: Annotated[str, choice("--format", choices=_FORMATS, help="Command file format.")] = "csv",
    chord: ChordOpt = 0.1,
    text_height: HeightOpt = 0.01,
    units: UnitsOpt = None,
) -> None:
    """Optimise the reference of a contour on a black-box stage (seed 002 §IV)."""
    from microfab.optimize.models import resolve_models_dir

    # the models folder is an input even when it is the shipped one (never written into)
    check_outputs(
        folders={"--out": out},
        inputs={"DRAWING": Path(drawing), "--model": resolve_models_dir(model)},
    )
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.optimize.problem import ContourProblem
    from microfab.optimize.stage1 import Stage1Error, Stage1Settings

    refuse_unused_sizing(ctx, drawing)
    if out.exists() and not out.is_dir():
        fail(f"--out {out} exists and is not a directory")
    from microfab.cli.geometry import _load

    layer = _load(drawing, units, chord, text_height)
    if len(layer) == 0:
        fail(f"{drawing}: no contour to trace")
    if contour is None and len(layer) > 1:
        fail(f"{drawing} has {len(layer)} contours: choose one with --contour 0..{len(layer) - 1}")
    k = 0 if contour is None else contour
    if not 0 <= k < len(layer):
        fail(f"--contour {k} is out of range: the drawing has {len(layer)} contours")
    try:
        problem = ContourProblem(layer[k], a_max=float(amax), tolerance_m=float(tolerance))
    except ValueError as exc:
        fail(str(exc))
    models = _models(model, need_networks=stage == "both")
    from microfab.core.limits import LimitViolation
    from microfab.optimize.pipeline import optimize_reference
    from microfab.trajectory.optimal import PlanningError

    checkpoint = str(out / _CHECKPOINT) if stage == "both" else None
    try:
        with console.status("stage 1: minimum time on the linear model (IPOPT)"):
            from microfab.optimize.stage1 import solve_stage1

            st1 = solve_stage1(problem, models.linear, Stage1Settings(n=n))
        console.print(
            f"stage 1: T = {st1.duration:.4f} s, N = {st1.n}, {st1.iterations} iterations, "
            f"{st1.wall_s:.1f} s",
            highlight=False,
        )
        out.mkdir(parents=True, exist_ok=True)  # only now: a refusal above writes nothing
        res = _stage2(problem, models, st1, stage, checkpoint, optimize_reference)
    except (Stage1Error, PlanningError) as exc:
        fail(str(exc))
    except LimitViolation as exc:
        fail(f"{exc}; the optimised input breaks Table I: raise the tolerance or lower --amax")
    except ValueError as exc:
        fail(str(exc))
    sizing = {"chord": chord, "text_height": text_height, "units": units}
    keep = (_CHECKPOINT,) if stage == "both" else ()  # its checkpoint, saved as it went
    _write(out, res, fmt, drawing, k, sizing, models.networks, keep)


#: The model files of a models folder and the command that writes each (README).
LINEAR_FILE = "linear_model.json"
ANN_DIR = "ann/model"


def _models(directory: Path | None, need_networks: bool) -> Any:
    """The models of ``--model``; a missing file is refused naming it and its command."""
    from microfab.optimize.models import builtin_models_dir, load_models, resolve_models_dir

    d = resolve_models_dir(directory)
    if d != builtin_models_dir():  # the shipped folder's own message says to reinstall
        if d.is_file():
            fail(f"--model {d} is a file: give the folder that holds {LINEAR_FILE} and {ANN_DIR}/")
        lin = d / LINEAR_FILE
        if not lin.is_file():
            fail(
                f"--model {d}: no {lin}; make it with `microfab identify linear RUNS --out "
                f"{lin}` (or give a stage-identify job's output folder)"
            )
        ann = d / ANN_DIR
        if need_networks and not (ann / "model.json").is_file():
            fail(
                f"--model {d}: no network model in {ann}/ (model.json); make it with "
                f"`microfab identify ann RUNS --out {ann}`, or use --stage 1 (linear model "
                "only)"
            )
    try:
        return load_models(directory, networks=need_networks)
    except ValueError as exc:
        fail(str(exc))


def _stage2(problem: Any, models: Any, st1: Any, stage: str, checkpoint: str | None,
            run: Any) -> Any:  # fmt: skip
    from microfab.cli._kit import progress

    if stage == "1":
        return run(problem, models.linear, models.networks, stage="1", stage1=st1)
    with progress() as prog:
        task = prog.add_task("stage 2: Gauss-Newton on the networks", total=None)

        def report(it: int, cost: float) -> None:
            prog.update(task, completed=it, description=f"stage 2: cost {cost:.4g}")

        def warn(text: str) -> None:  # before stage 2: what the prediction is worth
            prog.console.print(f"[yellow]warning:[/] {text}", highlight=False)

        return run(problem, models.linear, models.networks, stage="both", stage1=st1,
                   checkpoint=checkpoint, progress=report,
                   validation_sigma_m=models.validation_sigma_m, warn=warn)  # fmt: skip


def _file_digest(drawing: str) -> str | None:
    """SHA-256 of the drawing's file, or None for a shape, text or airfoil spec."""
    from microfab.io.runstore import content_digest

    p = Path(drawing)
    return content_digest(p) if p.is_file() else None


def _command_columns(position: Any) -> dict[str, Any]:
    """A 10 kHz command as the stage's command file: time, input_x, input_y (m)."""
    import numpy as np

    from microfab.optimize.pipeline import RUN_RATE_HZ

    pos = np.asarray(position, dtype=float)
    t = np.arange(pos.shape[0]) / RUN_RATE_HZ
    return {"time": t, "input_x": pos[:, 0], "input_y": pos[:, 1]}


def _baseline(res: Any) -> tuple[Any, str | None]:
    """The stretched time-optimal command at ``T``, held to ``t_M`` (or None and why)."""
    import numpy as np

    from microfab.optimize.baseline import stretched_time_optimal
    from microfab.optimize.pipeline import MODEL_RATE_HZ, RUN_RATE_HZ

    p = res.problem
    try:
        pos = stretched_time_optimal(p.path, res.duration, p.limits, RUN_RATE_HZ)
    except ValueError as exc:
        return None, f"no baseline command: {exc}"
    n = round(res.m * RUN_RATE_HZ / MODEL_RATE_HZ) + 1  # to t_M, as the reference job scores
    if pos.shape[0] < n:
        pos = np.vstack([pos, np.repeat(pos[-1:], n - pos.shape[0], axis=0)])
    return pos, None


#: Every file ``optimize`` writes into ``--out`` (the files it owns there).
_OWNED = (
    *(f"{stem}.{fmt}" for stem in ("command", "baseline") for fmt in _FORMATS),
    "input_400hz.csv",
    "predicted.csv",
    "stage1.npz",
    "summary.json",
    "contour.png",
    "deviation.png",
    _CHECKPOINT,
)


def _write(out: Path, res: Any, fmt: str, drawing: str, contour: int, sizing: dict[str, Any],
           networks: Any, keep: tuple[str, ...]) -> None:  # fmt: skip
    """Write the results into ``out`` whole: only this run's files are left of the `_OWNED`.

    The files are written into a temporary folder inside ``out``, then moved in one by one
    (``summary.json`` last); then the owned files this run did not write (an earlier run's
    ``predicted.csv``, a command file of another ``--format``, a stage-2 checkpoint after
    ``--stage 1``) are removed. Files of others in ``out`` are never touched; a failure
    before the move leaves ``out`` as it was. ``keep`` names the owned files this run
    wrote straight into ``out`` (its stage-2 checkpoint).
    """
    import os
    import shutil
    import tempfile

    tmp = Path(tempfile.mkdtemp(prefix=".optimize-", dir=out))
    try:
        summary = _write_files(tmp, res, fmt, drawing, contour, sizing, networks)
        written = sorted(p.name for p in tmp.iterdir())
        for name in sorted(written, key=lambda n: n == "summary.json"):
            os.replace(tmp / name, out / name)
        for name in set(_OWNED) - set(written) - set(keep):
            (out / name).unlink(missing_ok=True)
    except OSError as exc:
        fail(f"cannot write the results into {out}: {exc}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if summary["warning"]:
        console.print(f"[yellow]warning:[/] {summary['warning']}", highlight=False)
    pred = summary.get("predicted")
    extra = ""
    if pred:
        extra = f", predicted L2 {pred['l2'] * 1e6:.2f} µm, L∞ {pred['linf'] * 1e6:.2f} µm"
    console.print(
        f"T = {res.duration:.4f} s, M = {res.m} at 400 Hz{extra}; wrote {out}", highlight=False
    )


def _write_files(out: Path, res: Any, fmt: str, drawing: str, contour: int,
                 sizing: dict[str, Any], networks: Any) -> dict[str, Any]:  # fmt: skip
    """Write every result file of ``res`` into the (empty) folder ``out``; the summary."""
    from microfab.io.atomic import atomic_write_json
    from microfab.io.trace import write_columns
    from microfab.optimize.command import LEAD
    from microfab.optimize.pipeline import MODEL_RATE_HZ, RUN_RATE_HZ, training_warning
    from microfab.report.canvas import save_figure
    from microfab.report.reference import plot_contour, plot_deviation

    cmd = res.command
    q = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    base, no_base = _baseline(res)
    commands: dict[str, Any] = {
        "optimised": {"file": f"command.{fmt}", "t0_sample": LEAD * q, "lead": LEAD}
    }
    if base is not None:
        commands["baseline"] = {
            "file": f"baseline.{fmt}", "t0_sample": 0, "lead": 0,
            "what": "the time-optimal command under Table I stretched to T (seed 002 §V: "
            "the stronger baseline of the reference job), held to t_M",
        }  # fmt: skip
    try:
        write_columns(out / f"command.{fmt}", _command_columns(cmd.position), unit="m")
        if base is not None:
            write_columns(out / f"baseline.{fmt}", _command_columns(base), unit="m")
        r_cols = {"time": res.t[:-1], "x": res.r[:, 0], "y": res.r[:, 1]}
        write_columns(out / "input_400hz.csv", r_cols, unit="m")
        if res.predicted is not None:
            p, tg = res.predicted, res.target[1:]
            cols = {"time": res.t[1:], "x": p[:, 0], "y": p[:, 1],
                    "target_x": tg[:, 0], "target_y": tg[:, 1]}  # fmt: skip
            write_columns(out / "predicted.csv", cols, unit="m")
        res.stage1.save(out / "stage1.npz")
        summary = {
            "drawing": drawing,
            "contour": contour,
            "sizing": sizing,
            # what `stage score` checks the drawing it reads again against
            "path_length_m": res.problem.length,
            "drawing_sha256": _file_digest(drawing),
            "rate_hz": RUN_RATE_HZ,
            "commands": commands,
            "a_max": res.problem.a_max,
            "tolerance_m": res.problem.tolerance_m,
            "duration_s": res.duration,
            "m": res.m,
            "stage1": res.stage1.summary(),
            "stage2": None if res.stage2 is None else res.stage2.summary(),
            "wall_s": res.wall_s,
            "command_samples": int(cmd.position.shape[0]),
            "warning": "; ".join(
                w
                for w in (
                    res.warning,  # stage 1 alone predicted worse than the stretched baseline
                    no_base,
                    None if networks is None else training_warning(networks, res.problem.a_max),
                )
                if w
            )
            or None,
        }
        if res.predicted is not None:
            from microfab.optimize.metrics import DeviationNorms

            summary["predicted"] = DeviationNorms.of(res.problem.path, res.predicted).as_dict()
        save_figure(plot_contour(res), out / "contour.png")
        save_figure(plot_deviation(res), out / "deviation.png")
        atomic_write_json(out / "summary.json", summary)
    except (OSError, ValueError) as exc:
        fail(f"cannot write the results: {exc}")
    return summary
