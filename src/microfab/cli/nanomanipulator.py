"""``microfab nanomanipulator analyze``: seed 001 metrics and figures from a measured trace."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_outputs, console, fail, print_table
from microfab.cli._options import given, integer, number, refuse_unused
from microfab.experiments.seed001_nanomanipulator.keys import (
    PATTERN_DIAMETER_MM,
    PATTERN_FIELD_MM,
    PATTERN_MOVE_S,
    PATTERN_N_CIRCLES,
    PATTERN_PAUSE_S,
    PATTERN_PERIOD_S,
    PATTERN_PERIODS,
    PATTERN_RAMP_S,
)
from microfab.io.lock import hold_for_command

__all__ = ["SAMPLE_RATE_RANGE_HZ", "nanomanipulator_app"]

#: Sample rates a trace of the pattern may have, Hz (assumed: the seed gives no control
#: rate and the twin assumes 10 kHz; below 100 Hz a loop cannot follow the 50 Hz modes of
#: seed 001 eq. (9), above 1 MHz is past any capacitive-sensor loop of such a stage).
SAMPLE_RATE_RANGE_HZ = (100.0, 1e6)

#: The options that give the pattern, by parameter name, with the job key each one sets.
_PATTERN_OPTIONS = {
    "period": "period_s",
    "circles": "n_circles",
    "diameter_mm": "diameter_mm",
    "field_mm": "field_mm",
    "periods": "periods",
    "pause_s": "pause_s",
    "move_s": "move_s",
    "ramp_s": "ramp_s",
}

nanomanipulator_app = typer.Typer(
    no_args_is_help=True, help="The seed 001 XY nanomanipulator on hardware."
)


@nanomanipulator_app.command("analyze")
def analyze_cmd(
    ctx: typer.Context,
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
    period: Annotated[
        float | None,
        number(help="Time per circle (default 1; not with --job).", key=PATTERN_PERIOD_S),
    ] = None,
    circles: Annotated[
        int | None,
        integer(help="Circles in the field (default 4; not with --job).", key=PATTERN_N_CIRCLES),
    ] = None,
    diameter_mm: Annotated[
        float | None,
        number(help="Circle diameter (default 0.15; not with --job).", key=PATTERN_DIAMETER_MM),
    ] = None,
    field_mm: Annotated[
        float | None,
        number(
            help="Field side, not less than the diameter (default 0.5; not with --job).",
            key=PATTERN_FIELD_MM,
        ),
    ] = None,
    periods: Annotated[
        int | None,
        integer(help="Periods per circle (default 6; not with --job).", key=PATTERN_PERIODS),
    ] = None,
    pause_s: Annotated[
        float | None,
        number(help="Pause before each circle (default 0.2; not with --job).", key=PATTERN_PAUSE_S),
    ] = None,
    move_s: Annotated[
        float | None,
        number(help="Move to each circle (default 0.3; not with --job).", key=PATTERN_MOVE_S),
    ] = None,
    ramp_s: Annotated[
        float | None,
        number(help="Spin-up and spin-down (default 0.25; not with --job).", key=PATTERN_RAMP_S),
    ] = None,
    sample_rate_hz: Annotated[
        float | None,
        number(
            help="The pattern's sample rate (default the twin's); a period is a whole "
            "number of samples.",
            unit="Hz",
            low=SAMPLE_RATE_RANGE_HZ[0],
            high=SAMPLE_RATE_RANGE_HZ[1],
        ),
    ] = None,
) -> None:
    """Seed 001 §4.2 metrics of a measured job: table, and with --out a report, --json a file.

    The trace must follow the pattern's reference sample by sample (four 0.15 mm circles
    in a 0.5 mm field by default); give the pattern the job ran with the options or --job.
    """
    if job is not None:
        why = "with --job (its [pattern] is the pattern: by --job or by options, not both)"
        refuse_unused(ctx, list(_PATTERN_OPTIONS), why)
    typed = {"period": period, "circles": circles, "diameter_mm": diameter_mm,
             "field_mm": field_mm, "periods": periods, "pause_s": pause_s, "move_s": move_s,
             "ramp_s": ramp_s}  # fmt: skip
    pattern = {
        key: typed[name] for name, key in _PATTERN_OPTIONS.items() if typed[name] is not None
    }
    _check_field(diameter_mm=diameter_mm, field_mm=field_mm)
    check_outputs(
        folders={"--out": out}, files={"--json": json_path}, inputs={"TRACE": trace, "--job": job}
    )
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.io.atomic import atomic_write_json
    from microfab.measure.circle_trace import analyze_trace, pattern_from_job, twin_sample_rate_hz
    from microfab.report.circle_tracking import tracking_table, write_analysis
    from microfab.trajectory.circle_pattern import PatternConfig

    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a directory for the report")
    if json_path is not None and json_path.is_dir():
        fail(f"--json {json_path} is a directory; give a file name")
    try:
        config = pattern_from_job(job) if job is not None else PatternConfig(**pattern)
    except (OSError, ValueError) as exc:
        fail(str(exc))
    rate = twin_sample_rate_hz() if sample_rate_hz is None else sample_rate_hz
    period_from = "--period" if job is None else f"{job} [pattern] period_s"
    rate_from = "--sample-rate-hz" if given(ctx, "sample_rate_hz") else "the twin's sample rate"
    _check_whole_period(config.period_s, rate, period_from, rate_from)
    try:
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


def _check_field(*, diameter_mm: float | None, field_mm: float | None) -> None:
    """Refuse a field narrower than its circles (one line, exit 2).

    Parameters
    ----------
    diameter_mm, field_mm : float or None
        ``--diameter-mm`` and ``--field-mm``, mm (``None``: not given, the default).
    """
    d = PATTERN_DIAMETER_MM.default if diameter_mm is None else diameter_mm
    f = PATTERN_FIELD_MM.default if field_mm is None else field_mm
    if f < d:
        fail(
            f"--field-mm {f:g} mm is smaller than --diameter-mm {d:g} mm: the circles must "
            "fit in the field"
        )


def _check_whole_period(period_s: float, rate_hz: float, period_from: str, rate_from: str) -> None:
    """Refuse a period that is not a whole number of samples at the sample rate.

    The pattern's learning memory holds one value per sample, so a period must be a whole
    number of samples, at least 2 (`microfab.core.signals.period_samples` decides).

    Parameters
    ----------
    period_s : float
        The pattern's period, s.
    rate_hz : float
        The sample rate, Hz.
    period_from, rate_from : str
        Where each came from, for the message (``"--period"``, ``"--sample-rate-hz"``).
    """
    from microfab.core.signals import period_samples

    try:
        period_samples(period_s, 1.0 / rate_hz)
    except ValueError:
        fail(
            f"{period_from} {period_s:g} s is {period_s * rate_hz:.6g} samples at {rate_from} "
            f"{rate_hz:g} Hz: give a period of a whole number of samples, at least 2"
        )
