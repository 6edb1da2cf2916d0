"""``microfab calibrate galvo|nanomanipulator|laser|xy-stage``: refit twins to seed numbers."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._calibrate_kit import (
    BudgetOption,
    ConflictBudgetOption,
    FreshOption,
    JsonOption,
    OutOption,
    SeedOption,
    WorkersOption,
)
from microfab.cli._kit import check_outputs, console, fail, renamed, status
from microfab.cli._options import given, integer, number
from microfab.experiments.seed002_stage.keys import MAX_TOTAL_S, RUNS_SEED, RUNS_TOTAL_S

__all__ = ["calibrate_app"]

calibrate_app = typer.Typer(no_args_is_help=True, help="Calibrate digital twins.")


@calibrate_app.command("galvo")
def calibrate_galvo_cmd(
    write: Annotated[
        Path | None, typer.Option(help="Write the calibrated twin data file here.")
    ] = None,
    json_out: JsonOption = None,
    out: OutOption = None,
    fresh: FreshOption = False,
    budget: BudgetOption = None,
    conflict_budget: ConflictBudgetOption = None,
    seed: SeedOption = 0,
    workers: WorkersOption = 1,
) -> None:
    """Fit the galvo twin (rigid-body pole, gain ratio, noise per axis) to seed 000 Table 1.

    Fit: the feedback RMS and PP at 100, 200, 400 features/s and the ILC RMS at 100 per
    axis; the other ILC numbers are held back as checks. Prints the per-target table.
    """
    from microfab.cli._calibrate_kit import run_calibration
    from microfab.machines.galvo.calibration import DEFAULT_BUDGET, problem, write_twin

    run_calibration(
        problem(),
        title="seed 000 galvo twin",
        budget=budget or DEFAULT_BUDGET,
        seed=seed,
        workers=workers,
        out=out,
        fresh=fresh,
        json_out=json_out,
        write=write,
        write_twin=lambda r, p: write_twin(r, p),
        conflict_budget=conflict_budget,
    )


@calibrate_app.command("nanomanipulator")
def calibrate_nanomanipulator_cmd(
    write: Annotated[
        Path | None, typer.Option(help="Write the calibrated twin data file here.")
    ] = None,
    job: Annotated[
        Path | None, typer.Option(help="Fit on this nanomanipulator-msl job (default: seed's).")
    ] = None,
    contour_fit: Annotated[
        bool,
        typer.Option(
            "--contour-fit",
            help="Diagnostic: fit the contour RMS too and report its conflict (no --write).",
        ),
    ] = False,
    json_out: JsonOption = None,
    out: OutOption = None,
    fresh: FreshOption = False,
    budget: BudgetOption = None,
    conflict_budget: ConflictBudgetOption = None,
    seed: SeedOption = 0,
    workers: WorkersOption = 1,
) -> None:
    """Fit the nanomanipulator twin jointly to seed 001 §4.2's axial RMS (x, y).

    The free parameters are the sensor noise per axis, its colour and the disturbance
    bound per axis; the contour RMS (769.5 nm) and the gate period (3-4) are held back as
    checks.
    """
    if contour_fit and write is not None:
        fail("--contour-fit is a diagnostic (the contour RMS fitted, not checked): no --write")
    check_outputs(
        files={"--write": write, "--json": json_out}, folders={"--out": out}, inputs={"--job": job}
    )
    from microfab.cli._calibrate_kit import run_calibration
    from microfab.machines.nanomanipulator.calibration import (
        DEFAULT_BUDGET,
        contour_finding,
        problem,
        write_twin,
    )
    from microfab.machines.nanomanipulator.job import JobConfig

    config = None
    if job is not None:
        from microfab.experiments.catalog import load_job

        try:
            loaded = load_job(job)
        except (OSError, ValueError) as exc:
            fail(str(exc))
        if not isinstance(loaded.config, JobConfig):
            fail(f"{job}: not a nanomanipulator-msl job (kind {loaded.kind.name!r})")
        config = loaded.config
    try:
        prob = problem(config, contour_fit=contour_fit)
    except ValueError as exc:
        fail(str(exc))
    src = None if config is None else config.twin.params_file
    result = run_calibration(
        prob,
        title="seed 001 nanomanipulator twin",
        budget=budget or DEFAULT_BUDGET,
        seed=seed,
        workers=workers,
        out=out,
        fresh=fresh,
        json_out=json_out,
        write=write,
        write_twin=lambda r, p: write_twin(r, p, source=src),
        inputs={"--job": job},
        conflict_budget=conflict_budget,
    )
    finding = contour_finding(result)
    if finding is not None:
        console.print(f"finding: {finding}")


@calibrate_app.command("laser")
def calibrate_laser_cmd(
    write: Annotated[
        Path | None, typer.Option(help="Write the calibrated stage twin data file here.")
    ] = None,
    json_out: JsonOption = None,
    out: OutOption = None,
    fresh: FreshOption = False,
    budget: BudgetOption = None,
    conflict_budget: ConflictBudgetOption = None,
    seed: SeedOption = 0,
    workers: WorkersOption = 1,
) -> None:
    """Fit the seed 004 stage twin jointly to Fig. 3: the 0.8 µm peak and >= 95 % within 0.5 µm.

    The free parameters are the friction's magnitude and shape and the encoder noise; the
    RMS force against Table I's 3 N is held back as a check.
    """
    from microfab.cli._calibrate_kit import run_calibration
    from microfab.machines.laser_stage.calibration import DEFAULT_BUDGET, problem, write_twin

    run_calibration(
        problem(),
        title="seed 004 stage twin",
        budget=budget or DEFAULT_BUDGET,
        seed=seed,
        workers=workers,
        out=out,
        fresh=fresh,
        json_out=json_out,
        write=write,
        write_twin=lambda r, p: write_twin(r, p),
        conflict_budget=conflict_budget,
    )


@calibrate_app.command("xy-stage")
def calibrate_xy_stage_cmd(
    ctx: typer.Context,
    write: Annotated[
        Path | None,
        typer.Option(help="Write an XY stage twin data file with the fitted magnitudes here."),
    ] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write the fit (and checks) as JSON here.")
    ] = None,
    duration: Annotated[
        float, number("--duration", key=RUNS_TOTAL_S, help="Random-run data of the fit.")
    ] = 600.0,
    search: Annotated[
        float,
        number(
            "--search",
            help="Shorter data to search on first (at most --duration).",
            unit="s",
            low=0.0,
            low_open=True,
            high=MAX_TOTAL_S,
        ),
    ] = 120.0,
    seed: Annotated[
        int, integer("--seed", key=RUNS_SEED, help="Seed of the runs and the noise.")
    ] = 0,
    check: Annotated[
        bool, typer.Option(help="Then measure the checks (order scan 2..8, time constant).")
    ] = False,
) -> None:
    """Fit the XY stage twin's friction + cogging per axis to seed 002 Table II column 1."""
    check_outputs(files={"--write": write, "--json": json_out})
    if search > duration:
        default = "" if given(ctx, "search") else " (its default)"
        fail(
            f"--search {search:g} s{default} is longer than --duration {duration:g} s: the "
            "search runs on a shorter data set"
        )
    from microfab.machines.xy_stage.calibration import (
        CalibrationSettings,
        fit_scales,
        force_budget,
        scaled_changes,
        write_calibration_json,
        write_twin_file,
    )
    from microfab.machines.xy_stage.identify import linear_checks
    from microfab.plants.xy_stage_params import load_params

    try:
        settings = CalibrationSettings(total_s=duration, search_s=search, seed=seed)
    except ValueError as exc:
        fail(renamed(str(exc), {"total_s": "--duration", "search_s": "--search"}))
    try:
        with status("fitting the friction and cogging scales") as show:
            fit = fit_scales(
                settings,
                progress=lambda k, s, g: show(
                    f"run {k}: scales {s[0]:.4g} / {s[1]:.4g} -> sigma {g[0] * 1e6:.1f} / "
                    f"{g[1] * 1e6:.1f} µm"
                ),
            )
            changes = scaled_changes(fit.scales)
            checks = None
            if check:  # before anything is printed: a refusal here stays one line
                show("checks: order scan and time constants")
                try:
                    checks = linear_checks(fit.total_s, seed=seed, changes=changes)
                except ValueError as exc:
                    raise ValueError(
                        f"--check on {fit.total_s:g} s of data: {exc}; give a longer --duration"
                    ) from exc
    except ValueError as exc:
        fail(str(exc))
    capped = [ax for ax, c in zip("xy", fit.capped, strict=True) if c]
    console.print(
        f"scales x {fit.scales[0]:.4g}, y {fit.scales[1]:.4g}: linear sigma "
        f"{fit.sigma_m[0] * 1e6:.1f} / {fit.sigma_m[1] * 1e6:.1f} µm on {fit.total_s:g} s "
        "(seed 48.0 / 156.3)" + (f"; capped: {', '.join(capped)}" if capped else "")
    )
    for b in force_budget(load_params().with_(**dict(changes))):
        console.print(b.line())
    if checks is not None:
        d = checks.to_dict()
        console.print(
            f"checks: sigma(y-u) {d['tracking_sigma_um'][0]:.1f} / "
            f"{d['tracking_sigma_um'][1]:.1f} µm; slowest time constant "
            f"{d['slowest_time_constant_ms']:.1f} ms (seed reading 20 ms)"
        )
        for n, row in d["order_scan_sigma_um"].items():
            console.print(f"order {n}: sigma {row[0]:.1f} / {row[1]:.1f} µm")
    if write is not None:
        write_twin_file(fit, write)
        console.print(f"wrote {write}")
    if json_out is not None:
        write_calibration_json(fit, json_out, checks=checks)
        console.print(f"wrote {json_out}")
