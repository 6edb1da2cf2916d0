"""Stability margins and sensitivity of each axis loop of the seed 004 stage.

The loop is broken at the plant input (the current reference): ``L = −C_fb P`` with ``P``
the twin's linear axis (true mass and force constant, amplifier lag, ZOH at the sample
time: `LMWStage.linear_model`) and ``C_fb`` the controller's path from the measured
position to the current (`PreviewDOB.linear_model`, input ``x_fb``: position and velocity
feedback and the disturbance observer together). Margins are read off the frequency
response (`microfab.control.margins.loop_margins`); the sensitivity peak is
``max |1 / (1 + L)|`` on the same grid. The contour compensator adds its normal gains on
top along the path normal (its own check, `microfab.control.contour.check_normal_gains`);
these are the axis loops alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import control
from microfab.control.margins import LoopMargins, loop_margins
from microfab.control.preview_dob import PreviewDOB
from microfab.plants.lmw_stage import LMWStage
from microfab.plants.lti import DiscreteLTI
from microfab.report.tables import Table

__all__ = ["AxisMargins", "axis_loop", "axis_margins", "margins_table"]


@dataclass(frozen=True, kw_only=True)
class AxisMargins:
    """Margins of one axis loop.

    Attributes
    ----------
    axis : str
        ``"x"`` or ``"y"``.
    margins : LoopMargins
        Gain and phase margins and their frequencies.
    sensitivity_peak_db : float
        ``max |S|``, dB.
    sensitivity_peak_hz : float
        Where it occurs, Hz.
    """

    axis: str
    margins: LoopMargins
    sensitivity_peak_db: float
    sensitivity_peak_hz: float


def _ss(sys: DiscreteLTI) -> control.StateSpace:
    return control.ss(sys.A, sys.B, sys.C, sys.D, sys.dt)


def axis_loop(stage: LMWStage, controller: PreviewDOB, axis: int) -> DiscreteLTI:
    """``L = −C_fb P`` of axis ``axis`` (0: x, 1: y), broken at the current reference."""
    plant = stage.linear_model().channel(axis, axis)
    c_fb = controller.linear_model(axis).channel(0, 3)
    loop = -control.series(_ss(plant), _ss(c_fb))
    return DiscreteLTI(loop.A, loop.B, loop.C, loop.D, stage.dt)


def axis_margins(
    stage: LMWStage, controller: PreviewDOB, n_points: int = 20_000
) -> tuple[AxisMargins, ...]:
    """`AxisMargins` of both axes (module notes)."""
    out = []
    for a, name in enumerate("xy"):
        loop = axis_loop(stage, controller, a)
        m = loop_margins(loop, n_points=n_points)
        f = np.geomspace(1.0, 0.999 / (2 * stage.dt), n_points)
        s = 1.0 / np.abs(1.0 + loop.frequency_response(f)[:, 0, 0])
        i = int(np.argmax(s))
        out.append(
            AxisMargins(
                axis=name,
                margins=m,
                sensitivity_peak_db=float(20 * np.log10(s[i])),
                sensitivity_peak_hz=float(f[i]),
            )
        )
    return tuple(out)


def margins_table(margins: tuple[AxisMargins, ...]) -> Table:
    """The margins as a report table."""
    return Table(
        title="Axis loops (preview + DOB on the twin's linear axis), broken at the current",
        columns=("axis", "crossover [Hz]", "phase margin [°]", "gain margin [dB]",
                 "at [Hz]", "max |S| [dB]", "at [Hz]"),
        rows=[
            (
                m.axis,
                f"{m.margins.pm_freq_hz:.1f}",
                f"{m.margins.pm_deg:.1f}",
                f"{m.margins.gm_db:.1f}",
                f"{m.margins.gm_freq_hz:.0f}",
                f"{m.sensitivity_peak_db:.2f}",
                f"{m.sensitivity_peak_hz:.0f}",
            )
            for m in margins
        ],
        note="The plant is the twin's true axis (mass and force constant 10 % off the "
        "controller's nominal) with its amplifier lag; friction and saturation left out.",
    )  # fmt: skip
