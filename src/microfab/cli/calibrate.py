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
from microfab.cli._kit import check_outputs, console, fail, renamed
from microfab.cli._options import integer, number
from microfab.experiments.seed002_stage.keys import MAX_TOTAL_S, RUNS_SEED, RUNS_TOTAL_S

#: Most hidden units of the networks' proxy (assumed: ten times its 400; the read-out's
#: Gram matrix grows as (201 + hidden)^2 doubles, 140 MB at 4000).
MAX_PROXY_HIDDEN = 4000
#: Most subsampling offsets: the 25 samples of 10 kHz in one 400 Hz step
#: (`microfab.machines.xy_stage.proxy.ProxySettings.offsets`).
MAX_PROXY_OFFSETS = 25

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
        write_twin=write_twin,
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
        write_twin=write_twin,
        conflict_budget=conflict_budget,
    )


@calibrate_app.command("xy-stage")
def calibrate_xy_stage_cmd(
    write: Annotated[
        Path | None, typer.Option(help="Write the calibrated XY stage twin data file here.")
    ] = None,
    duration: Annotated[
        float,
        number(
            "--duration",
            key=RUNS_TOTAL_S,
            help="Random runs of the linear model per evaluation (seed §III-C.1: 600 s).",
        ),
    ] = 60.0,
    ann_duration: Annotated[
        float,
        number(
            "--ann-duration",
            help="The networks' data per evaluation (random runs and shapes, split 80/20 by "
            "whole runs; it must leave a validation run: 10 s does with --runs-seed 0).",
            unit="s",
            low=0.0,
            low_open=True,
            high=MAX_TOTAL_S,
        ),
    ] = 60.0,
    runs_seed: Annotated[
        int, integer("--runs-seed", key=RUNS_SEED, help="Seed of the runs and the twin's noise.")
    ] = 0,
    proxy_hidden: Annotated[
        int,
        integer(
            "--proxy-hidden",
            help="Random hidden units of the networks' σ proxy (xy_stage.proxy: 400).",
            unit="units",
            low=1,
            high=MAX_PROXY_HIDDEN,
        ),
    ] = 400,
    proxy_offsets: Annotated[
        int,
        integer(
            "--proxy-offsets",
            help="Subsampling offsets of the proxy's training windows (xy_stage.proxy: 2).",
            low=1,
            high=MAX_PROXY_OFFSETS,
        ),
    ] = 2,
    json_out: JsonOption = None,
    out: OutOption = None,
    fresh: FreshOption = False,
    budget: BudgetOption = None,
    conflict_budget: ConflictBudgetOption = None,
    seed: SeedOption = 0,
    workers: WorkersOption = 1,
) -> None:
    """Fit the XY stage twin's assumed magnitudes jointly to seed 002 Table II.

    Free: Coulomb friction, cogging and the built-in loop's acceleration feedforward per
    axis, the y cable's link ripple and stiffness, the carriage resonance and the y -> x
    coupling. Fit: the linear model's σ and μ per axis on its training data and the
    networks' validation σ per axis, through a random-feature proxy (training the networks
    per evaluation is far too slow); the slowest time constant (about 20 ms, §III-B) is
    held back as a check. Each evaluation plays
    --duration s of random runs and --ann-duration s of the networks' data on the twin.
    """
    # before the data are made: a refusal stays one line and writes nothing
    check_outputs(files={"--write": write, "--json": json_out}, folders={"--out": out})
    from microfab.cli._calibrate_kit import run_calibration
    from microfab.machines.xy_stage.calibration import force_budget
    from microfab.machines.xy_stage.calibration_core import (
        DEFAULT_BUDGET,
        XYCalData,
        changes_of,
        problem,
        write_twin,
    )
    from microfab.machines.xy_stage.proxy import ProxySettings
    from microfab.plants.xy_stage_params import load_params

    try:
        data = XYCalData(
            linear_s=duration,
            ann_s=ann_duration,
            seed=runs_seed,
            proxy=ProxySettings(hidden=proxy_hidden, offsets=proxy_offsets),
        )
        prob = problem(data)  # the networks' runs made (a second or two), checked
    except ValueError as exc:
        fail(renamed(str(exc), {"ann_s": "--ann-duration", "linear_s": "--duration"}))
    result = run_calibration(
        prob,
        title="seed 002 XY stage twin",
        budget=budget or DEFAULT_BUDGET,
        seed=seed,
        workers=workers,
        out=out,
        fresh=fresh,
        json_out=json_out,
        write=write,
        write_twin=write_twin,
        conflict_budget=conflict_budget,
    )
    # plausibility of the answer's forces (a real stage of this size: friction
    # coefficient about 0.01-0.1, cogging a few % of the peak force)
    fitted = load_params().with_(**dict(changes_of(result.values)))
    console.print("forces at the answer:")
    for b in force_budget(fitted):
        console.print(b.line())
