"""``microfab droplet sweep|calibrate|sensitivity``: the droplet studies over many points.

Each runs the jet model at many points, not one: the breakup-time sweep over
concentrations and voltages (``sweep``, the seed's Fig. 4), the fit of the ink's
relaxation law to the seed's breakups (``calibrate``, `microfab.cli._calibrate_kit`) and
the one-at-a-time change of each assumed fluid value (``sensitivity``). Their points are
kept in the output folder as they finish, so a rerun resumes; ``sweep`` and
``sensitivity`` run them on local Dask workers (``--jobs``). Registered on the ``droplet``
group (`cli/droplet.py`, which holds the single-drop commands, the options they share and
the group) when imported: `cli/__init__.py` imports this module.

Every refusal is one ``error:`` line, exit code 2; a point that fails ends the command
with exit code 1 once the others are written.
"""

from __future__ import annotations

import json
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
from microfab.cli._kit import (
    check_output_path,
    check_outputs,
    console,
    fail,
    progress,
)
from microfab.cli._options import integer, number, refuse_unused
from microfab.cli.droplet import (
    MAX_DURATION_US,
    ModelOpt,
    _check_each,
    _floats,
    droplet_app,
)
from microfab.experiments.seed003_inkjet.keys import (
    CONCENTRATION,
    DURATION,
    VOLTAGE,
    VOLTAGE_CONCENTRATION,
    WORKERS,
)
from microfab.io.atomic import atomic_write_text
from microfab.io.lock import hold_for_command
from microfab.process.inkjet.fluids import DEFAULT_JET_MODEL

__all__ = ["calibrate_cmd", "sensitivity_cmd", "sweep_cmd"]


@droplet_app.command("sweep")
def sweep_cmd(
    ctx: typer.Context,
    concentrations: Annotated[
        str, typer.Option(help="NaAlg concentrations at 50 V, % w/v, comma-separated.")
    ] = "0.15,0.2,0.25,1,1.5,2",
    voltages: Annotated[
        str, typer.Option(help="Voltages of the voltage series, V, comma-separated ('' = none).")
    ] = "40,45,50,55,60,65,70",
    voltage_concentration: Annotated[
        float,
        number(
            help="Concentration of the voltage series (needs --voltages).",
            key=VOLTAGE_CONCENTRATION,
        ),
    ] = 1.0,
    duration: Annotated[float, number(help="Simulated time per point.", key=DURATION)] = 400.0,
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/sweep"),
    jobs: Annotated[
        int,
        integer(
            "--jobs",
            "--workers",
            help="Points simulated side by side (local Dask worker processes; not with "
            "--scheduler).",
            key=WORKERS,
        ),
    ] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Run on this Dask scheduler (tcp://host:8786) instead."),
    ] = None,
    model: ModelOpt = DEFAULT_JET_MODEL,
) -> None:
    """Breakup time against concentration (the seed's Fig. 4) and the 40-70 V trend.

    Finished points are kept in OUT/sweep/ as they come back; running the same sweep
    again resumes. microfab run examples/droplet_sweep.toml runs the same sweep as a
    job and writes a report with the seed's numbers beside ours.
    """
    cs = _floats(concentrations, "concentrations")
    vs = _floats(voltages, "voltages") if voltages.strip() else []
    _check_each("--concentrations", cs, CONCENTRATION)
    _check_each("--voltages", vs, VOLTAGE)
    if not vs:
        refuse_unused(ctx, ["voltage_concentration"], "with --voltages '' (no voltage series)")
    if scheduler is not None:
        refuse_unused(ctx, ["jobs"], "with --scheduler (the scheduler's workers run the points)")
    check_output_path("--out", out, kind="folder")
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.experiments.seed003_inkjet.paper import SEED_BREAKUP
    from microfab.machines.printhead.machine import DropletSettings, droplet_sweep, sweep_points
    from microfab.process.inkjet.fluids import naalg
    from microfab.report.canvas import save_figure
    from microfab.report.inkjet import fig_sweep

    try:
        for c in {*cs, voltage_concentration}:
            naalg(c)
        points = sweep_points(cs, vs, voltage_concentration_pct=voltage_concentration)
        with progress() as bar:
            task = bar.add_task("droplet sweep", total=len(points))
            res = droplet_sweep(
                points,
                settings=DropletSettings(duration_s=duration / 1e6, model=model),
                results_dir=out / "sweep",
                progress=lambda n, total, p, ok: bar.update(
                    task,
                    completed=n,
                    description=f"{'done' if ok else 'FAILED'} {p.concentration_pct:g} %, "
                    f"{p.voltage_v:g} V",
                ),
                workers=jobs,
                scheduler=scheduler,
                raise_on_failure=False,
            )
            bar.update(task, completed=len(points))
    except (OSError, ValueError) as exc:
        fail(str(exc))
    rows = list(res.rows)
    atomic_write_text(out / "sweep.json", json.dumps({"rows": rows}, indent=2) + "\n")
    if rows:
        save_figure(fig_sweep(rows, seed_points=SEED_BREAKUP), out / "breakup_time.png")
    keys = (
        "concentration_pct",
        "voltage_v",
        "breakup_time_s",
        "breakup_mode",
        "head_speed_m_s",
        "satellites",
    )
    console.print_json(json.dumps([{k: r.get(k) for k in keys} for r in rows], default=float))
    console.print(
        f"wrote {out / 'sweep.json'}" + (f" and {out / 'breakup_time.png'}" if rows else "")
    )
    if res.failed:
        first = res.failed[0]
        fail(
            f"{len(res.failed)} point(s) failed (running the sweep again retries them); first: "
            f"{first.point.concentration_pct:g} %, {first.point.voltage_v:g} V: {first.error}",
            code=1,
        )


