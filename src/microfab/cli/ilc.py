"""``microfab ilc step``: one ILC step on real hardware through files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_option, check_outputs, console, fail
from microfab.io.lock import hold_for_command

__all__ = ["ONE_STEP_HINT", "ilc_app"]

#: What a second step on a state another step is writing should do (it is refused).
ONE_STEP_HINT = (
    "one step at a time: let it finish, then measure the input it writes (this trial "
    "was measured on the input it replaces, so it is not learned from)"
)

ilc_app = typer.Typer(no_args_is_help=True, help="Iterative learning control on hardware.")


@ilc_app.command("step")
def ilc_step_cmd(
    trial: Annotated[
        Path, typer.Argument(help="Measured trial: time, reference_<a>, input_<a>, output_<a>.")
    ],
    state: Annotated[Path, typer.Option("--state", help="Learning-state directory.")],
    out: Annotated[Path, typer.Option("--out", help="Next input file (.csv, .mat, .h5).")],
    cutoff_hz: Annotated[
        float, typer.Option(help="Highest learned harmonic [Hz] (first call).")
    ] = 8000.0,
    gain: Annotated[float, typer.Option(help="Learning gain rho (first call).")] = 0.4,
    max_position: Annotated[
        float | None, typer.Option(help="Declared |input| limit [unit].")
    ] = None,
    max_velocity: Annotated[
        float | None, typer.Option(help="Declared slope limit [unit/s].")
    ] = None,
    max_acceleration: Annotated[
        float | None, typer.Option(help="Declared [unit/s^2] limit.")
    ] = None,
    frf: Annotated[
        Path | None,
        typer.Option(
            help="Measured FRF file (freq_hz, re_<a>, im_<a> or mag_<a>, phase_deg_<a>) to "
            "invert instead of the first trial (first call)."
        ),
    ] = None,
    law: Annotated[
        str, typer.Option(help="Update law: 'inverse' (seed 000) or 'p-type' (first call).")
    ] = "inverse",
    advance_us: Annotated[
        float | None,
        typer.Option(help="P-type time advance [µs] (default: the lag seen in trial 1)."),
    ] = None,
    axis_gain: Annotated[
        list[str] | None,
        typer.Option(help="Gain of one axis, AXIS=GAIN, repeatable (first call)."),
    ] = None,
) -> None:
    """Learn from one measured trial and write the next input (state kept in --state).

    The first call takes the inverse model from the trial (seed 000 eq. 7). Limits default to
    the galvo twin's (10 V, 5e4 V/s, 2e10 V/s^2) on the first call and are kept in the state.
    """
    check_outputs(
        folders={"--state": state},
        files={"--out": out},
        inputs={"TRIAL": trial, "--frf": frf, "--state": state / "ilc_state.npz"},
    )
    # one step at a time, locked before the state is read; never wait: this trial was
    # measured on the input the state held, which the running step is replacing
    hold_for_command(state, "--state", on_refused=fail, hint=ONE_STEP_HINT)
    from microfab.control.ilc import ILCConfig
    from microfab.core.limits import AxisLimits
    from microfab.machines import galvo
    from microfab.machines.files import ilc_step

    check_option("--cutoff-hz", cutoff_hz, "Hz")
    check_option("--gain", gain, "", high=2.0)
    check_option("--max-position", max_position, "(input unit)")
    check_option("--max-velocity", max_velocity, "(input unit)/s")
    check_option("--max-acceleration", max_acceleration, "(input unit)/s²")
    check_option("--advance-us", advance_us, "µs", low_closed=True)
    if law not in ("inverse", "p-type"):
        fail(f"--law must be 'inverse' or 'p-type', got {law!r}")
    gains: dict[str, float] = {}
    for item in axis_gain or []:
        name, sep, value = item.partition("=")
        try:
            gains[name.strip()] = float(value)
        except ValueError:
            fail(f"--axis-gain takes AXIS=GAIN, e.g. y=0.2; got {item!r}")
        if not sep or not name.strip():
            fail(f"--axis-gain takes AXIS=GAIN, e.g. y=0.2; got {item!r}")
        check_option(f"--axis-gain {name.strip()}", gains[name.strip()], "", high=2.0)
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
        if any(v is not None for v in given) or not (state / "ilc_state.npz").exists():
            base = galvo.limits()["x"]
            lim = AxisLimits(
                position=max_position if max_position is not None else base.position,
                velocity=max_velocity if max_velocity is not None else base.velocity,
                acceleration=max_acceleration
                if max_acceleration is not None
                else base.acceleration,
                unit=base.unit,
            )
            from microfab.machines.files import read_trial_file

            limits = {a: lim for a in read_trial_file(trial).axes}
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
