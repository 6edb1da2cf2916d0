"""``microfab laser analyze``: seed 004 figures of merit from a measured trace."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import console, fail, print_table

__all__ = ["laser_app"]

laser_app = typer.Typer(no_args_is_help=True, help="The seed 004 laser micromachining stage.")


@laser_app.command("analyze")
def analyze_cmd(
    trace: Annotated[
        Path,
        typer.Argument(
            help="Measured run (.csv, .mat, .h5): time [s], ref_x, ref_y, x, y [m]; "
            "optional current_x, current_y [A]."
        ),
    ],
    drawing: Annotated[
        str, typer.Option(help="The drawing the reference came from (file or shape source).")
    ],
    contour: Annotated[int, typer.Option(help="Which closed contour of the drawing.")] = 0,
    reference_tol_um: Annotated[
        float, typer.Option(help="Largest distance of the reference to the drawing [µm].")
    ] = 1.0,
    out: Annotated[
        Path | None, typer.Option(help="Write report.html and its figures here.")
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the figures as JSON here.")
    ] = None,
) -> None:
    """Axis and contour errors of a measured trace against the exact drawing (seed 004)."""
    from microfab.experiments.seed004_laser.analyze import (
        analysis_table,
        analyze_file,
        write_analysis,
    )
    from microfab.io.atomic import atomic_write_json

    if not reference_tol_um > 0:
        fail(f"--reference-tol-um must be positive, got {reference_tol_um:g} µm")
    try:
        a = analyze_file(trace, drawing, contour, reference_tol_m=reference_tol_um * 1e-6)
    except (OSError, ValueError) as exc:
        fail(f"{trace}: {exc}")
    print_table(analysis_table(a))
    if json_path is not None:
        atomic_write_json(json_path, a.summary())
        console.print(f"wrote {json_path}")
    if out is not None:
        console.print(f"report: {write_analysis(a, out, f'Measured trace {trace.name}')}")
