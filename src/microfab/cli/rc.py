"""``microfab rc step``: one period of the seed 001 plug-in RC on hardware through files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_outputs, console, fail
from microfab.cli._options import integer, number, refuse_unused
from microfab.experiments.seed001_nanomanipulator.keys import (
    PATTERN_PERIOD_S,
    RC_GAIN,
    RC_LEAD_SAMPLES,
    RC_TAU_MS,
)
from microfab.io.lock import hold_for_command

__all__ = ["ONE_PERIOD_HINT", "rc_app"]

#: What a second step on a state another step is writing should do (it is refused).
ONE_PERIOD_HINT = (
    "one period at a time: let it finish, then measure the command it writes (this trial "
    "was measured on the command it replaces, so it is not learned from)"
)

#: Options the first call takes and the state keeps (refused on a later step).
FIRST_CALL = ("tau_ms", "gain", "lead_samples")

rc_app = typer.Typer(no_args_is_help=True, help="Plug-in repetitive control on hardware.")


@rc_app.command("step")
def rc_step_cmd(
    ctx: typer.Context,
    trial: Annotated[
        Path,
        typer.Argument(
            help="One measured period (.csv, .mat, .h5): time [s], ref_x, ref_y (the "
            "uncorrected contour), x, y [mm]."
        ),
    ],
    state: Annotated[Path, typer.Option("--state", help="RC state directory.")],
    out: Annotated[
        Path,
        typer.Option("--out", help="Next command file: time, command_x/y = ref + correction [mm]."),
    ],
    tau_ms: Annotated[
        float | None,
        number(help="Time constant of Q(s) = 1/(tau s + 1) (first call; 1.59).", key=RC_TAU_MS),
    ] = None,
    gain: Annotated[
        float | None, number(help="Learning gain k_r (first call; 1).", key=RC_GAIN)
    ] = None,
    lead_samples: Annotated[
        int | None,
        integer(help="Phase lead, below the trial's period (first call; 0).", key=RC_LEAD_SAMPLES),
    ] = None,
    period_s: Annotated[
        float | None,
        number(help="Contour period to check the trial against.", key=PATTERN_PERIOD_S),
    ] = None,
) -> None:
    """Learn from one measured period and write the next command (seed 001 Fig. 6).

    The first call creates the state (the trial must have run on the plain contour); the
    state is the simulated RC's (PluginRC.save_state), so a twin run can be continued.
    The options marked (first call) are kept in the state: on a later step they are refused.
    """
    check_outputs(folders={"--state": state}, files={"--out": out}, inputs={"TRIAL": trial})
    # one period at a time, locked before the state is read (never wait: see ilc step)
    hold_for_command(state, "--state", on_refused=fail, hint=ONE_PERIOD_HINT)
    from microfab.io.xy_trace import read_measured
    from microfab.machines.nanomanipulator.files import STATE_FILE, rc_file_step

    if (state / STATE_FILE).exists():
        kept = f"on a later step: the state in {state} keeps the settings it was started with"
        refuse_unused(ctx, FIRST_CALL, f"{kept} (start a new --state to change them)")
    elif lead_samples is not None:  # read before anything is written: the period bounds it
        try:
            n = read_measured(trial).n_samples
        except (OSError, ValueError) as exc:
            fail(str(exc))
        if lead_samples >= n:
            fail(f"--lead-samples {lead_samples} is not below the trial's period of {n} "
                 "samples: the lead is a shift within one period")  # fmt: skip
    try:
        rep = rc_file_step(
            trial,
            state,
            out,
            tau_s=None if tau_ms is None else tau_ms * 1e-3,
            gain=gain,
            lead_samples=lead_samples,
            period_s=period_s,
        )
    except (OSError, ValueError) as exc:
        fail(str(exc))
    x, y = rep.rms_nm
    cx, cy = rep.correction_rms_nm
    made = " (new state)" if rep.created else ""
    console.print(
        f"period {rep.period}{made}: RMS error x {x:.1f} nm, y {y:.1f} nm; next correction "
        f"RMS x {cx:.1f} nm, y {cy:.1f} nm; wrote {rep.out_path}",
        highlight=False,
    )
