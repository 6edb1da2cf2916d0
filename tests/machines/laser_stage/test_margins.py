"""Axis-loop margins of the seed 004 stage: finite, sensible, and true to the closed loop."""

from __future__ import annotations

import numpy as np

import control
from microfab.machines.laser_stage.machine import (
    ControlSettings,
    TwinSettings,
    axis_loop,
    axis_margins,
)
from microfab.machines.laser_stage.machine import controller as make_controller
from microfab.machines.laser_stage.machine import twin as make_stage
from microfab.report.contour import margins_table


def _setup():
    stage = make_stage(TwinSettings())
    return stage, make_controller(ControlSettings(law="preview-dob"), stage)


def test_default_loops_have_margins_and_a_modest_sensitivity_peak():
    stage, ctrl = _setup()
    ms = axis_margins(stage, ctrl)
    assert [m.axis for m in ms] == ["x", "y"]
    for m in ms:
        assert m.margins.pm_deg > 30.0 and m.margins.gm_db > 6.0
        assert 0.0 < m.sensitivity_peak_db < 6.0
    assert "crossover" in " ".join(margins_table(ms).columns)


def test_the_gain_margin_is_where_the_closed_loop_reaches_the_unit_circle():
    stage, ctrl = _setup()
    m = axis_margins(stage, ctrl)[0].margins
    loop = axis_loop(stage, ctrl, 0)
    sys = control.ss(loop.A, loop.B, loop.C, loop.D, loop.dt)

    def worst_pole(k: float) -> float:
        # the loop carries the plant's integrator, cancelled in the feedback (a pole left
        # at z = 1 by any gain): the other poles decide stability
        p = control.feedback(k * sys, 1).poles()
        return float(np.max(np.abs(p[np.abs(p - 1.0) > 1e-6])))

    assert worst_pole(1.0) < 1.0
    k = 10 ** (m.gm_db / 20)
    assert worst_pole(0.98 * k) < 1.0 < worst_pole(1.02 * k)
