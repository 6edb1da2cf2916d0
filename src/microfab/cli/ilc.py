"""``microfab ilc step``: one ILC step on real hardware through files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_outputs, console, fail
from microfab.cli._options import choice, number, refuse_unused
from microfab.experiments.seed000_msl.keys import ILC_CUTOFF_HZ, ILC_GAIN
from microfab.io.lock import hold_for_command

__all__ = ["ONE_STEP_HINT", "ilc_app"]

#: What a second step on a state another step is writing should do (it is refused).
ONE_STEP_HINT = (
    "one step at a time: let it finish, then measure the input it writes (this trial "
    "was measured on the input it replaces, so it is not learned from)"
)

#: Bounds of the declared limits, in the trial's input unit (assumed: 1e5 times the galvo
#: twin's 10 V, 5e4 V/s and 2e10 V/s² (`microfab.machines.galvo.GALVO_LIMITS`), room for an
#: input in the counts of a converter of up to 20 bits (5e4 counts per V), while a limit
#: no scanner input reaches in any unit is refused).
MAX_POSITION = 1e6
MAX_VELOCITY = 5e9
MAX_ACCELERATION = 2e15
#: Longest P-type advance, µs (assumed: a scanner's loop lags its input by micro- to
#: milliseconds; the trial's period bounds it too, checked against the trial).
MAX_ADVANCE_US = 1e6
#: Options the first call takes and the state keeps (refused on a later step).
FIRST_CALL = ("cutoff_hz", "gain", "law", "frf", "axis_gain", "advance_us")


def _laws() -> object:
    """The update laws (`microfab.control.ilc.Law`), imported when first needed."""
    from microfab.control.ilc import Law

    return Law


ilc_app = typer.Typer(no_args_is_help=True, help="Iterative learning control on hardware.")


@ilc_app.command("step")
def ilc_step_cmd(
    ctx: typer.Context,
    trial: Annotated[
        Path, typer.Argument(help="Measured trial: time, reference_<a>, input_<a>, output_<a>.")
    ],
    state: Annotated[Path, typer.Option("--state", help="Learning-state directory.")],
    out: Annotated[Path, typer.Option("--out", help="Next input file (.csv, .mat, .h5).")],
    cutoff_hz: Annotated[
        float,
        number(help="Highest learned harmonic (first call).", key=ILC_CUTOFF_HZ),
    ] = 8000.0,
    gain: Annotated[float, number(help="Learning gain rho (first call).", key=ILC_GAIN)] = 0.4,
    max_position: Annotated[
        float | None,
        number(
            help="Declared |input| limit.",
            unit="(input unit)",
            low=0.0,
            low_open=True,
            high=MAX_POSITION,
        ),
    ] = None,
    max_velocity: Annotated[
        float | None,
        number(
            help="Declared slope limit.",
            unit="(input unit)/s",
            low=0.0,
            low_open=True,
            high=MAX_VELOCITY,
        ),
    ] = None,
    max_acceleration: Annotated[
        float | None,
        number(
            help="Declared acceleration limit.",
            unit="(input unit)/s²",
            low=0.0,
            low_open=True,
            high=MAX_ACCELERATION,
        ),
    ] = None,
    frf: Annotated[
        Path | None,
        typer.Option(
            help="Measured FRF file (freq_hz, re_<a>, im_<a> or mag_<a>, phase_deg_<a>) to "
            "invert instead of the first trial (first call)."
        ),
    ] = None,
    law: Annotated[
        str, choice(choices=_laws, help="Update law (first call); inverse is seed 000 eq. 7.")
    ] = "inverse",
    advance_us: Annotated[
        float | None,
        number(
            help="P-type time advance, shorter than the trial's period (default: the lag "
            "seen in trial 1; first call).",
            unit="µs",
            low=0.0,
            high=MAX_ADVANCE_US,
        ),
    ] = None,
    axis_gain: Annotated[
        list[str] | None,
        typer.Option(help="Gain of one axis, AXIS=GAIN, repeatable (first call)."),
    ] = None,
) -> None:
    """Learn from one measured trial and write the next input (state kept in --state).

    The first call takes the inverse model from the trial (seed 000 eq. 7). Limits default to
    the galvo twin's (10 V, 5e4 V/s, 2e10 V/s^2) on the first call and are kept in the state.
    The options marked (first call) are kept in the state too: on a later step they are
    refused, as is --advance-us with --law inverse.
    """
    check_outputs(
        folders={"--state": state},
        files={"--out": out},
        inputs={"TRIAL": trial, "--frf": frf, "--state": state / "ilc_state.npz"},
    )
    # one step at a time, locked before the state is read; never wait: this trial was
    # measured on the input the state held, which the running step is replacing
    hold_for_command(state, "--state", on_refused=fail, hint=ONE_STEP_HINT)
    from microfab.control.ilc import FrequencyILC, ILCConfig
    from microfab.core.limits import AxisLimits
    from microfab.machines.files import ilc_step, read_trial_file
    from microfab.machines.galvo import machine as galvo

    try:
        first = not FrequencyILC.exists(state)
    except ValueError as exc:
        fail(str(exc))
    if not first:
        kept = f"on a later step: the state in {state} keeps the settings it was started with"
        refuse_unused(ctx, FIRST_CALL, f"{kept} (start a new --state to change them)")
    if law == "inverse":
        refuse_unused(ctx, ["advance_us"], "with --law inverse (it is the P-type law's advance)")
    gains: dict[str, float] = {}
    for item in axis_gain or []:
        name, sep, value = item.partition("=")
        try:
            gains[name.strip()] = float(value)
        except ValueError:
            fail(f"--axis-gain takes AXIS=GAIN, e.g. y=0.2; got {item!r}")
        if not sep or not name.strip():
            fail(f"--axis-gain takes AXIS=GAIN, e.g. y=0.2; got {item!r}")
        if ILC_GAIN.outside(gains[name.strip()]):
            fail(f"--axis-gain {item}: the gain is outside the allowed range "
                 f"{ILC_GAIN.range_text()}")  # fmt: skip
    try:  # read before anything is written: the period bounds the advance
        measured = read_trial_file(trial)
    except (OSError, ValueError) as exc:
        fail(str(exc))
    period_us = measured.reference.shape[0] * measured.dt * 1e6
    if advance_us is not None and advance_us >= period_us:
        fail(f"--advance-us {advance_us:g} µs is not shorter than the trial's period of "
             f"{period_us:g} µs: the advance is a shift within one period")  # fmt: skip
    try:
        config = ILCConfig(
            cutoff_hz=cutoff_hz,
            gain=gain,
            axis_gains=gains or None,
            law=law,  # type: ignore[arg-type]  # checked by ILCConfig
            advance_s=None if advance_us is None else advance_us * 1e-6,
        )
        given = (max_position, max_velocity, max_acceleration)
        limits = None
        if any(v is not None for v in given) or first:
            base = galvo.limits()["x"]
            lim = AxisLimits(
                position=max_position if max_position is not None else base.position,
                velocity=max_velocity if max_velocity is not None else base.velocity,
                acceleration=max_acceleration
                if max_acceleration is not None
                else base.acceleration,
                unit=base.unit,
            )
            limits = {a: lim for a in measured.axes}
        rep = ilc_step(trial, state, out, config=config, limits=limits, frf_path=frf)
    except (OSError, ValueError) as exc:
        fail(str(exc))
    for event in rep.events:
        console.print(f"monitor: {event}", highlight=False)
    rms = ", ".join(f"{a} {v:.4g}" for a, v in rep.rms.items())
    console.print(
        f"iteration {rep.iteration}: RMS error {rms}; harmonics "
        f"{', '.join(f'{a} {n}' for a, n in rep.harmonics.items())}; wrote {rep.out_path}",
        highlight=False,
    )
