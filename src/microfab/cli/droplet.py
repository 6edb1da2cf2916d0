"""``microfab droplet simulate|render|analyze``: drop-on-demand inkjet, one drop at a time.

Holds the ``droplet`` group (`droplet_app`) and what its commands share: ``--model``
(`ModelOpt`), the camera keys, the duration bounds and the readers of list options
(`_floats`, `_check_each`). The studies over many points, ``droplet sweep|calibrate|
sensitivity``, are in `cli/droplet_studies.py`, registered on this group when
`cli/__init__.py` imports it (this module does not import it).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import (
    check_output_path,
    check_outputs,
    console,
    fail,
    progress,
)
from microfab.cli._options import choice, given, integer, number
from microfab.experiments.seed003_inkjet.keys import (
    AFTER_BREAKUP,
    CONCENTRATION,
    DURATION,
    VOLTAGE,
)
from microfab.io.atomic import atomic_write_text
from microfab.io.job import Key
from microfab.io.lock import hold_for_command
from microfab.process.inkjet.fluids import DEFAULT_JET_MODEL

__all__ = ["MAX_DURATION_US", "droplet_app"]

#: Longest simulated time a command accepts, µs (the seed's runs are 100 to 400 µs).
MAX_DURATION_US = DURATION.high
#: Shortest simulated time of `droplet simulate`, µs (assumed: a few solver steps, a look at
#: the meniscus before any breakup; a sweep point needs the 10 µs of `DURATION`).
MIN_SIMULATE_US = 1.0

droplet_app = typer.Typer(
    no_args_is_help=True,
    help="Drop-on-demand inkjet (seed 003 part 1): simulate a droplet, analyse camera frames.",
)


#: Camera settings accepted, as the render command's (assumed: a shadowgraph of a 10-100 µm
#: nozzle has pixels of 0.1-100 µm and frames 0.1-1000 µs apart; outside, the unit is wrong).
#: The same ranges as frames.json's (`microfab.measure.frames.PIXEL_SIZE_RANGE_M`,
#: `FRAME_INTERVAL_RANGE_S`, restated in µm and µs so that the CLI does not import pydantic
#: at start-up; a test checks that they agree).
_PIXEL_RANGE_UM = (0.1, 100.0)
_INTERVAL_RANGE_US = (0.1, 1000.0)
PIXEL_SIZE = Key(name="pixel_size_um", type="float", default=2.0, low=_PIXEL_RANGE_UM[0],
                 high=_PIXEL_RANGE_UM[1], unit="µm", help="Camera pixel size, in the object "
                 "plane.")  # fmt: skip
FRAME_INTERVAL = Key(name="frame_interval_us", type="float", default=10.0,
                     low=_INTERVAL_RANGE_US[0], high=_INTERVAL_RANGE_US[1], unit="µs",
                     help="Time between frames.")  # fmt: skip
#: Most frames one render writes (assumed: a high-speed camera's burst is a few hundred to
#: a few thousand frames; 1000 frames of the default camera are already about 1 GB of
#: float64 while they are rendered).
MAX_RENDER_FRAMES = 1000
#: Most bytes the rendered frames may take (assumed: the 2 GB peak of issue 44 for a
#: command, float64 frames).
MAX_RENDER_BYTES = 2e9
#: Tallest image row accepted as the nozzle's, px (assumed: 10 times the 10 000 rows of the
#: tallest scientific camera sensors).
MAX_IMAGE_ROWS = 100_000


def _json(data: dict[str, Any], path: Path | None) -> None:
    text = json.dumps(data, indent=2, default=float)
    if path is None:
        console.print_json(text)
    else:
        atomic_write_text(path, text + "\n")
        console.print(f"wrote {path}")


@droplet_app.command("simulate")
def simulate_cmd(
    ctx: typer.Context,
    concentration: Annotated[float, number(help="NaAlg concentration.", key=CONCENTRATION)] = 1.0,
    voltage: Annotated[float, number(help="Bipolar drive amplitude.", key=VOLTAGE)] = 50.0,
    duration: Annotated[
        float,
        number(
            help="Simulated time (the sweep's default).",
            unit="µs",
            low=MIN_SIMULATE_US,
            high=MAX_DURATION_US,
        ),
    ] = 400.0,
    after_breakup: Annotated[
        float,
        number(
            help="How long to follow the bodies after breakup (less than --duration).",
            key=AFTER_BREAKUP,
        ),
    ] = 20.0,
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet/simulate"),
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the summary to this JSON file.")
    ] = None,
    model: ModelOpt = DEFAULT_JET_MODEL,
) -> None:
    """Predict breakup time, position, mode, satellites and head speed; write a report.

    Runs the same path as a sweep point (`microfab.machines.printhead.run_point`, which plays
    the printhead machine) with the same defaults, so both give the same answer for the
    same point.
    """
    if given(ctx, "after_breakup") and not after_breakup < duration:
        fail(
            f"--after-breakup {after_breakup:g} µs is not shorter than --duration "
            f"{duration:g} µs: the bodies cannot be followed that long after a breakup"
        )
    check_outputs(folders={"--out": out}, files={"--json": json_out})
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point
    from microfab.process.inkjet.fluids import naalg

    try:
        fluid = naalg(concentration)
    except ValueError as exc:
        fail(f"--concentration: {exc}")
    settings = DropletSettings(
        duration_s=duration * 1e-6, after_breakup_s=after_breakup * 1e-6, model=model
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


def _jet_models() -> tuple[str, ...]:
    """The jet models (`microfab.process.inkjet.droplet.JET_MODELS`), imported when needed."""
    from microfab.process.inkjet.droplet import JET_MODELS

    return JET_MODELS


#: --model of every droplet command, checked while parsed against `JET_MODELS`.
ModelOpt = Annotated[str, choice(choices=_jet_models, help=_MODEL_HELP)]


def _check_each(name: str, values: list[float], key: Key) -> None:
    """Refuse an element of a list option outside ``key``'s range, on one line."""
    for value in values:
        if key.outside(value):
            fail(f"{name}: {value:g} {key.unit} is outside the allowed range {key.range_text()}")


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
    concentration: Annotated[float, number(help="NaAlg concentration.", key=CONCENTRATION)] = 1.0,
    voltage: Annotated[float, number(help="Bipolar drive amplitude.", key=VOLTAGE)] = 50.0,
    duration: Annotated[float, number(help="Simulated time.", key=DURATION)] = 400.0,
    frame_interval: Annotated[
        float, number(help="Time between frames (at most --duration).", key=FRAME_INTERVAL)
    ] = 10.0,
    pixel_size: Annotated[float, number(help="Camera pixel size.", key=PIXEL_SIZE)] = 2.0,
    seed: Annotated[int, integer(help="Seed of the camera noise (any one; 0 and up).", low=0)] = 0,
    model: ModelOpt = DEFAULT_JET_MODEL,
) -> None:
    """Simulate a droplet and write shadowgraph frames that droplet analyze can read."""
    if frame_interval > duration:
        fail(
            f"--frame-interval {frame_interval:g} µs is longer than --duration {duration:g} µs: "
            "no two frames to measure a speed from"
        )
    if duration / frame_interval > MAX_RENDER_FRAMES:
        fail(
            f"--duration {duration:g} µs at --frame-interval {frame_interval:g} µs is "
            f"{duration / frame_interval:.0f} frames; at most {MAX_RENDER_FRAMES} are rendered: "
            "a longer interval or a shorter duration"
        )
    check_output_path("OUT", out, kind="folder")
    hold_for_command(out, "OUT", on_refused=fail)
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point
    from microfab.measure.shadowgraph import render_sequence, write_frames
    from microfab.process.inkjet.fluids import naalg

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
        size = len(sil) * cam.height_px * cam.width_px * 8  # float64 frames, bytes
        if size > MAX_RENDER_BYTES:
            fail(
                f"{len(sil)} frames of {cam.width_px} x {cam.height_px} px at --pixel-size "
                f"{pixel_size:g} µm would take {size / 1e9:.3g} GB (at most "
                f"{MAX_RENDER_BYTES / 1e9:g} GB): a larger --pixel-size or --frame-interval"
            )
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
        float | None,
        number(help="Pixel size (else from frames.json; the same if both).", key=PIXEL_SIZE),
    ] = None,
    frame_interval: Annotated[
        float | None,
        number(
            help="Time between frames (else from frames.json; the same if both).",
            key=FRAME_INTERVAL,
        ),
    ] = None,
    nozzle_row: Annotated[
        int | None,
        integer(
            help="Last image row of the nozzle (else from frames.json, else detected).",
            unit="px",
            low=0,
            high=MAX_IMAGE_ROWS,
        ),
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
    _agree_with_sidecar(frames_dir, pixel_size=pixel_size, frame_interval=frame_interval)
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


def _agree_with_sidecar(
    folder: Path, *, pixel_size: float | None, frame_interval: float | None
) -> None:
    """Refuse a camera option that contradicts the folder's frames.json (one line, exit 2).

    The sidecar says how the frames were taken: an option saying otherwise would measure
    them at the wrong scale. They agree to 1e-9 relative (the µm-to-m conversion of a
    decimal changes the last bits only, about 1e-16). ``pixel_size`` (µm) and
    ``frame_interval`` (µs) are the options, ``None`` where not given.
    """
    import math

    from microfab.measure.frames import SIDECAR_NAME, read_sidecar

    if pixel_size is None and frame_interval is None:
        return
    try:
        meta = read_sidecar(folder) if folder.is_dir() else {}
    except (OSError, ValueError) as exc:
        fail(str(exc))
    for name, value, key, scale, unit in (
        ("--pixel-size", pixel_size, "pixel_size_m", 1e-6, "µm"),
        ("--frame-interval", frame_interval, "frame_interval_s", 1e-6, "µs"),
    ):
        stated = meta.get(key)
        if value is None or stated is None:
            continue
        if not math.isclose(value * scale, stated, rel_tol=1e-9):
            fail(
                f"{name} {value:g} {unit}, but {folder / SIDECAR_NAME} says {key} = {stated:g} "
                f"({stated / scale:g} {unit}); leave {name} out, or correct the file"
            )


def _floats(text: str, name: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        fail(f"--{name} must be comma-separated numbers, got {text!r}")
    if not values:
        fail(f"--{name} is empty")
    return values
