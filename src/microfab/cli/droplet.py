"""``microfab droplet simulate|sweep|render|analyze|calibrate``: drop-on-demand inkjet."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import (
    check_option,
    check_output_path,
    check_outputs,
    console,
    fail,
    progress,
)
from microfab.io.atomic import atomic_write_text
from microfab.io.lock import hold_for_command
from microfab.process.inkjet.fluids import DEFAULT_JET_MODEL

__all__ = ["MAX_DURATION_US", "droplet_app"]

#: Longest simulated time a command accepts, µs (the seed's runs are 100 to 400 µs).
MAX_DURATION_US = 5000.0

droplet_app = typer.Typer(
    no_args_is_help=True,
    help="Drop-on-demand inkjet (seed 003 part 1): simulate a droplet, analyse camera frames.",
)


#: Camera settings accepted, as the render command's (assumed: a shadowgraph of a 10-100 µm
#: nozzle has pixels of 0.1-100 µm and frames 0.1-1000 µs apart; outside, the unit is wrong).
_PIXEL_RANGE_UM = (0.1, 100.0)
_INTERVAL_RANGE_US = (0.1, 1000.0)


def _json(data: dict[str, Any], path: Path | None) -> None:
    text = json.dumps(data, indent=2, default=float)
    if path is None:
        console.print_json(text)
    else:
        atomic_write_text(path, text + "\n")
        console.print(f"wrote {path}")


@droplet_app.command("simulate")
def simulate_cmd(
    concentration: Annotated[
        float, typer.Option(help="NaAlg concentration, % w/v (0 to 2).")
    ] = 1.0,
    voltage: Annotated[float, typer.Option(help="Bipolar drive amplitude, V.")] = 50.0,
    duration: Annotated[
        float, typer.Option(help="Simulated time, µs (at most 5000; the sweep's default).")
    ] = 400.0,
    after_breakup: Annotated[
        float,
        typer.Option(help="How long to follow the bodies after breakup, µs (at most 5000)."),
    ] = 20.0,
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/simulate"),
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the summary to this JSON file.")
    ] = None,
    model: Annotated[str, typer.Option(help=_MODEL_HELP)] = DEFAULT_JET_MODEL,
) -> None:
    """Predict breakup time, position, mode, satellites and head speed; write a report.

    Runs the same path as a sweep point (`microfab.machines.printhead.run_point`, which plays
    the printhead machine) with the same defaults, so both give the same answer for the
    same point.
    """
    check_outputs(folders={"--out": out}, files={"--json": json_out})
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.machines.printhead import DropletSettings, SweepPoint, run_point
    from microfab.process.inkjet.fluids import naalg

    _check_voltage("--voltage", voltage)
    # at least 1 µs, a few solver steps (1e-300 ran 0 steps and wrote a report)
    check_option("--duration", duration, "µs", low=1.0, high=MAX_DURATION_US, low_closed=True)
    check_option("--after-breakup", after_breakup, "µs", high=MAX_DURATION_US)
    if not after_breakup * 1e-6 > 0.0:  # a subnormal count of µs is 0 s
        fail(f"--after-breakup must be more than 0 µs, got {after_breakup:g} µs")
    try:
        fluid = naalg(concentration)
    except ValueError as exc:
        fail(f"--concentration: {exc}")
    settings = DropletSettings(
        duration_s=duration * 1e-6, after_breakup_s=after_breakup * 1e-6, model=_model(model)
    )
    with progress() as bar:
        task = bar.add_task(f"{fluid.name}, {voltage:g} V", total=round(duration))
        res = run_point(
            SweepPoint(concentration, voltage),
            settings,
            progress=lambda t: bar.update(task, completed=round(t * 1e6)),
        )
    summary = res.to_dict()
    _write_report(res, out)
    _json(summary, out / "droplet.json")
    if json_out is not None:
        _json(summary, json_out)
    console.print_json(json.dumps(summary, default=float))


#: What each jet model is, for --model's help (the default is named from `DEFAULT_JET_MODEL`).
_MODEL_TRAITS = {
    "eulerian": "fixed grid, a thin film through pinch-offs, the meniscus retracting into "
    "the bore, acoustics coupled both ways",
    "lagrangian": "moving nodes, bodies split at each pinch, meniscus held at the rim",
}
_MODEL_HELP = (
    "Jet model: "
    + " or ".join(f"'{m}' ({traits})" for m, traits in _MODEL_TRAITS.items())
    + f" (default: {DEFAULT_JET_MODEL})."
)


def _model(name: str) -> str:
    """Refuse an unknown jet model on one line."""
    from microfab.process.inkjet.droplet import JET_MODELS

    if name not in JET_MODELS:
        fail(f"--model must be one of {', '.join(JET_MODELS)}, got {name!r}")
    return name


def _check_voltage(name: str, volts: float) -> None:
    """Refuse a drive amplitude outside the calibrated 40-70 V (seed 003 Table 1)."""
    from microfab.machines.printhead import limits

    low, high = limits().voltage_v
    if not low <= volts <= high:
        fail(
            f"{name} {volts:g} V is outside what the model is calibrated for ({low:g} to "
            f"{high:g} V, seed 003 Table 1)"
        )


def _camera(silhouettes: list[Any], pixel_size_m: float = 2e-6) -> Any:
    """A camera tall enough for the farthest body.

    A 2 µm pixel is assumed by default, as in the shadowgraph module: the seed gives no
    imaging optics.
    """
    from microfab.measure.shadowgraph import Camera

    reach = max(float(b[0][-1]) for s in silhouettes for b in s.bodies)
    return Camera(pixel_size_m=pixel_size_m, width_px=160, height_px=int(reach / pixel_size_m) + 40)


def _write_report(res: Any, out: Path) -> None:
    from microfab.measure.shadowgraph import render_sequence
    from microfab.report.canvas import save_figure
    from microfab.report.inkjet import fig_montage, fig_nozzle_flow

    out.mkdir(parents=True, exist_ok=True)
    flow_fig = fig_nozzle_flow(res.flow, res.waveform, res.meniscus_trace)
    save_figure(flow_fig, out / "nozzle_flow.png")
    sil = [s for s in res.silhouettes if s.bodies]
    if sil:
        cam = _camera(sil)
        frames = render_sequence(sil, cam, seed=0)
        save_figure(fig_montage(frames, [s.time_s for s in sil], cam), out / "silhouettes.png")


@droplet_app.command("render")
def render_cmd(
    out: Annotated[Path, typer.Argument(help="Folder for the frames and frames.json.")],
    concentration: Annotated[
        float, typer.Option(help="NaAlg concentration, % w/v (0 to 2).")
    ] = 1.0,
    voltage: Annotated[float, typer.Option(help="Bipolar drive amplitude, V.")] = 50.0,
    duration: Annotated[float, typer.Option(help="Simulated time, µs.")] = 400.0,
    frame_interval: Annotated[float, typer.Option(help="Time between frames, µs.")] = 10.0,
    pixel_size: Annotated[float, typer.Option(help="Camera pixel size, µm.")] = 2.0,
    seed: Annotated[int, typer.Option(min=0, help="Seed of the camera noise.")] = 0,
    model: Annotated[str, typer.Option(help=_MODEL_HELP)] = DEFAULT_JET_MODEL,
) -> None:
    """Simulate a droplet and write shadowgraph frames that droplet analyze can read."""
    check_output_path("OUT", out, kind="folder")
    hold_for_command(out, "OUT", on_refused=fail)
    from microfab.machines.printhead import DropletSettings, SweepPoint, run_point
    from microfab.measure.shadowgraph import render_sequence, write_frames
    from microfab.process.inkjet.fluids import naalg

    _check_voltage("--voltage", voltage)
    for name, value, low, high, unit in (
        ("--duration", duration, 10.0, 5000.0, "µs"),
        ("--frame-interval", frame_interval, *_INTERVAL_RANGE_US, "µs"),
        ("--pixel-size", pixel_size, *_PIXEL_RANGE_UM, "µm"),
    ):
        check_option(name, value, unit, low=low, high=high, low_closed=True)
    model = _model(model)
    try:
        fluid = naalg(concentration)
    except ValueError as exc:
        fail(str(exc))
    with progress() as bar:
        task = bar.add_task(f"{fluid.name}, {voltage:g} V", total=round(duration))
        res = run_point(
            SweepPoint(concentration, voltage),
            DropletSettings(duration_s=duration / 1e6, model=model),
            frame_interval_s=frame_interval / 1e6,
            progress=lambda t: bar.update(task, completed=round(t * 1e6)),
        )
        sil = [s for s in res.silhouettes if s.bodies]
        if not sil:  # inside the bar's block: a refusal clears it
            fail("the simulation produced no liquid outside the nozzle to photograph")
    cam = _camera(sil, pixel_size / 1e6)
    frames = render_sequence(sil, cam, seed=seed)
    try:
        paths = write_frames(
            frames, out, camera=cam, frame_interval_s=frame_interval / 1e6, t0_s=sil[0].time_s
        )
    except (OSError, ValueError) as exc:
        fail(f"cannot write the frames: {exc}")
    console.print(
        f"wrote {len(paths)} frames and frames.json to {out}; measure them with "
        f"`microfab droplet analyze {out}`",
        highlight=False,
    )


@droplet_app.command("analyze")
def analyze_cmd(
    frames_dir: Annotated[Path, typer.Argument(help="Folder of PNG/TIFF frames.")],
    pixel_size: Annotated[
        float | None, typer.Option(help="Pixel size, µm (else from frames.json).")
    ] = None,
    frame_interval: Annotated[
        float | None, typer.Option(help="Time between frames, µs (else from frames.json).")
    ] = None,
    nozzle_row: Annotated[
        int | None, typer.Option(help="Last image row of the nozzle (else detected).")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Figure (PNG).")] = None,
    json_out: Annotated[Path | None, typer.Option("--json", help="Write JSON here.")] = None,
) -> None:
    """Measure head speed, breakup frame and mode, satellites and drop volume from frames."""
    check_outputs(files={"--out": out, "--json": json_out}, inputs={"FRAMES": frames_dir})
    from microfab.measure.imaging import (
        SIDECAR_NAME,
        MissingSettingError,
        analyze_folder,
        load_frames,
    )
    from microfab.report.canvas import save_figure
    from microfab.report.inkjet import fig_analysis

    options = {
        "pixel_size_m": ("--pixel-size", "µm"),
        "frame_interval_s": ("--frame-interval", "µs"),
    }
    ranges = (_PIXEL_RANGE_UM, _INTERVAL_RANGE_US)
    for (name, unit), value, (low, high) in zip(
        options.values(), (pixel_size, frame_interval), ranges, strict=True
    ):
        check_option(name, value, unit, low=low, high=high, low_closed=True)
    if nozzle_row is not None and nozzle_row < 0:
        fail(f"--nozzle-row must be 0 or more (an image row), got {nozzle_row}")
    try:
        res = analyze_folder(
            frames_dir,
            pixel_size_m=None if pixel_size is None else pixel_size * 1e-6,
            frame_interval_s=None if frame_interval is None else frame_interval * 1e-6,
            nozzle_row=nozzle_row,
        )
    except MissingSettingError as exc:
        name, unit = options[exc.key]
        fail(
            f'{name} is required ({unit}): pass it, or put "{exc.key}" '
            f"in {frames_dir / SIDECAR_NAME}"
        )
    except (OSError, ValueError) as exc:
        fail(str(exc))
    if out is not None:
        frames, _ = load_frames(frames_dir)
        save_figure(fig_analysis(res, frames), out)
    _json(res.to_dict(), json_out)


def _floats(text: str, name: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        fail(f"--{name} must be comma-separated numbers, got {text!r}")
    if not values:
        fail(f"--{name} is empty")
    return values


@droplet_app.command("sweep")
def sweep_cmd(
    concentrations: Annotated[
        str, typer.Option(help="NaAlg concentrations at 50 V, % w/v, comma-separated.")
    ] = "0.15,0.2,0.25,1,1.5,2",
    voltages: Annotated[
        str, typer.Option(help="Voltages of the voltage series, V, comma-separated ('' = none).")
    ] = "40,45,50,55,60,65,70",
    voltage_concentration: Annotated[
        float, typer.Option(help="Concentration of the voltage series, % w/v.")
    ] = 1.0,
    duration: Annotated[
        float, typer.Option(help="Simulated time per point, µs (10 to 5000).")
    ] = 400.0,
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/sweep"),
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs",
            "--workers",
            min=1,
            max=256,
            help="Points simulated side by side (local Dask worker processes).",
        ),
    ] = 1,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Run on this Dask scheduler (tcp://host:8786) instead."),
    ] = None,
    model: Annotated[str, typer.Option(help=_MODEL_HELP)] = DEFAULT_JET_MODEL,
) -> None:
    """Breakup time against concentration (the seed's Fig. 4) and the 40-70 V trend.

    Finished points are kept in OUT/sweep/ as they come back; running the same sweep
    again resumes. microfab run examples/droplet_sweep.toml runs the same sweep as a
    job and writes a report with the seed's numbers beside ours.
    """
    check_output_path("--out", out, kind="folder")
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.experiments.seed003_inkjet.paper import SEED_BREAKUP
    from microfab.machines.printhead import DropletSettings, droplet_sweep, sweep_points
    from microfab.process.inkjet.fluids import naalg
    from microfab.report.canvas import save_figure
    from microfab.report.inkjet import fig_sweep

    cs = _floats(concentrations, "concentrations")
    vs = _floats(voltages, "voltages") if voltages.strip() else []
    for v in vs:
        _check_voltage("--voltages", v)
    check_option("--duration", duration, "µs", low=10.0, high=MAX_DURATION_US, low_closed=True)
    try:
        for c in {*cs, voltage_concentration}:
            naalg(c)
        points = sweep_points(cs, vs, voltage_concentration_pct=voltage_concentration)
        with progress() as bar:
            task = bar.add_task("droplet sweep", total=len(points))
            res = droplet_sweep(
                points,
                settings=DropletSettings(duration_s=duration / 1e6, model=_model(model)),
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
        typer.Option(help="Store the fitted law in this property table (TOML) file."),
    ] = None,
    model: Annotated[str, typer.Option(help=_MODEL_HELP)] = DEFAULT_JET_MODEL,
) -> None:
    """Fit the relaxation law λ(c) to the seed's 95 µs (0.15 %) and 230 µs (1 %) breakups.

    Runs the full model twenty to thirty times (a few minutes with the Lagrangian model,
    about 15 s with the Eulerian one). A law belongs to the jet model it was fitted with:
    --write stores it as that model's law ([relaxation] or [relaxation_<model>]).
    """
    check_output_path("--write", write)
    from microfab.machines.printhead_calibration import (
        calibrate_relaxation,
        check_property_table,
        model_breakup,
        write_relaxation,
    )

    model = _model(model)
    if write is not None and not write.is_file():
        fail(f"--write {write}: no such property table (copy src/microfab/data/naalg.toml)")
    if write is not None:
        try:
            check_property_table(write)  # before minutes of runs, not after them
        except ValueError as exc:
            fail(f"--write {exc}")
    with progress() as bar:
        task = bar.add_task("calibration runs", total=None)
        fit = calibrate_relaxation(
            breakup=model_breakup(model),
            progress=lambda ev: bar.update(
                task,
                advance=1,
                description=f"{ev.concentration_pct:g} %, λ {ev.relaxation_time_s * 1e6:.3g} µs",
            ),
        )
    console.print(fit.summary())
    if write is not None:
        try:
            write_relaxation(
                fit,
                write,
                command=f"microfab droplet calibrate --model {model} --write {write}",
                model=model,
            )
        except (OSError, ValueError) as exc:
            fail(str(exc))
        console.print(f"wrote {write}")


@droplet_app.command("sensitivity")
def sensitivity_cmd(
    concentrations: Annotated[
        str, typer.Option(help="NaAlg concentrations at 50 V, % w/v, comma-separated.")
    ] = "0.15,1,2",
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/sensitivity"),
    model: Annotated[str, typer.Option(help=_MODEL_HELP)] = DEFAULT_JET_MODEL,
    jobs: Annotated[
        int, typer.Option("--jobs", min=1, max=256, help="Local Dask worker processes.")
    ] = 1,
) -> None:
    """Breakup time when each assumed fluid value is changed, one at a time.

    The NaAlg values of data/naalg.toml are assumed or calibrated (no published
    measurement of this alginate was found); this shows which of them the breakup times
    hang on. Points are kept in OUT/points/ as they finish; a rerun resumes.
    """
    check_output_path("--out", out, kind="folder")
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.machines.printhead import DropletSettings
    from microfab.machines.printhead_sensitivity import (
        markdown,
        sensitivity_points,
        sensitivity_study,
        sensitivity_table,
    )
    from microfab.process.inkjet.fluids import naalg

    cs = _floats(concentrations, "concentrations")
    settings = DropletSettings(model=_model(model))
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
