"""``microfab droplet simulate|analyze``: drop-on-demand inkjet, predicted and measured."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.clikit import console, fail, progress
from microfab.io.atomic import atomic_write_text

__all__ = ["droplet_app"]

droplet_app = typer.Typer(
    no_args_is_help=True,
    help="Drop-on-demand inkjet (seed 003 part 1): simulate a droplet, analyse camera frames.",
)


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
    duration: Annotated[float, typer.Option(help="Simulated time, µs.")] = 300.0,
    after_breakup: Annotated[
        float, typer.Option(help="How long to follow the bodies after breakup, µs.")
    ] = 60.0,
    out: Annotated[Path, typer.Option(help="Report folder.")] = Path("report/droplet"),
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Also write the summary to this JSON file.")
    ] = None,
) -> None:
    """Predict breakup time, position, mode, satellites and head speed; write a report."""
    from microfab.process.inkjet.droplet import simulate_droplet
    from microfab.process.inkjet.fluids import naalg
    from microfab.process.inkjet.waveform import seed003_waveform

    if not 40.0 <= voltage <= 70.0:
        fail(
            f"voltage {voltage} V is outside what the model is calibrated for "
            "(40 to 70 V, seed 003 Table 1)"
        )
    if not (math.isfinite(duration) and duration > 0 and after_breakup > 0):
        fail(f"durations must be positive, got {duration} µs and {after_breakup} µs")
    try:
        fluid = naalg(concentration)
    except ValueError as exc:
        fail(str(exc))
    with progress() as bar:
        task = bar.add_task(f"{fluid.name}, {voltage:g} V", total=round(duration))
        res = simulate_droplet(
            fluid,
            seed003_waveform(voltage),
            duration_s=duration * 1e-6,
            after_breakup_s=after_breakup * 1e-6,
            progress=lambda t: bar.update(task, completed=round(t * 1e6)),
        )
    summary = res.to_dict()
    _write_report(res, out)
    _json(summary, out / "droplet.json")
    if json_out is not None:
        _json(summary, json_out)
    else:
        console.print_json(json.dumps(summary, default=float))


def _write_report(res: Any, out: Path) -> None:
    from microfab.process.inkjet.acoustics import fig_nozzle_flow
    from microfab.process.inkjet.shadowgraph import Camera, fig_montage, render_sequence
    from microfab.report.canvas import save_figure

    out.mkdir(parents=True, exist_ok=True)
    save_figure(fig_nozzle_flow(res.flow, res.waveform), out / "nozzle_flow.png")
    sil = [s for s in res.silhouettes if s.bodies]
    if sil:
        reach = max(float(b[0][-1]) for s in sil for b in s.bodies)
        cam = Camera(pixel_size_m=2e-6, width_px=160, height_px=int(reach / 2e-6) + 40)
        frames = render_sequence(sil, cam, seed=0)
        save_figure(fig_montage(frames, [s.time_s for s in sil], cam), out / "silhouettes.png")


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
    from microfab.process.inkjet.imaging import analyze_folder, fig_analysis, load_frames
    from microfab.report.canvas import save_figure

    try:
        res = analyze_folder(
            frames_dir,
            pixel_size_m=None if pixel_size is None else pixel_size * 1e-6,
            frame_interval_s=None if frame_interval is None else frame_interval * 1e-6,
            nozzle_row=nozzle_row,
        )
    except (OSError, ValueError) as exc:
        fail(str(exc))
    if out is not None:
        frames, _ = load_frames(frames_dir)
        save_figure(fig_analysis(res, frames), out)
    _json(res.to_dict(), json_out)
