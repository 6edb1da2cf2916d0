"""``microfab slm scan-time|build``: scan time of an SLM layer, or a whole part, on the twin.

Seed 003 part 2 (Buls et al.): ``slm scan-time SOURCE`` turns a lattice layer or a
drawing into a scan program (`microfab.process.slm.source`) and prints its naive,
fixed-delay and dynamics-aware scan times on the twin, with and without a shaper
(``shaper design``, `cli/shaper.py`) (`microfab.process.slm.estimate`). ``slm build``
times a whole lattice part layer by layer (`microfab.process.slm.build`), in this process
or on Dask, saving each layer as it finishes so that a rerun resumes.

Every number is declared with its unit and range (`microfab.cli._options`), sharing the
``slm-shaping`` job's key where one sets the same quantity
(`microfab.experiments.seed003_slm.keys`); an option the chosen mode does not use is
refused, not ignored. Every refusal is one ``error:`` line, exit code 2, and nothing is
written.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer

from microfab.cli._kit import (
    check_outputs,
    console,
    fail,
    print_table,
)
from microfab.cli._options import choice, given, integer, number, refuse_unused
from microfab.experiments.seed003_slm import keys
from microfab.io.lock import hold_for_command
from microfab.process.slm.timing import RTCDelays

if TYPE_CHECKING:
    from microfab.process.slm.estimate import ScanTimeComparison

__all__ = ["slm_app"]

slm_app = typer.Typer(
    no_args_is_help=True, help="SLM scanning on the galvo twin (seed 003 part 2)."
)

#: Most strut nodes of a lattice layer within its outline (assumed 5000: ten times the
#: default part's ~470, more than the seed's strut and fraction fit in the field; more is a
#: mistaken strut or fraction, and 20 000 took minutes).
_MAX_LATTICE_NODES = 5000.0
#: Settling band of the dynamics-aware estimate, % of the jump: more than 0, at most 50 %
#: (as the job's ``settle_band`` <= 0.5, assumed: within half the jump is no settling).
_MAX_BAND_PCT = 50.0
_D = RTCDelays()  # the library's defaults are the options' defaults


@slm_app.command("scan-time")
def scan_time_cmd(
    ctx: typer.Context,
    source: Annotated[
        str,
        typer.Argument(
            help="lattice:key=value,... (z, radius, strut, fraction, hatch, sides; m) or a "
            "drawing (DXF/SVG file, or a shape such as circle:radius=5e-3)."
        ),
    ],
    shaper: Annotated[
        Path | None, typer.Option(help="Shaper JSON (shaper design): also estimate with it.")
    ] = None,
    mark_speed: Annotated[float, number(help="Mark speed.", key=keys.MARK_SPEED)] = 0.6,
    jump_speed: Annotated[float, number(help="Jump speed.", key=keys.JUMP_SPEED)] = 5.0,
    jump_delay_us: Annotated[
        float,
        number(help="Fixed jump delay without the shaper (seed: 750 µs).", key=keys.JUMP_DELAY),
    ] = _D.jump_s * 1e6,
    shaped_jump_delay_us: Annotated[
        float,
        number(
            help="Fixed jump delay with the shaper (seed: 250 µs).",
            unit="µs",
            low=0.0,
            high=keys.MAX_DELAY_US,
        ),
    ] = 250.0,
    mark_delay_us: Annotated[
        float, number(help="Mark delay (sky-writing off).", key=keys.MARK_DELAY)
    ] = _D.mark_s * 1e6,
    polygon_delay_us: Annotated[
        float, number(help="Polygon delay (sky-writing 0 or 3).", key=keys.POLYGON_DELAY)
    ] = _D.polygon_s * 1e6,
    laser_on_delay_us: Annotated[
        float, number(help="Laser on delay.", key=keys.LASER_ON_DELAY)
    ] = _D.laser_on_s * 1e6,
    laser_off_delay_us: Annotated[
        float, number(help="Laser off delay.", key=keys.LASER_OFF_DELAY)
    ] = _D.laser_off_s * 1e6,
    variable_polygon: Annotated[
        bool,
        typer.Option(help="Scale the polygon delay by the corner's angle (sky-writing 0 or 3)."),
    ] = False,
    sky_writing: Annotated[
        int, integer(help="Sky-writing mode (RTC5): 0 off, 1, 2 or 3.", low=0, high=3)
    ] = 0,
    sky_prev: Annotated[
        int,
        integer(
            help="Sky-writing run-in (modes 1-3).", unit="ticks", low=0, high=keys.MAX_SKY_TICKS
        ),
    ] = 0,
    sky_post: Annotated[
        int,
        integer(
            help="Sky-writing run-out (modes 1-3).", unit="ticks", low=0, high=keys.MAX_SKY_TICKS
        ),
    ] = 0,
    tolerance_pct: Annotated[
        float,
        number(
            help="Settled: within this % of the jump length (at least 1 bit).",
            unit="%",
            low=0.0,
            low_open=True,
            high=_MAX_BAND_PCT,
        ),
    ] = 2.0,
    hatch_um: Annotated[
        float,
        number(help="Hatch spacing (a lattice's hatch= sets its own).", key=keys.HATCH_SPACING),
    ] = 100.0,
    hatch_angle_deg: Annotated[
        float, number(help="Hatch direction (modulo 180°).", key=keys.HATCH_ANGLE)
    ] = 0.0,
    contours: Annotated[
        bool, typer.Option(help="Mark a drawing's contours before hatching it.")
    ] = True,
    naive_jump_delay: Annotated[
        bool, typer.Option(help="Add the fixed jump delay to the naive estimate (PySLM).")
    ] = False,
    mirror_mode: Annotated[
        bool, typer.Option(help="Twin with the extra mirror mode (3 kHz, ζ 0.02, assumed).")
    ] = False,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the estimates (JSON) here.")
    ] = None,
) -> None:
    """Scan time of one layer three ways: naive Σ L/v, fixed RTC delays, dynamics-aware.

    The dynamics-aware estimate waits after each jump only until the twin's position
    stays within the tolerance (exact propagation of the axis model); with --shaper the
    twin is driven through the shaper (a ZPETC shaper's look-ahead counts as delay) and
    the fixed estimate uses --shaped-jump-delay-us.
    """
    _refuse_unused_scan_options(ctx, sky_writing, shaper is not None, _is_lattice(source))
    check_outputs(files={"--json": json_path}, inputs={"SOURCE": Path(source), "--shaper": shaper})
    from microfab.control.shaper_io import read_shaper, shaper_lti, shaper_to_dict
    from microfab.machines.slm_galvo import machine as slm_galvo
    from microfab.process.slm.estimate import SettleTolerance, estimate_with_shaper
    from microfab.process.slm.source import parse_lattice_source, scan_program
    from microfab.process.slm.timing import (
        TICK_S,
        RTCSettings,
        ScanSpeeds,
        SkyWriting,
        ticks,
    )
    from microfab.report.slm_tables import scan_table

    delays = {
        "jump_s": ("--jump-delay-us", jump_delay_us),
        "mark_s": ("--mark-delay-us", mark_delay_us),
        "polygon_s": ("--polygon-delay-us", polygon_delay_us),
        "laser_on_s": ("--laser-on-delay-us", laser_on_delay_us),
        "laser_off_s": ("--laser-off-delay-us", laser_off_delay_us),
        "shaped": ("--shaped-jump-delay-us", shaped_jump_delay_us),
    }
    for option, value in delays.values():
        try:  # in range (parsed); a whole number of ticks is checked here
            ticks(option, value * 1e-6)
        except ValueError as exc:
            fail(str(exc))
    settings = RTCSettings(
        speeds=ScanSpeeds(mark_m_s=mark_speed, jump_m_s=jump_speed),
        delays=RTCDelays(
            **{k: v * 1e-6 for k, (_, v) in delays.items() if k != "shaped"},
            variable_polygon=variable_polygon,
        ),
        sky_writing=SkyWriting(mode=sky_writing, n_prev=sky_prev, n_post=sky_post),
    )
    shaped_settings = settings.with_delays(jump_s=shaped_jump_delay_us * 1e-6)
    tol = SettleTolerance(relative=tolerance_pct / 100.0)
    the_shaper = None
    if shaper is not None:
        try:
            the_shaper = read_shaper(shaper)
            prefilter = shaper_lti(the_shaper, TICK_S)
        except (OSError, ValueError) as exc:
            fail(str(exc) if str(shaper) in str(exc) else f"{shaper}: {exc}")
    twin = slm_galvo.twin(mirror_mode=mirror_mode)
    bit_m = twin.config.bit_size_m
    field_m = twin.config.field_bit * bit_m
    if _is_lattice(source):  # refused before it is built
        try:
            spec = parse_lattice_source(source)[1]
        except ValueError as exc:
            fail(str(exc))
        if "hatch" in _lattice_keys(source) and given(ctx, "hatch_um"):
            fail(f"--hatch-um {hatch_um:g} µm and the source's hatch={spec.hatch_spacing_m:g} m "
                 "both set the hatch spacing (the source's would win): give one")  # fmt: skip
        if spec.outline_radius_m > field_m:
            fail(f"{source}: the outline radius {spec.outline_radius_m * 1e3:.4g} mm reaches "
                 f"outside the scanner's field of ±{field_m * 1e3:.4g} mm")  # fmt: skip
        if spec.strut_m < bit_m:
            fail(f"{source}: strut={spec.strut_m:g} m is finer than one bit of the "
                 f"scanner, {bit_m:g} m")  # fmt: skip
        if spec.hatch_spacing_m < bit_m:
            fail(f"{source}: hatch={spec.hatch_spacing_m:g} m is finer than one bit of the "
                 f"scanner, {bit_m:g} m")  # fmt: skip
        nodes = math.pi * (spec.outline_radius_m / spec.cell_m) ** 2
        if nodes > _MAX_LATTICE_NODES:
            fail(f"{source}: the cell of {spec.cell_m * 1e6:.4g} µm (strut, fraction) puts "
                 f"about {nodes:.3g} strut nodes in the outline, more than "
                 f"{_MAX_LATTICE_NODES:g}: a larger strut or a smaller fraction?")  # fmt: skip
    try:
        path = scan_program(
            source, hatch_spacing_m=hatch_um * 1e-6, hatch_angle_deg=hatch_angle_deg,
            contours=contours,
        )  # fmt: skip
    except (OSError, ValueError) as exc:
        fail(str(exc))
    if len(path) == 0:
        fail(f"{source}: nothing to scan (narrower than the hatch spacing, contours off)")
    reach = float(np.max(np.abs(path.points)))
    if reach > field_m:
        fail(f"{source}: the program reaches {reach * 1e3:.4g} mm from the field's centre, "
             f"outside the scanner's field of ±{field_m * 1e3:.4g} mm")  # fmt: skip
    runs = estimate_with_shaper(
        path,
        twin,
        settings,
        prefilter=prefilter if the_shaper is not None else None,
        shaped_settings=shaped_settings,
        tolerance=tol,
        naive_jump_delay=naive_jump_delay,
    )
    print_table(scan_table(runs, title=f"Scan time of {source}"))
    _print_scan_summary(path, runs)
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        data: dict[str, Any] = {
            "source": source,
            "program": path.summary(),
            "mirror_mode": mirror_mode,
            "tolerance_relative": tol.relative,
            "delays_us": {opt.lstrip("-"): v for opt, v in delays.values()},
            "speeds_m_s": {"mark": mark_speed, "jump": jump_speed},
        }
        for name, c in runs.items():
            data[name] = {e.method: e.summary() for e in (c.naive, c.fixed, c.dynamics)}
        if the_shaper is not None:
            data["shaper"] = shaper_to_dict(the_shaper)
        atomic_write_json(json_path, data)
        console.print(f"wrote {json_path}", highlight=False)


def _is_lattice(source: str) -> bool:
    """Whether ``source`` is a lattice (``lattice:...``), not a drawing."""
    return source.strip().lower().startswith("lattice:")


def _lattice_keys(source: str) -> set[str]:
    """The keys a lattice source names (``lattice:z=1e-3,hatch=5e-5`` -> ``{z, hatch}``)."""
    body = source.strip().split(":", 1)[1]
    return {item.split("=", 1)[0].strip().lower() for item in body.split(",") if item.strip()}


def _refuse_unused_scan_options(
    ctx: typer.Context, sky_writing: int, with_shaper: bool, lattice: bool
) -> None:
    """Refuse the ``slm scan-time`` options the chosen mode does not use (one line, exit 2).

    The RTC timing (`microfab.process.slm.timing.rtc_timeline`): sky-writing off uses no
    run-in or run-out; sky-writing on drops the mark delay, and modes 1 and 2 sky-write
    every corner (no polygon delay; mode 3 keeps it at corners under its limit angle).
    """
    mode = f"with --sky-writing {sky_writing}"
    if sky_writing == 0:
        refuse_unused(ctx, ["sky_prev", "sky_post"], f"{mode} (sky-writing off)")
    else:
        refuse_unused(ctx, ["mark_delay_us"], f"{mode} (sky-writing replaces the mark delay)")
    if sky_writing in (1, 2):
        refuse_unused(ctx, ["polygon_delay_us", "variable_polygon"],
                      f"{mode} (every corner is sky-written: no polygon delay)")  # fmt: skip
    if not with_shaper:
        refuse_unused(ctx, ["shaped_jump_delay_us"], "without --shaper")
    if lattice:
        refuse_unused(
            ctx, ["contours"], "on a lattice source (a lattice always marks its contours)"
        )


def _print_scan_summary(path: Any, runs: dict[str, ScanTimeComparison]) -> None:
    s = path.summary()
    console.print(
        f"program: {s['n_marks']} marks ({s['mark_length_m'] * 1e3:.4g} mm), {s['n_jumps']} "
        f"jumps ({s['jump_length_m'] * 1e3:.4g} mm)",
        highlight=False,
    )
    for name, c in runs.items():
        d = c.dynamics.summary()
        err = max(d.get("max_laser_on_error_bit", 0.0), d.get("max_laser_off_error_bit", 0.0))
        mean = d.get("mean_jump_delay_s")
        jd = f"mean jump delay {mean * 1e6:.1f} µs, " if mean is not None else ""
        console.print(
            f"{name}, dynamics-aware: {jd}largest laser on/off position error {err:.3g} bit",
            highlight=False,
        )
    if "shaped" in runs:
        a, b = runs["unshaped"], runs["shaped"]
        console.print(
            f"with the shaper: fixed delays {_cut(a.fixed.total_s, b.fixed.total_s)}, "
            f"dynamics-aware {_cut(a.dynamics.total_s, b.dynamics.total_s)}",
            highlight=False,
        )


def _cut(before: float, after: float) -> str:
    return f"{before:.5g} → {after:.5g} s ({100 * (after / before - 1):+.1f} %)"


def _build_shapers() -> object:
    """The shapers of a build's estimates (`microfab.process.slm.build.Shaper`)."""
    from microfab.process.slm.build import Shaper

    return Shaper


@slm_app.command("build")
def build_cmd(
    ctx: typer.Context,
    layers: Annotated[int, integer(help="Layers of the part.", low=1, high=keys.MAX_LAYERS)] = 500,
    layer_um: Annotated[float, number(help="Layer thickness.", key=keys.LAYER_THICKNESS)] = 30.0,
    outline_radius_mm: Annotated[
        float, number(help="Radius of the disc the lattice fills.", key=keys.OUTLINE_RADIUS)
    ] = 8.0,
    hatch_um: Annotated[float, number(help="Hatch spacing.", key=keys.HATCH_SPACING)] = 100.0,
    hatch_rotation_deg: Annotated[
        float,
        number(
            help="Hatch turn from one layer to the next (modulo 360°).", key=keys.HATCH_ROTATION
        ),
    ] = 67.0,
    mark_speed: Annotated[float, number(help="Mark speed.", key=keys.MARK_SPEED)] = 0.6,
    jump_speed: Annotated[float, number(help="Jump speed.", key=keys.JUMP_SPEED)] = 5.0,
    shaper: Annotated[
        str,
        choice(choices=_build_shapers, help="Shaper of the shaped estimates (zoh: the seed's)."),
    ] = "zpetc",
    mirror_mode: Annotated[
        bool, typer.Option(help="Twin with the extra mirror mode (3 kHz, ζ 0.02, assumed).")
    ] = False,
    results_dir: Annotated[
        Path | None,
        typer.Option(help="Save each layer here; a rerun skips the finished layers."),
    ] = None,
    workers: Annotated[
        int,
        integer(
            help="1: in this process; more: a local Dask cluster (not with --scheduler).",
            key=keys.WORKERS,
        ),
    ] = 1,
    scheduler: Annotated[
        str | None, typer.Option(help="Address of a running Dask scheduler.")
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the build's summary (JSON) here.")
    ] = None,
) -> None:
    """Scan time of a whole lattice part, layer by layer, five ways (seed 003 part 2 §4).

    Each layer is a section of the seed's strut lattice in a disc, hatched at its own
    angle, timed naive (Σ L/v), with fixed RTC delays (the seed's 750 µs jump delay) and
    dynamics-aware on the twin, without and with the model-inverse shaper (its derived
    jump delay for the fixed estimate).
    """
    from microfab.cli._kit import progress as progress_bar
    from microfab.machines.slm_galvo import machine as slm_galvo
    from microfab.process.slm.build import BuildSettings, run_build
    from microfab.process.slm.source import MAX_HEIGHT_M
    from microfab.report.slm_tables import build_table

    if scheduler is not None:
        refuse_unused(ctx, ["workers"], "with --scheduler (the scheduler's workers run the layers)")
    height_m = layers * layer_um * 1e-6
    if height_m > MAX_HEIGHT_M:
        fail(f"--layers {layers} of --layer-um {layer_um:g} µm make a part {height_m:g} m tall, "
             f"taller than {MAX_HEIGHT_M:g} m (an SLM build volume)")  # fmt: skip
    if outline_radius_mm * 1e3 < hatch_um:
        fail(f"--outline-radius-mm {outline_radius_mm:g} mm is smaller than --hatch-um "
             f"{hatch_um:g} µm: a layer would have nothing to mark")  # fmt: skip
    try:
        settings = BuildSettings(
            n_layers=layers,
            layer_m=layer_um * 1e-6,
            outline_radius_m=outline_radius_mm * 1e-3,
            hatch_spacing_m=hatch_um * 1e-6,
            hatch_angle_deg_per_layer=hatch_rotation_deg,
            mark_speed_m_s=mark_speed,
            jump_speed_m_s=jump_speed,
            shaper=shaper,  # type: ignore[arg-type]  # checked by BuildSettings
            mirror_mode=mirror_mode,
        )
    except ValueError as exc:
        fail(str(exc))
    check_outputs(folders={"--results-dir": results_dir}, files={"--json": json_path})
    hold_for_command(results_dir, "--results-dir", on_refused=fail)
    try:
        with progress_bar() as bar:
            task = bar.add_task("whole build", total=layers)
            result = run_build(
                settings,
                results_dir,
                workers=workers,
                scheduler=scheduler,
                progress=lambda done, total: bar.update(task, completed=done, total=total),
                twin=slm_galvo.twin,
            )
    except (OSError, ValueError) as exc:
        fail(str(exc))
    print_table(build_table(result))
    for line in result.failed:
        console.print(f"failed: {line}", highlight=False)
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        atomic_write_json(json_path, result.summary())
        console.print(f"wrote {json_path}", highlight=False)