@droplet_app.command("calibrate")
def calibrate_cmd(
    write: Annotated[
        Path | None,
        typer.Option(
            help="Property table (TOML) to fit on and to store the fitted law in (default: "
            "fit on the packaged table, write nothing)."
        ),
    ] = None,
    model: ModelOpt = DEFAULT_JET_MODEL,
    duration: Annotated[
        float,
        number(
            help="Simulated time per concentration (a shorter one only for a quick look: a "
            "later breakup counts as none).",
            unit="µs",
            low=10.0,
            high=MAX_DURATION_US,
        ),
    ] = 1000.0,
    mode_fit: Annotated[
        bool,
        typer.Option(
            "--mode-fit",
            help="Diagnostic: fit the pinch modes too and report their conflict (no --write).",
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
    """Fit the ink (λ_ref, exponent m, polymer share) to the seed's 95 µs and 230 µs breakups.

    On the calibration core: the 0.15 % and 1 % first-breakup times at 50 V are fitted; the
    pinch modes (front at 0.15 %, exit at 1 %), the rise over the six concentrations, a
    2 % breakup within 1 ms and every breakup outside the orifice are held back as checks.
    Each evaluation runs the six concentrations (3-13 s with the Eulerian model); --out
    keeps the evaluations so that a rerun resumes. A law belongs to the jet model it was
    fitted with: --write stores it as that model's law ([relaxation] or [relaxation_<model>]).
    """
    if mode_fit and write is not None:
        fail("--mode-fit is a diagnostic (the pinch modes fitted, not checked): no --write")
    check_outputs(files={"--write": write, "--json": json_out}, folders={"--out": out})
    if write is not None and not write.is_file():
        fail(f"--write {write}: no such property table (copy src/microfab/data/naalg.toml)")
    from microfab.cli._calibrate_kit import run_calibration
    from microfab.machines.printhead.calibration import DEFAULT_BUDGET, problem, write_twin

    try:  # a table that cannot take the result is refused before minutes of runs
        prob = problem(source=write, model=model, duration_s=duration * 1e-6, mode_fit=mode_fit)
    except (OSError, ValueError) as exc:
        fail(f"--write {exc}" if write is not None else str(exc))
    run_calibration(
        prob,
        title=f"seed 003 NaAlg ink ({model} jet model)",
        budget=budget or DEFAULT_BUDGET,
        seed=seed,
        workers=workers,
        out=out,
        fresh=fresh,
        json_out=json_out,
        write=write,
        write_twin=lambda r, p: write_twin(r, p, source=write, model=model),
        conflict_budget=conflict_budget,
    )


@droplet_app.command("sensitivity")
def sensitivity_cmd(
    concentrations: Annotated[
        str, typer.Option(help="NaAlg concentrations at 50 V, % w/v, comma-separated.")
    ] = "0.15,1,2",
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/sensitivity"),
    model: ModelOpt = DEFAULT_JET_MODEL,
    jobs: Annotated[int, integer("--jobs", help="Local Dask worker processes.", key=WORKERS)] = 1,
) -> None:
    """Breakup time when each assumed fluid value is changed, one at a time.

    The NaAlg values of data/naalg.toml are assumed or calibrated (no published
    measurement of this alginate was found); this shows which of them the breakup times
    hang on. Points are kept in OUT/points/ as they finish; a rerun resumes.
    """
    cs = _floats(concentrations, "concentrations")
    _check_each("--concentrations", cs, CONCENTRATION)
    check_output_path("--out", out, kind="folder")
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.machines.printhead.machine import DropletSettings
    from microfab.machines.printhead.sensitivity import (
        markdown,
        sensitivity_points,
        sensitivity_study,
        sensitivity_table,
    )
    from microfab.process.inkjet.fluids import naalg

    settings = DropletSettings(model=model)
    try:
        for c in cs:
            naalg(c)
        points = sensitivity_points(cs)
        with progress() as bar:
            task = bar.add_task("sensitivity", total=len(points))
            res = sensitivity_study(
                points,
                settings=settings,
                results_dir=out / "points",
                progress=lambda n, total, p, ok: bar.update(
                    task,
                    completed=n,
                    description=f"{p.concentration_pct:g} % {p.prop} ×{p.factor:g}",
                ),
                workers=jobs,
                raise_on_failure=False,
            )
    except (OSError, ValueError) as exc:
        fail(str(exc))
    table = sensitivity_table(list(res.rows))
    atomic_write_text(out / "sensitivity.json", json.dumps({"model": model, "rows": table},
                                                           indent=2) + "\n")  # fmt: skip
    atomic_write_text(out / "sensitivity.md", markdown(table))
    console.print(markdown(table))
    console.print(f"wrote {out / 'sensitivity.json'} and {out / 'sensitivity.md'}")
    if res.failed:
        first = res.failed[0]
        fail(
            f"{len(res.failed)} point(s) failed (running again retries them); first: "
            f"{first.point.concentration_pct:g} % {first.point.prop} ×{first.point.factor:g}: "
            f"{first.error}",
            code=1,
        )
