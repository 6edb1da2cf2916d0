"""``microfab nanomanipulator analyze``: seed 001 metrics and figures from a measured trace."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_option, check_outputs, console, fail, print_table
from microfab.io.lock import hold_for_command

__all__ = ["nanomanipulator_app"]

nanomanipulator_app = typer.Typer(
    no_args_is_help=True, help="The seed 001 XY nanomanipulator on hardware."
)


@nanomanipulator_app.command("analyze")
def analyze_cmd(
    trace: Annotated[
        Path,
        typer.Argument(
            help="Measured job (.csv, .mat, .h5): time [s], ref_x, ref_y, x, y [mm], laser (0/1)."
        ),
    ],
    job: Annotated[
        Path | None, typer.Option(help="Job file whose [pattern] section the trace ran.")
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Write report.html and its figures here.")
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the metrics as JSON here.")
    ] = None,
    period: Annotated[float | None, typer.Option(help="Time per circle [s] (default 1).")] = None,
    circles: Annotated[int | None, typer.Option(help="Circles in the field (default 4).")] = None,
    diameter_mm: Annotated[
        float | None, typer.Option(help="Circle diameter [mm] (default 0.15).")
    ] = None,
    field_mm: Annotated[float | None, typer.Option(help="Field side [mm] (default 0.5).")] = None,
    periods: Annotated[int | None, typer.Option(help="Periods per circle (default 6).")] = None,
    pause_s: Annotated[
        float | None, typer.Option(help="Pause before each circle [s] (default 0.2).")
    ] = None,
    move_s: Annotated[
        float | None, typer.Option(help="Move to each circle [s] (default 0.3).")
    ] = None,
    ramp_s: Annotated[
        float | None, typer.Option(help="Spin-up and spin-down [s] (default 0.25).")
    ] = None,
    sample_rate_hz: Annotated[
        float | None, typer.Option(help="The pattern's sample rate [Hz] (default the twin's).")
    ] = None,
) -> None:
    """Seed 001 §4.2 metrics of a measured job: table, and with --out a report, --json a file.

    The trace must follow the pattern's reference sample by sample (four 0.15 mm circles
    in a 0.5 mm field by default); give the pattern the job ran with the options or --job.
    """
    check_outputs(
        folders={"--out": out}, files={"--json": json_path}, inputs={"TRACE": trace, "--job": job}
    )
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.io.atomic import atomic_write_json
    from microfab.measure.circle_trace import analyze_trace, pattern_from_job
    from microfab.report.circle_tracking import tracking_table, write_analysis
    from microfab.trajectory.circle_pattern import PatternConfig

    fields = {
        "period_s": ("--period", period, "s"),
        "n_circles": ("--circles", circles, "circles"),
        "diameter_mm": ("--diameter-mm", diameter_mm, "mm"),
        "field_mm": ("--field-mm", field_mm, "mm"),
        "periods": ("--periods", periods, "periods"),
        "pause_s": ("--pause-s", pause_s, "s"),
        "move_s": ("--move-s", move_s, "s"),
        "ramp_s": ("--ramp-s", ramp_s, "s"),
    }
    given = {k: v for k, (_, v, _) in fields.items() if v is not None}
    for name, value, unit in fields.values():
        check_option(name, value, unit)
    check_option("--sample-rate-hz", sample_rate_hz, "Hz")
    if job is not None and given:
        opts = ", ".join(fields[k][0] for k in given)
        fail(f"give the pattern either by --job or by options, not both (got --job and {opts})")
    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a directory for the report")
    if json_path is not None and json_path.is_dir():
        fail(f"--json {json_path} is a directory; give a file name")
    try:
        config = pattern_from_job(job) if job is not None else PatternConfig(**given)
        analysis = analyze_trace(trace, config, sample_rate_hz=sample_rate_hz)
        report = None
        if out is not None:
            report = write_analysis(analysis, out)
        if json_path is not None:
            atomic_write_json(json_path, analysis.summary())
    except (OSError, ValueError) as exc:
        fail(str(exc))
    print_table(tracking_table(analysis.metrics))
    if report is not None:
        console.print(f"report: {report}", highlight=False)
    if json_path is not None:
        console.print(f"metrics: {json_path}", highlight=False)
