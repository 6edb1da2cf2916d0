"""``microfab calibrate galvo|nanomanipulator|laser``: refit a twin to its seed's numbers."""

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


@calibrate_app.command("nanomanipulator")
def calibrate_nanomanipulator_cmd(
    write: Annotated[
        Path | None, typer.Option(help="Write a twin data file with the fitted noise here.")
    ] = None,
    job: Annotated[
        Path | None, typer.Option(help="Fit on this nanomanipulator-msl job (default: seed's).")
    ] = None,
) -> None:
    """Fit the nanomanipulator twin's sensor noise to seed 001 §4.2's axial RMS."""
    from microfab.cli._kit import fail
    from microfab.experiments.seed001_nanomanipulator.calibration import fit_noise, write_noise
    from microfab.experiments.seed001_nanomanipulator.run import JobConfig

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
        fit = fit_noise(
            config,
            progress=lambda k, s, a: console.print(
                f"run {k}: noise {s[0]:.1f} / {s[1]:.1f} nm -> axial RMS {a[0]:.1f} / {a[1]:.1f} nm"
            ),
        )
    except ValueError as exc:
        fail(str(exc))
    ex, ey = fit.axial_error_pct
    console.print(
        f"noise x {fit.noise_rms_nm[0]:.1f} nm, y {fit.noise_rms_nm[1]:.1f} nm; axial RMS "
        f"{fit.axial_rms_nm[0]:.1f} / {fit.axial_rms_nm[1]:.1f} nm ({ex:+.2f} %, {ey:+.2f} %; "
        "seed 485.8 / 885.8); contour RMS (prediction) "
        f"{fit.contour_rms_nm:.1f} nm ({fit.contour_error_pct:+.1f} %; seed 769.5)"
    )
    if write is not None:
        src = None if config is None else config.twin.params_file
        write_noise(fit, write, source=src)
        console.print(f"wrote {write}")


@calibrate_app.command("laser")
def calibrate_laser_cmd(
    write: Annotated[
        Path | None,
        typer.Option(help="Write a stage twin data file with the fitted disturbance scale here."),
    ] = None,
) -> None:
    """Fit the seed 004 stage twin's disturbance scale to Fig. 3's 0.8 µm peak error."""
    from microfab.cli._kit import fail
    from microfab.experiments.seed004_laser.calibration import fit_disturbance_scale, write_scale

    try:
        fit = fit_disturbance_scale(
            progress=lambda k, s, p: console.print(
                f"run {k}: disturbance scale {s:.4g} -> peak {p:.3f} µm"
            )
        )
    except ValueError as exc:
        fail(str(exc))
    fx, fy = (v * 100 for v in fit.fraction_below)
    console.print(
        f"disturbance scale {fit.scale:.4g}: peak {fit.peak_um[0]:.3f} / {fit.peak_um[1]:.3f} "
        f"µm (x / y; seed 0.8, the larger fitted); within ±0.5 µm {fx:.1f} / {fy:.1f} % "
        "(the check; seed 'generally')"
    )
    if write is not None:
        write_scale(fit, write)
        console.print(f"wrote {write}")
