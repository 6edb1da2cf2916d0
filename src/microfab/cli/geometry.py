"""``microfab path show`` and ``microfab trajectory``: drawings in, references out."""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from microfab.cli._kit import (
    check_outputs,
    console,
    err_console,
    fail,
    progress,
)
from microfab.cli._options import choice, integer, number, refuse_unused
from microfab.io.job import Key

__all__ = [
    "CHORD_M",
    "LIMIT_RANGES",
    "LISTED",
    "MAX_GRID",
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "MIN_SAMPLES",
    "TEXT_HEIGHT_M",
    "path_app",
    "refuse_unused_sizing",
    "trajectory_cmd",
]

#: Largest ``--n-grid`` (the linear programs grow with it; 20000 points take a minute).
MAX_GRID = 20_000
#: Largest ``--rate``, Hz.
MAX_RATE_HZ = 1e8
#: Lowest ``--rate``, Hz (assumed: the slowest loop among the machines microfab drives is
#: the 400 Hz of seed 002's networks (seed 002 §III-B, Fig. 4); a quarter of it is a floor
#: below which no machine here is commanded).
MIN_RATE_HZ = 100.0
#: Fewest samples a reference may hold over its motion (assumed: 100 samples around a
#: circle are 3.6° apart, their chords within R (1 - cos(π/100)) = 5e-4 R of the arc; a
#: coarser reference no longer describes the path it is meant to follow).
MIN_SAMPLES = 100
#: Accepted range of each limit option by unit (assumed physical bounds of the machines
#: microfab drives: galvo scanners reach ~10 m/s, 1e6 m/s², 1e10 m/s³ at the image plane,
#: stages a metre of travel; outside them a planner only meets overflows).
LIMIT_RANGES: dict[str, tuple[float, float]] = {
    "m/s": (1e-6, 1e3),
    "m/s²": (1e-6, 1e8),
    "m/s³": (1e-6, 1e13),
    "m": (1e-6, 10.0),
}
#: Airfoil chord and text height: from 1 µm to the 10 m of the largest workspace one may
#: declare (`LIMIT_RANGES`); assumed, like that range.
CHORD_M = Key(name="chord", type="float", default=0.1, low=1e-6, high=10.0, unit="m",
              help="Airfoil chord.")  # fmt: skip
TEXT_HEIGHT_M = Key(name="text_height", type="float", default=0.01, low=1e-6, high=10.0,
                    unit="m", help="Text font size.")  # fmt: skip
#: Contours (and skipped items) ``path show`` lists one per line; ``--json`` gives all.
LISTED = 20

path_app = typer.Typer(no_args_is_help=True, help="Inspect drawings: contours, lengths, holes.")

DrawingArg = Annotated[
    str,
    typer.Argument(
        help="A .dxf/.svg/.dat file, a shape (circle:radius=0.01, square:side=0.02, spiral, "
        "polygon:n_sides=6,radius=0.01, ...), text:LETTERS or airfoil:e344."
    ),
]


def _units() -> dict[str, float]:
    """The drawing units `microfab.geometry.dxf.UNITS_M` names, imported when needed."""
    from microfab.geometry.dxf import UNITS_M

    return UNITS_M


#: --units, checked while parsed against `UNITS_M` in any case (as the DXF reader reads it).
UnitsOpt = Annotated[
    str | None,
    choice(
        choices=_units, help="DXF drawing units when the header has none.", case_sensitive=False
    ),
]
ChordOpt = Annotated[float, number("--chord", key=CHORD_M)]
HeightOpt = Annotated[float, number("--text-height", key=TEXT_HEIGHT_M)]


def _velocity(help: str) -> Any:
    """A speed option (m/s) in the range of ``--vmax`` (`LIMIT_RANGES`)."""
    low, high = LIMIT_RANGES["m/s"]
    return number(help=help, unit="m/s", low=low, high=high)


