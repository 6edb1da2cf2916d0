"""The ``microfab`` command.

``microfab run [JOB.toml]``           run a job (default: galvo MSL twin) and write a report
``microfab reproduce msl-ilc``        seed 000 Tables 1 and 2 beside ours, optional JSON
``microfab ilc step TRIAL ...``       one ILC step on real hardware through files
``microfab calibrate galvo``          refit the galvo twin to seed 000 Table 1
``microfab path show DRAWING``        picture and summary of a drawing's contours
``microfab trajectory DRAWING``       a limit-safe sampled reference along a drawing
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from microfab.cli._kit import console, fail, progress
from microfab.cli.droplet import droplet_app
from microfab.cli.geometry import path_app, trajectory_cmd

app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__)
reproduce_app = typer.Typer(no_args_is_help=True, help="Reproduce a seed paper on the twin.")
ilc_app = typer.Typer(no_args_is_help=True, help="Iterative learning control on hardware.")
calibrate_app = typer.Typer(no_args_is_help=True, help="Calibrate digital twins.")
app.add_typer(reproduce_app, name="reproduce")
app.add_typer(ilc_app, name="ilc")
app.add_typer(calibrate_app, name="calibrate")
app.add_typer(path_app, name="path")
app.add_typer(droplet_app, name="droplet")
app.command("trajectory")(trajectory_cmd)


@app.command()
def run(
    job_file: Annotated[
        Path | None, typer.Argument(help="Job TOML; the default job if omitted.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Report folder (overrides the job's).")] = None,
) -> None:
    """Run a job on the digital twin and write its report (report.html + figures + JSON)."""
    from microfab.experiments.seed000_msl.report import write_report
    from microfab.experiments.seed000_msl.run import run_msl_ilc
    from microfab.io.atomic import atomic_write_json
    from microfab.io.job import default_job, load_job

    try:
        job = load_job(job_file) if job_file is not None else default_job()
    except (OSError, ValueError) as exc:
        fail(str(exc))
    out_dir = out or job.out
    rates = sorted(set(job.learning_rates) | {job.rate_hz})
    runs: dict[float, Any] = {}
    with progress() as prog:
        for r in rates:
            task = prog.add_task(f"ILC at {r} features/s", total=job.iterations)
            runs[r] = run_msl_ilc(
                r,
                job.iterations,
                config=job.ilc,
                seed=job.seed,
                state_dir=out_dir / "state" / f"rate_{r}",
                progress=lambda done, total, t=task: prog.update(t, completed=done),
            )
    main = runs[job.rate_hz]
    summary = {
        "job": job.name,
        "rate_hz": job.rate_hz,
        "iterations": job.iterations,
        "table1_mV": {a: main.table1_row(a) for a in main.axes},
        "velocity_mm_s": main.velocity_stats(),
    }
    atomic_write_json(out_dir / "summary.json", summary)
    notes = [
        "Digital twin: galvo x/y with eq. (1) lead-lag feedback at 1 MHz; rigid-body pole, "
        "gain ratio and encoder noise calibrated to seed 000 Table 1 "
        "(microfab/data/galvo_twin.toml, `microfab calibrate galvo`).",
        "Trial 1 is feedback only (u_1 = y_d); ILC learns odd harmonics up to "
        f"{job.ilc.cutoff_hz:g} Hz with gain {job.ilc.gain:g}.",
        "Line width: quasi-steady working-curve model with assumed resin (D_p 100 um, "
        "E_c 10 mJ/cm^2) and beam waist 5 um; the seed gives neither.",
        "Learning state is saved after every iteration under state/; re-running resumes.",
    ]
    path = write_report(out_dir, runs, main_rate=job.rate_hz, title=job.name, notes=notes)
    tab = Table(title=f"{job.name}")
    tab.add_column("axis")
    for k in ("FB RMS", "FB PP", "ILC RMS", "ILC PP"):
        tab.add_column(f"{k} \\[mV]", justify="right")
    for a in main.axes:
        row = main.table1_row(a)
        tab.add_row(a, *(f"{row[k]:.2f}" for k in ("fb_rms", "fb_pp", "ilc_rms", "ilc_pp")))
    console.print(tab)
    console.print(f"report: {path}")


@reproduce_app.command("msl-ilc")
def reproduce_msl_ilc(
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the numbers as JSON.")
    ] = None,
    iterations: Annotated[int, typer.Option(help="ILC trials per run.")] = 30,
    seed: Annotated[int, typer.Option(help="Twin noise seed.")] = 0,
) -> None:
    """Seed 000 on the twin: Tables 1 and 2, margins and learning curves beside the seed's."""
    from microfab.experiments.seed000_msl import paper as seed000
    from microfab.experiments.seed000_msl.run import reproduce_tables
    from microfab.io.atomic import atomic_write_json

    with progress() as prog:
        task = prog.add_task("runs", total=len(seed000.RATES))
        tables, _ = reproduce_tables(
            iterations=iterations,
            seed=seed,
            progress=lambda label: prog.update(task, advance=0, description=label),
        )
        prog.update(task, completed=len(seed000.RATES))
    t1 = Table(title="Table 1: RMS (PP) error \\[mV], ours / seed 000")
    t1.add_column("axis")
    t1.add_column("ctrl")
    for r in seed000.RATES:
        t1.add_column(f"{r} feat/s", justify="right")
    for a in ("x", "y"):
        for c in ("fb", "ilc"):
            cells = []
            for r in seed000.RATES:
                o, s = tables["table1"][a][str(r)], seed000.TABLE1_MV[a][r]
                cells.append(
                    f"{o[c + '_rms']:.2f} ({o[c + '_pp']:.1f}) / "
                    f"{s[c + '_rms']:.2f} ({s[c + '_pp']:.1f})"
                )
            t1.add_row(a, c.upper(), *cells)
    console.print(t1)
    t2 = Table(title="Table 2: beam velocity mean (std) \\[min, max] \\[mm/s], ours / seed 000")
    t2.add_column("ctrl")
    for r in seed000.RATES:
        t2.add_column(f"{r} feat/s", justify="right")
    for c in ("fb", "ilc"):
        cells = []
        for r in seed000.RATES:
            o, s = tables["table2"][str(r)], seed000.TABLE2_MM_S[r]
            cells.append(
                f"{o[c + '_mean']:.0f} ({o[c + '_std']:.0f}) [{o[c + '_min']:.0f}, "
                f"{o[c + '_max']:.0f}] / {s[c + '_mean']} ({s[c + '_std']}) "
                f"[{s[c + '_min']}, {s[c + '_max']}]"
            )
        t2.add_row(c.upper(), *cells)
    console.print(t2)
    for a, m in tables["margins"].items():
        s = seed000.MARGINS[a]
        console.print(
            f"margins {a}: GM {m['gm_db']:.1f} dB at {m['gm_freq_hz'] / 1e3:.1f} kHz, "
            f"PM {m['pm_deg']:.1f} deg at {m['pm_freq_hz'] / 1e3:.2f} kHz "
            f"(seed: {s['gm_db']} dB, {s['pm_deg']} deg)"
        )
    if json_path is not None:
        atomic_write_json(json_path, tables)
        console.print(f"wrote {json_path}")


