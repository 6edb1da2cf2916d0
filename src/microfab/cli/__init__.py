"""The ``microfab`` command.

``microfab run [JOB.toml]``        run a job of any kind (default: galvo MSL twin), write its report
``microfab kinds``                 the job kinds and reproductions microfab knows
``microfab reproduce NAME``        a seed paper's tables beside ours
``microfab ilc step TRIAL ...``    one ILC step on real hardware through files
``microfab calibrate galvo``       refit the galvo twin to seed 000 Table 1
``microfab path show DRAWING``     picture and summary of a drawing's contours
``microfab trajectory DRAWING``    a limit-safe sampled reference along a drawing
``microfab droplet ...``           drop-on-demand inkjet: simulate, sweep, analyse frames
"""

from __future__ import annotations

import sys

import typer

from microfab.cli._kit import OneLineErrors
from microfab.cli.calibrate import calibrate_app
from microfab.cli.droplet import droplet_app
from microfab.cli.geometry import path_app, trajectory_cmd
from microfab.cli.ilc import ilc_app
from microfab.cli.run import kinds_cmd, reproduce_cmd, run_cmd

__all__ = ["app", "main"]

app = typer.Typer(cls=OneLineErrors, add_completion=False, no_args_is_help=True, help=__doc__)
app.command("run")(run_cmd)
app.command("kinds")(kinds_cmd)
app.command("reproduce")(reproduce_cmd)
app.add_typer(ilc_app, name="ilc")
app.add_typer(calibrate_app, name="calibrate")
app.add_typer(path_app, name="path")
app.add_typer(droplet_app, name="droplet")
app.command("trajectory")(trajectory_cmd)


def main() -> None:  # pragma: no cover - entry point
    """Console entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