def refuse_unused_sizing(ctx: typer.Context, drawing: str) -> None:
    """Refuse ``--chord``, ``--text-height`` or ``--units`` where the drawing has no use for it.

    ``--chord`` sizes an airfoil (``airfoil:NAME`` or a ``.dat`` file), ``--text-height``
    the letters of ``text:LETTERS``, ``--units`` a DXF file (`microfab.geometry.load`).
    """
    spec = drawing.strip()
    kind, sep, _ = spec.partition(":")
    kind = kind.lower() if sep else ""
    suffix = "" if kind in ("text", "airfoil") else Path(spec).suffix.lower()
    if not (kind == "airfoil" or suffix == ".dat"):
        refuse_unused(ctx, ["chord"], "on this drawing: it sizes an airfoil (airfoil:NAME, .dat)")
    if kind != "text":
        refuse_unused(ctx, ["text_height"], "on this drawing: it sizes text:LETTERS")
    if suffix != ".dxf":
        refuse_unused(ctx, ["units"], "on this drawing: it is the unit of a .dxf file")


def _load(drawing: str, units: str | None, chord: float, text_height: float):
    from microfab.geometry.load import load_drawing

    # the options are checked while parsed; `stage score` passes the sizing it reads
    # from a summary file, checked here against the same declarations
    sizing = (("--chord", chord, CHORD_M), ("--text-height", text_height, TEXT_HEIGHT_M))
    for flag, value, key in sizing:
        if key.outside(value):
            fail(f"{flag} {value:g} {key.unit} is outside the allowed range {key.range_text()}")
    units_m = _units()  # --units is checked while parsed; a summary's units here
    if units is not None and units.strip().lower() not in units_m:
        fail(f"--units {units!r} is not one of {', '.join(units_m)}")
    try:
        return load_drawing(drawing, units=units, chord=chord, text_height=text_height)
    except (OSError, ValueError) as exc:
        fail(str(exc))


@path_app.command("show")
def path_show_cmd(
    ctx: typer.Context,
    drawing: DrawingArg,
    out: Annotated[
        Path | None, typer.Option(help="PNG picture (default: DRAWING-stem.png).")
    ] = None,
    json_out: Annotated[
        bool, typer.Option("--json", help="Print the summary of every contour as JSON.")
    ] = False,
    units: UnitsOpt = None,
    chord: ChordOpt = 0.1,
    text_height: HeightOpt = 0.01,
) -> None:
    """Picture of the contours (start dots, direction arrows) and a summary.

    The summary lists the first 20 contours, one line each (kind, length, box, segments),
    then how many more there are and of which kinds; --json prints every contour. A
    progress bar on stderr follows reading, nesting, drawing and writing.
    """
    target = out or Path(_stem(drawing) + ".png")
    check_outputs(files={"--out": target}, inputs={"DRAWING": Path(drawing)})
    refuse_unused_sizing(ctx, drawing)
    from microfab.report.canvas import save_figure
    from microfab.report.geometry import fig_layer

    with progress() as prog:
        task = prog.add_task("reading the drawing", total=4)
        layer = _load(drawing, units, chord, text_height)
        prog.update(task, advance=1, description=f"nesting {len(layer)} contours")
        depth = layer.depth
        summary = layer.summary()
        prog.update(task, advance=1, description="drawing")
        fig = fig_layer(layer)
        prog.update(task, advance=1, description="writing the picture")
        try:
            save_figure(fig, target)
        except OSError as exc:
            fail(f"cannot write {target}: {exc}")
        prog.update(task, advance=1, description=f"{len(layer)} contours")
    if json_out:
        text = json.dumps(summary, indent=2, ensure_ascii=False)
        if console.is_terminal and len(layer) <= LISTED:
            console.print_json(text)  # coloured; a long one would take seconds
        else:
            print(text)
        err_console.print(f"wrote {target}", highlight=False)
        return
    _print_contours(summary["contours"], depth)  # type: ignore[arg-type]
    for s in layer.skipped[:LISTED]:
        err_console.print(f"skipped {s.kind} {s.ref}: {s.reason}", highlight=False)
    if len(layer.skipped) > LISTED:
        err_console.print(
            f"... and {len(layer.skipped) - LISTED} more skipped; --json lists them all",
            highlight=False,
        )
    console.print(f"wrote {target}", highlight=False)


def _kind(depth: int) -> str:
    """What a contour of this nesting depth is: ``open``, ``outer`` or ``hole``."""
    return "open" if depth < 0 else ("outer" if depth % 2 == 0 else "hole")


