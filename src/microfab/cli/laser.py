"""``microfab laser export|analyze``: the seed 004 stage on hardware, through files."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import check_outputs, console, fail, print_table
from microfab.cli._options import integer, number
from microfab.experiments.seed004_laser.keys import CONTOUR
from microfab.io.lock import hold_for_command

__all__ = ["MAX_REFERENCE_TOL_UM", "MIN_REFERENCE_TOL_UM", "laser_app"]

#: Largest distance of the reference to the drawing accepted, µm (assumed: the reference
#: is computed from the drawing and keeps to it within the spline's rounding, nm to a
#: few µm on seed 004's 30 µm circle; a millimetre is another drawing, or another unit).
MAX_REFERENCE_TOL_UM = 1000.0
#: Smallest, µm: the stage's position resolution, 10 nm (seed 004 Table I, as
#: ``data/lmw_stage.toml`` [encoder]); a finer tolerance says nothing about the machine.
MIN_REFERENCE_TOL_UM = 0.01

laser_app = typer.Typer(no_args_is_help=True, help="The seed 004 laser micromachining stage.")


@laser_app.command("analyze")
def analyze_cmd(
    trace: Annotated[
        Path,
        typer.Argument(
            help="Measured run (.csv, .mat, .h5): time [s], ref_x, ref_y, x, y [m]; "
            "optional current_x, current_y [A]."
        ),
    ],
    drawing: Annotated[
        str, typer.Option(help="The drawing the reference came from (file or shape source).")
    ],
    contour: Annotated[
        int, integer(help="Which closed contour of the drawing, from 0.", key=CONTOUR)
    ] = 0,
    reference_tol_um: Annotated[
        float,
        number(
            help="Largest distance of the reference to the drawing.",
            unit="µm",
            low=MIN_REFERENCE_TOL_UM,
            high=MAX_REFERENCE_TOL_UM,
        ),
    ] = 1.0,
    out: Annotated[
        Path | None, typer.Option(help="Write report.html and its figures here.")
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the figures as JSON here.")
    ] = None,
    replay: Annotated[
        bool,
        typer.Option(help="Run our controller on the recorded encoder; compare its current."),
    ] = False,
    job: Annotated[
        Path | None, typer.Option(help="The job whose [control] and [twin] the run used.")
    ] = None,
) -> None:
    """Axis and contour errors of a measured trace against the exact drawing (seed 004).

    With --replay the trace must also hold current_x, current_y (A) and, for an exact
    comparison, the exported reference derivatives ref_vx, ref_vy, ref_ax, ref_ay.
    """
    check_outputs(
        folders={"--out": out},
        files={"--json": json_path},
        inputs={"TRACE": trace, "--job": job, "--drawing": Path(drawing)},
    )
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.io.atomic import atomic_write_json
    from microfab.measure.contour_trace import analyze_trace
    from microfab.report.contour import analysis_table, write_analysis
    from microfab.trajectory.contour_laps import contour_path

    cfg = _laser_job(job) if job is not None else None  # before any work or output
    try:  # the drawing and its contour before the trace: a bad --contour reads nothing
        path = contour_path(drawing, contour)
    except (OSError, ValueError) as exc:
        msg = str(exc)
        fail(msg if drawing in msg else f"--drawing {drawing}: {msg}")
    measured = _measured_trace(trace, cfg)
    try:
        a = analyze_trace(measured, path, reference_tol_m=reference_tol_um * 1e-6)
    except (OSError, ValueError) as exc:
        fail(f"{trace}: {exc}")
    summary = a.summary()
    replayed = None
    if replay:
        from microfab.machines.laser_stage.files import replay_trace

        control = None if cfg is None else cfg.run.control
        twin = None if cfg is None else cfg.run.twin
        try:
            replayed = replay_trace(measured, control, twin)
        except (OSError, ValueError) as exc:
            fail(f"{trace}: {exc}")
        summary["replay"] = {
            "rms_difference_a": list(replayed.rms_difference_a),
            "max_difference_a": list(replayed.max_difference_a),
            "exact_derivatives": replayed.exact_derivatives,
        }
    print_table(analysis_table(a))
    if replayed is not None:
        rx, ry = (v * 1e3 for v in replayed.rms_difference_a)
        mx, my = (v * 1e3 for v in replayed.max_difference_a)
        how = "exported derivatives" if replayed.exact_derivatives else "differenced derivatives"
        console.print(
            f"replay ({how}): our current against the recorded one, RMS {rx:.4g} / {ry:.4g} "
            f"mA, max {mx:.4g} / {my:.4g} mA (x / y)"
        )
    if json_path is not None:
        atomic_write_json(json_path, summary)
        console.print(f"wrote {json_path}")
    if out is not None:
        console.print(f"report: {write_analysis(a, out, f'Measured trace {trace.name}')}")


def _measured_trace(path: Path, cfg: Any) -> Any:
    """The measured trace, checked against the stage it was recorded on (exits 2 otherwise).

    Its sample time must be the controller's (a time column in ms is 1000 times it), its
    positions in m, and it must last at least one period of the position loop's
    bandwidth: shorter, the errors are the loop's transient, not its tracking.
    """
    from microfab.io.trace import read_trace
    from microfab.machines.laser_stage import machine as laser_stage

    cs = laser_stage.ControlSettings() if cfg is None else cfg.run.control
    dt = laser_stage.stage().dt
    n_min = math.ceil(1.0 / (cs.bandwidth_hz * dt))
    try:
        tr = read_trace(path, min_samples=n_min)
    except (OSError, ValueError) as exc:
        msg = str(exc)
        fail(msg if str(path) in msg else f"{path}: {msg}")
    if abs(tr.dt - dt) > 1e-6 * dt:
        fail(
            f"{path}: sample time {tr.dt:g} s, but the stage's controller samples every "
            f"{dt:g} s; the time column must be in s, at the controller's rate"
        )
    if tr.unit not in ("", "m"):
        fail(f"{path}: unit {tr.unit!r}; the stage's positions are read in m")
    return tr


def _laser_job(path: Path) -> Any:
    """The checked config of a laser-micromachining job file (exits 2 otherwise)."""
    from microfab.experiments.catalog import load_job
    from microfab.experiments.seed004_laser.job import LaserJob

    try:
        loaded = load_job(path)
    except (OSError, ValueError) as exc:
        fail(str(exc))
    if not isinstance(loaded.config, LaserJob):
        fail(f"{path}: not a laser-micromachining job (kind {loaded.kind.name!r})")
    return loaded.config


@laser_app.command("export")
def export_cmd(
    job: Annotated[Path, typer.Argument(help="A laser-micromachining job file.")],
    out: Annotated[Path, typer.Option(help="Folder for reference.csv and controller.json.")],
) -> None:
    """Write a job's reference and discrete controller for a real-time target (seed 004)."""
    check_outputs(folders={"--out": out}, inputs={"JOB": job})
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.machines.laser_stage.files import export_job

    cfg = _laser_job(job)
    ref, spec = export_job(cfg, out)
    console.print(f"wrote {ref} and {spec}")