@ilc_app.command("step")
def ilc_step_cmd(
    trial: Annotated[
        Path, typer.Argument(help="Measured trial: time, reference_<a>, input_<a>, output_<a>.")
    ],
    state: Annotated[Path, typer.Option("--state", help="Learning-state directory.")],
    out: Annotated[Path, typer.Option("--out", help="Next input file (.csv, .mat, .h5).")],
    cutoff_hz: Annotated[
        float, typer.Option(help="Highest learned harmonic [Hz] (first call).")
    ] = 8000.0,
    gain: Annotated[float, typer.Option(help="Learning gain rho (first call).")] = 0.4,
    max_position: Annotated[
        float | None, typer.Option(help="Declared |input| limit [unit].")
    ] = None,
    max_velocity: Annotated[
        float | None, typer.Option(help="Declared slope limit [unit/s].")
    ] = None,
    max_acceleration: Annotated[
        float | None, typer.Option(help="Declared [unit/s^2] limit.")
    ] = None,
) -> None:
    """Learn from one measured trial and write the next input (state kept in --state).

    The first call takes the inverse model from the trial (seed 000 eq. 7). Limits default to
    the galvo twin's (10 V, 5e4 V/s, 2e10 V/s^2) on the first call and are kept in the state.
    """
    from microfab.control.ilc import ILCConfig
    from microfab.core.limits import AxisLimits
    from microfab.machines.files import ilc_step
    from microfab.machines.galvo import GALVO_LIMITS

    try:
        config = ILCConfig(cutoff_hz=cutoff_hz, gain=gain)
        given = (max_position, max_velocity, max_acceleration)
        limits = None
        if any(v is not None for v in given) or not (state / "ilc_state.npz").exists():
            base = GALVO_LIMITS["x"]
            lim = AxisLimits(
                position=max_position if max_position is not None else base.position,
                velocity=max_velocity if max_velocity is not None else base.velocity,
                acceleration=max_acceleration
                if max_acceleration is not None
                else base.acceleration,
                unit=base.unit,
            )
            from microfab.machines.files import read_trial_file

            limits = {a: lim for a in read_trial_file(trial).axes}
        rep = ilc_step(trial, state, out, config=config, limits=limits)
    except (OSError, ValueError) as exc:
        fail(str(exc))
    rms = ", ".join(f"{a} {v:.4g}" for a, v in rep.rms.items())
    console.print(
        f"iteration {rep.iteration}: RMS error {rms}; harmonics "
        f"{', '.join(f'{a} {n}' for a, n in rep.harmonics.items())}; wrote {rep.out_path}",
        highlight=False,
    )


@calibrate_app.command("galvo")
def calibrate_galvo_cmd(
    write: Annotated[Path | None, typer.Option(help="Write the calibration TOML here.")] = None,
) -> None:
    """Refit the galvo twin (rigid-body pole, gain ratio, noise) to seed 000 Table 1."""
    from microfab.experiments.seed000_msl.calibration import calibrate_galvo

    cal = calibrate_galvo(write)
    for name, c in cal.items():
        ax = c.axis
        res = "; ".join(f"{r}: {v[0]:+.1f} %, {v[1]:+.1f} %" for r, v in c.residual_pct.items())
        console.print(
            f"{name}: rigid pole {ax.rigid_pole_hz:.2f} Hz, gain ratio {ax.gain_ratio:.4f}, "
            f"noise {ax.noise_rms_v * 1e3:.3f} mV; FB residual (RMS, PP) {res}"
        )
    if write is not None:
        console.print(f"wrote {write}")


def main() -> None:  # pragma: no cover - entry point
    """Console entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