def _print_contours(contours: list[dict[str, Any]], depth: tuple[int, ...]) -> None:
    """One line for each of the first `LISTED` contours, then a count of the rest."""
    for i, (c, d) in enumerate(zip(contours[:LISTED], depth, strict=False)):
        x0, y0, x1, y1 = (v * 1e3 for v in c["bbox_m"])
        console.print(
            f"#{i} {_kind(d):5s} {'closed' if c['closed'] else 'open  '} "
            f"length {c['length_m'] * 1e3:.4f} mm, bbox [{x0:.3f}, {y0:.3f}] - [{x1:.3f}, "
            f"{y1:.3f}] mm, {c['n_segments']} segments",
            highlight=False,
        )
    if len(contours) > LISTED:
        kinds = Counter(_kind(d) for d in depth)
        console.print(
            f"... and {len(contours) - LISTED} more contours (of {len(contours)}: "
            f"{kinds['outer']} outer, {kinds['hole']} holes, {kinds['open']} open); "
            "--json lists them all",
            highlight=False,
        )


def _stem(drawing: str) -> str:
    p = Path(drawing)
    stem = p.stem if p.suffix.lower() in (".dxf", ".svg", ".dat") else drawing.split(":")[0]
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in stem) or "drawing"


def _limit(help: str, unit: str) -> Any:
    """A machine-limit option in its unit's range (`LIMIT_RANGES`)."""
    low, high = LIMIT_RANGES[unit]
    return number(help=help, unit=unit, low=low, high=high)


def _enough_samples(n: int, dt: float, rate: float) -> None:
    """Refuse a reference of fewer than `MIN_SAMPLES` samples over its motion.

    Parameters
    ----------
    n : int
        Samples of the reference.
    dt : float
        Its sample time, s.
    rate : float
        ``--rate``, Hz, as given.
    """
    if n >= MIN_SAMPLES:
        return
    motion = (n - 1) * dt  # from the first sample to the last, s
    need = f"{math.ceil((MIN_SAMPLES - 1) / motion)} Hz or more" if motion > 0 else "a longer path"
    fail(
        f"--rate {rate:g} Hz gives {n} samples over the {motion:.6g} s motion; a reference "
        f"needs at least {MIN_SAMPLES} to follow the path: give --rate {need}"
    )


