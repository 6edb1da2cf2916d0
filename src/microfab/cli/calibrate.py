"""``microfab calibrate galvo``: refit the galvo twin to seed 000 Table 1."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import console

__all__ = ["calibrate_app"]

calibrate_app = typer.Typer(no_args_is_help=True, help="Calibrate digital twins.")


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
