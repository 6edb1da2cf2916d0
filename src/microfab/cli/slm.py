"""``microfab slm scan-time|build``: scan time of an SLM layer, or a whole part, on the twin.

Seed 003 part 2 (Buls et al.): ``slm scan-time SOURCE`` turns a lattice layer or a
drawing into a scan program (`microfab.process.slm.source`) and prints its naive,
fixed-delay and dynamics-aware scan times on the twin, with and without a shaper
(``shaper design``, `cli/shaper.py`) (`microfab.process.slm.estimate`). ``slm build``
times a whole lattice part layer by layer (`microfab.process.slm.build`), in this process
or on Dask, saving each layer as it finishes so that a rerun resumes.

Every refusal is one ``error:`` line, exit code 2, and nothing is written.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer

from microfab.cli._kit import (
    check_option,
    check_outputs,
    console,
    fail,
    print_table,
    renamed,
)
from microfab.io.lock import hold_for_command
from microfab.process.slm.timing import RTCDelays

if TYPE_CHECKING:
    from microfab.process.slm.estimate import ScanTimeComparison

__all__ = ["slm_app"]

slm_app = typer.Typer(
    no_args_is_help=True, help="SLM scanning on the galvo twin (seed 003 part 2)."
)

_MAX_DELAY_US = 1e6  # a delay of more than 1 s is a typo (and overflows the tick counts)
#: Longest sky-writing run-in or run-out, ticks (assumed 1000 = 10 ms: ten times the
#: twin's settling after a jump, ~0.9 ms; longer serves nothing and is simulated tick by tick).
_MAX_SKY_TICKS = 1000
#: Most strut nodes of a lattice layer within its outline (assumed 5000: ten times the
#: default part's ~470, more than the seed's strut and fraction fit in the field; more is a
#: mistaken strut or fraction, and 20 000 took minutes).
_MAX_LATTICE_NODES = 5000.0
_D = RTCDelays()  # the library's defaults are the options' defaults


@slm_app.command("scan-time")
def scan_time_cmd(
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
    mark_speed: Annotated[float, typer.Option(help="Mark speed [m/s].")] = 0.6,
    jump_speed: Annotated[float, typer.Option(help="Jump speed [m/s].")] = 5.0,
    jump_delay_us: Annotated[
        float, typer.Option(help="Fixed jump delay without the shaper [µs] (seed: 750).")
    ] = _D.jump_s * 1e6,
    shaped_jump_delay_us: Annotated[
        float, typer.Option(help="Fixed jump delay with the shaper [µs] (seed: 250).")
    ] = 250.0,
    mark_delay_us: Annotated[float, typer.Option(help="Mark delay [µs].")] = _D.mark_s * 1e6,
    polygon_delay_us: Annotated[float, typer.Option(help="Polygon delay [µs].")] = _D.polygon_s
    * 1e6,
    laser_on_delay_us: Annotated[float, typer.Option(help="Laser on delay [µs].")] = _D.laser_on_s
    * 1e6,
    laser_off_delay_us: Annotated[
        float, typer.Option(help="Laser off delay [µs].")
    ] = _D.laser_off_s * 1e6,
    variable_polygon: Annotated[
        bool, typer.Option(help="Scale the polygon delay by the corner's angle.")
    ] = False,
    sky_writing: Annotated[int, typer.Option(help="Sky-writing mode 0-3.")] = 0,
    sky_prev: Annotated[int, typer.Option(help="Sky-writing run-in [ticks].")] = 0,
    sky_post: Annotated[int, typer.Option(help="Sky-writing run-out [ticks].")] = 0,
    tolerance_pct: Annotated[
        float, typer.Option(help="Settled: within this % of the jump length (at least 1 bit).")
    ] = 2.0,
    hatch_um: Annotated[float, typer.Option(help="Hatch spacing [µm].")] = 100.0,
    hatch_angle_deg: Annotated[float, typer.Option(help="Hatch direction [deg].")] = 0.0,
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
    check_outputs(files={"--json": json_path}, inputs={"SOURCE": Path(source), "--shaper": shaper})
    from microfab.control.shaper_io import read_shaper, shaper_lti, shaper_to_dict
    from microfab.machines import slm_galvo
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

    check_option("--mark-speed", mark_speed, "m/s")
    check_option("--jump-speed", jump_speed, "m/s")
    check_option("--tolerance-pct", tolerance_pct, "%", high=100.0)
    check_option("--hatch-um", hatch_um, "µm")
    delays = {
        "jump_s": ("--jump-delay-us", jump_delay_us),
        "mark_s": ("--mark-delay-us", mark_delay_us),
        "polygon_s": ("--polygon-delay-us", polygon_delay_us),
        "laser_on_s": ("--laser-on-delay-us", laser_on_delay_us),
        "laser_off_s": ("--laser-off-delay-us", laser_off_delay_us),
        "shaped": ("--shaped-jump-delay-us", shaped_jump_delay_us),
    }
    for option, value in delays.values():
        check_option(option, value, "µs", high=_MAX_DELAY_US, low_closed=True)
        try:
            ticks(option, value * 1e-6)
        except ValueError as exc:
            fail(str(exc))
    for option, n_ticks in (("--sky-prev", sky_prev), ("--sky-post", sky_post)):
        if n_ticks > _MAX_SKY_TICKS:
            fail(f"{option} must be at most {_MAX_SKY_TICKS} ticks ({_MAX_SKY_TICKS * 10} µs), "
                 f"got {n_ticks}")  # fmt: skip
    try:
        sky = SkyWriting(mode=sky_writing, n_prev=sky_prev, n_post=sky_post)
    except ValueError as exc:
        fail(f"--sky-writing: {exc}")
    try:
        speeds = ScanSpeeds(mark_m_s=mark_speed, jump_m_s=jump_speed)
    except ValueError as exc:
        fail(renamed(str(exc), {"mark speed mark_m_s": "--mark-speed",
                                "jump speed jump_m_s": "--jump-speed"}))  # fmt: skip
    settings = RTCSettings(
        speeds=speeds,
        delays=RTCDelays(
            **{k: v * 1e-6 for k, (_, v) in delays.items() if k != "shaped"},
            variable_polygon=variable_polygon,
        ),
        sky_writing=sky,
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
    if hatch_um * 1e-6 < bit_m:
        fail(f"--hatch-um must be at least one bit of the scanner, {bit_m * 1e6:g} µm, got "
             f"{hatch_um:g} µm")  # fmt: skip
    if source.strip().lower().startswith("lattice:"):  # refused before it is built
        try:
            spec = parse_lattice_source(source)[1]
        except ValueError as exc:
            fail(str(exc))
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


@slm_app.command("build")
def build_cmd(
    layers: Annotated[int, typer.Option(help="Layers of the part.")] = 500,
    layer_um: Annotated[float, typer.Option(help="Layer thickness [µm].")] = 30.0,
    outline_radius_mm: Annotated[
        float, typer.Option(help="Radius of the disc the lattice fills [mm].")
    ] = 8.0,
    hatch_um: Annotated[float, typer.Option(help="Hatch spacing [µm].")] = 100.0,
    hatch_rotation_deg: Annotated[
        float, typer.Option(help="Hatch turn from one layer to the next [deg].")
    ] = 67.0,
    mark_speed: Annotated[float, typer.Option(help="Mark speed [m/s].")] = 0.6,
    jump_speed: Annotated[float, typer.Option(help="Jump speed [m/s].")] = 5.0,
    shaper: Annotated[
        str, typer.Option(help="Shaper of the shaped estimates: none, zoh (the seed's), zpetc.")
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
        typer.Option(min=1, max=256, help="1: in this process; more: a local Dask cluster."),
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
    from microfab.machines import slm_galvo
    from microfab.process.slm.build import BuildSettings, run_build
    from microfab.report.slm_tables import build_table

    if layers < 1:
        fail(f"--layers must be at least 1, got {layers}")
    if workers < 1:
        fail(f"--workers must be at least 1, got {workers}")
    for option, value, unit in (
        ("--layer-um", layer_um, "µm"),
        ("--outline-radius-mm", outline_radius_mm, "mm"),
        ("--hatch-um", hatch_um, "µm"),
        ("--mark-speed", mark_speed, "m/s"),
        ("--jump-speed", jump_speed, "m/s"),
    ):
        check_option(option, value, unit)
    check_outputs(folders={"--results-dir": results_dir}, files={"--json": json_path})
    hold_for_command(results_dir, "--results-dir", on_refused=fail)
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