def trajectory_cmd(
    ctx: typer.Context,
    drawing: DrawingArg,
    speed: Annotated[
        float | None,
        _velocity(
            "Path speed (seed 002 eq. 15): held wherever the limits allow, with ramps from "
            "and to rest, slower in tight curves, a stop at each corner."
        ),
    ] = None,
    time_optimal: Annotated[
        bool, typer.Option("--time-optimal", help="Minimum time under the limits.")
    ] = False,
    vmax: Annotated[float | None, _limit("Per-axis velocity limit.", "m/s")] = None,
    amax: Annotated[float | None, _limit("Per-axis acceleration limit.", "m/s²")] = None,
    jmax: Annotated[float | None, _limit("Per-axis jerk limit.", "m/s³")] = None,
    workspace: Annotated[float | None, _limit("Half width of the square workspace.", "m")] = None,
    feed: Annotated[float | None, _velocity("Path speed cap (time-optimal).")] = None,
    rate: Annotated[
        float,
        number(
            help=f"Sample rate; the reference holds at least {MIN_SAMPLES} samples.",
            unit="Hz",
            low=MIN_RATE_HZ,
            high=MAX_RATE_HZ,
        ),
    ] = 10_000.0,
    n_grid: Annotated[
        int,
        integer(
            help="Planning grid points (time-optimal); planning time grows faster than the "
            "grid (1000: a few s, 20000: about a minute).",
            low=10,  # assumed: fewer points do not resolve a corner's ramps
            high=MAX_GRID,
        ),
    ] = 1000,
    contour: Annotated[
        int | None,
        integer(help="Only this contour (index); default: all, joined by jumps.", low=0),
    ] = None,
    out: Annotated[Path, typer.Option(help="Reference file: .csv, .h5 or .mat.")] = Path(
        "reference.csv"
    ),
    plot: Annotated[
        Path | None, typer.Option(help="Profile PNG (default: <out stem>_profile.png).")
    ] = None,
    units: UnitsOpt = None,
    chord: ChordOpt = 0.1,
    text_height: HeightOpt = 0.01,
) -> None:
    """Sample a reference along a drawing, check it against the machine limits, write it.

    Limits default to the seed 002 stage (Table I: 1.5 m/s, 40 m/s², ±0.19 m, no jerk
    limit); each option overrides one. Nothing is written if the reference would break
    a limit.
    """
    check_outputs(files={"--out": out, "--plot": plot}, inputs={"DRAWING": Path(drawing)})
    from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
    from microfab.io.trace import write_columns
    from microfab.report.canvas import save_figure
    from microfab.report.geometry import fig_profile
    from microfab.trajectory.cruise import cruise

    if (speed is None) == (not time_optimal):
        fail("give exactly one of --speed V or --time-optimal")
    refuse_unused_sizing(ctx, drawing)
    if not time_optimal:
        refuse_unused(ctx, ["feed"], "with --speed (it caps the speed of --time-optimal)")
        refuse_unused(ctx, ["n_grid"], "with --speed (it is the planning grid of --time-optimal)")
    base = MachineLimits.seed002_stage()
    try:
        half = workspace
        limits = MachineLimits(
            workspace=tuple((-half, half) for _ in base.axes)
            if half is not None
            else base.workspace,
            velocity=(vmax,) * 2 if vmax is not None else base.velocity,
            acceleration=(amax,) * 2 if amax is not None else base.acceleration,
            jerk=(jmax,) * 2 if jmax is not None else None,
        )
    except ValueError as exc:
        fail(str(exc))
    layer = _load(drawing, units, chord, text_height)
    if contour is not None:
        if not 0 <= contour < len(layer):
            fail(f"--contour {contour} is out of range: the drawing has {len(layer)} contours")
        path, marks = layer[contour], ((0.0, layer[contour].length),)
    else:
        path, marks = layer.tour() if len(layer) > 1 else (layer[0], ((0.0, layer[0].length),))
    box = path.bbox
    for k, (lo, hi) in enumerate(limits.workspace):
        if box[k] < lo or box[k + 2] > hi:
            fail(
                f"the drawing spans {'xy'[k]} from {box[k]:.6g} to {box[k + 2]:.6g} m, outside "
                f"the workspace [{lo:.6g}, {hi:.6g}] m; declare a larger --workspace, or check "
                "the drawing's units"
            )
    try:
        if time_optimal:
            from microfab.trajectory.optimal import PlanningError
            from microfab.trajectory.optimal import time_optimal as plan

            planning_error: PlanningError | None = None
            with console.status("planning the time-optimal profile"):
                try:
                    res = plan(path, limits, n_grid=n_grid, sample_rate_hz=rate, feed=feed)
                except PlanningError as exc:
                    planning_error = exc
            if planning_error is not None:
                fail(str(planning_error))
            traj = res.trajectory
        else:
            assert speed is not None
            traj = cruise(path, limits, speed=speed, sample_rate_hz=rate)
        check_trajectory(traj, limits)
        _enough_samples(traj.n_samples, traj.dt, rate)
    except LimitViolation as exc:
        if time_optimal:
            fail(f"{exc}. Declare other limits (--vmax, --amax, --jmax, --workspace).")
        fail(
            f"{exc}. Use --time-optimal (it also plans with --jmax; --feed caps the speed), "
            "or declare other limits."
        )
    except ValueError as exc:
        fail(str(exc))
    cols = traj.columns()
    on = np.zeros(traj.n_samples)
    if traj.s is not None:
        for a, b in marks:
            on[(traj.s >= a) & (traj.s <= b)] = 1.0
        cols["laser"] = on
    try:
        write_columns(out, cols, unit="m")
        target = plot or out.with_name(out.stem + "_profile.png")
        save_figure(fig_profile(traj, limits), target)
    except (OSError, ValueError) as exc:
        fail(f"cannot write the reference: {exc}")
    how = ""
    if not time_optimal:
        how = (
            f"; at {speed:g} m/s for {100 * traj.meta['share_at_speed']:.0f} % of the time, "
            f"{traj.meta['corner_stops']} corner stops"
        )
    console.print(
        f"{traj.n_samples} samples at {1 / traj.dt:.6g} Hz, duration {traj.duration:.6g} s, "
        f"path length {path.length * 1e3:.4f} mm{how}; wrote {out} and {target}",
        highlight=False,
    )
