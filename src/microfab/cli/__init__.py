"""The ``microfab`` command: one sub-command or group per module of this package.

``run``, ``kinds``, ``reproduce`` (`run.py`), ``ilc step`` (`ilc.py`), ``rc step``
(`rc.py`), ``nanomanipulator analyze`` (`nanomanipulator.py`), ``laser analyze``
(`laser.py`), ``calibrate`` (`calibrate.py`), ``path show`` and ``trajectory``
(`geometry.py`), ``droplet simulate``, ``droplet render`` and ``droplet analyze``
(`droplet.py`), ``droplet sweep``, ``droplet calibrate`` and ``droplet sensitivity``
(`droplet_studies.py`, registered on the ``droplet`` group when imported here),
``identify chirp``, ``identify linear`` and ``identify validate`` (`identify.py`),
``identify ann`` (`identify_ann.py`, registered on the ``identify`` group when imported
here), ``shaper design`` (`shaper.py`), ``slm scan-time``
(`slm.py`), ``stage excite`` (`stage.py`), ``optimize`` (`optimize.py`); `_kit.py` holds
the console, errors, progress bars, tables and the readers several groups share
(``LOW:HIGH`` ranges, measured traces); `_sigint.py` how a Ctrl-C is taken, from the
first import on, so that it always ends as one line and exit 130.
"""

from __future__ import annotations

import sys
from typing import Annotated, Any

from microfab.cli import _sigint

# A Ctrl-C while the command's modules load is held and answered once they are loaded
# (`microfab.cli._sigint`); the handler is Python's again when this module is imported.
_sigint.hold()
try:
    import typer

    from microfab.cli._kit import OneLineErrors, print_interrupted
    from microfab.cli.calibrate import calibrate_app
    from microfab.cli.droplet import droplet_app
    from microfab.cli.droplet_studies import sweep_cmd as _sweep_cmd  # noqa: F401 (registers them)
    from microfab.cli.geometry import path_app, trajectory_cmd
    from microfab.cli.identify import identify_app
    from microfab.cli.identify_ann import ann_cmd as _ann_cmd  # noqa: F401 (registers it)
    from microfab.cli.ilc import ilc_app
    from microfab.cli.laser import laser_app
    from microfab.cli.nanomanipulator import nanomanipulator_app
    from microfab.cli.optimize import optimize_cmd
    from microfab.cli.rc import rc_app
    from microfab.cli.run import kinds_cmd, reproduce_cmd, run_cmd
    from microfab.cli.shaper import shaper_app
    from microfab.cli.slm import slm_app
    from microfab.cli.stage import stage_app
finally:
    _INTERRUPTED_WHILE_LOADING = _sigint.pending()
    _sigint.restore()
if _INTERRUPTED_WHILE_LOADING:
    print_interrupted([a for a in sys.argv[1:] if a[:1] != "-"])
    sys.exit(130)

__all__ = ["app", "main"]

#: Help of the ``microfab`` command (plain text: it is shown as is when piped).
HELP = """From a part drawing and a micro-fabrication machine to machine commands.

Command groups: run (a job of any kind, default the galvo MSL twin; writes its report),
kinds (the job kinds and reproductions), reproduce NAME (a seed paper's tables beside
ours), ilc (learning on real hardware through files), rc (seed 001 repetitive control on
hardware through files), nanomanipulator (seed 001 metrics of a measured trace), laser
(seed 004 axis and contour errors of a measured trace), calibrate
(refit a twin), path (inspect a drawing), trajectory (a limit-safe reference along a
drawing), droplet (drop-on-demand inkjet: simulate, sweep, render, analyse frames),
identify (fit a model to a recorded chirp or to measured XY stage runs, validate it),
shaper (design an input shaper), slm (scan time of an SLM layer on the galvo twin), stage
(command files for the black-box XY stage).
"""

#: Piped or redirected output gets plain help, never wrapped (rich help in a terminal).
_PLAIN = not sys.stdout.isatty()
_SETTINGS = {"max_content_width": 10_000, "terminal_width": 10_000} if _PLAIN else {}
_MARKUP = None if _PLAIN else "rich"


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"microfab {version('microfab')}")
        except PackageNotFoundError:  # pragma: no cover - run from a source tree
            typer.echo("microfab (not installed)")
        raise typer.Exit()


class _Microfab(typer.Typer):
    """The ``microfab`` application: SIGINT held while typer builds the command.

    Building resolves every command's signature (seconds under load); a Ctrl-C then is
    raised when the command starts (`OneLineErrors.invoke`), as one line and exit 130.
    """

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        """Build and run the command (`typer.Typer.__call__`) with SIGINT held until it runs."""
        _sigint.hold()
        try:
            return super().__call__(*args, **kwargs)
        finally:
            _sigint.restore()  # no-op once the command took SIGINT over


app = _Microfab(
    cls=OneLineErrors,
    add_completion=False,
    no_args_is_help=True,
    help=HELP,
    rich_markup_mode=_MARKUP,
    context_settings=_SETTINGS,
)


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """From a part drawing and a micro-fabrication machine to machine commands."""


app.command("run")(run_cmd)
app.command("kinds")(kinds_cmd)
app.command("reproduce")(reproduce_cmd)
for _sub in (
    ilc_app,
    rc_app,
    nanomanipulator_app,
    laser_app,
    calibrate_app,
    path_app,
    droplet_app,
    identify_app,
    shaper_app,
    slm_app,
    stage_app,
):
    _sub.rich_markup_mode = _MARKUP
app.add_typer(ilc_app, name="ilc", context_settings=_SETTINGS)
app.add_typer(rc_app, name="rc", context_settings=_SETTINGS)
app.add_typer(nanomanipulator_app, name="nanomanipulator", context_settings=_SETTINGS)
app.add_typer(laser_app, name="laser", context_settings=_SETTINGS)
app.add_typer(calibrate_app, name="calibrate", context_settings=_SETTINGS)
app.add_typer(path_app, name="path", context_settings=_SETTINGS)
app.add_typer(droplet_app, name="droplet", context_settings=_SETTINGS)
app.add_typer(identify_app, name="identify", context_settings=_SETTINGS)
app.add_typer(shaper_app, name="shaper", context_settings=_SETTINGS)
app.add_typer(slm_app, name="slm", context_settings=_SETTINGS)
app.add_typer(stage_app, name="stage", context_settings=_SETTINGS)
app.command("trajectory")(trajectory_cmd)
app.command("optimize")(optimize_cmd)


def main() -> None:  # pragma: no cover - entry point
    """Console entry point."""
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
