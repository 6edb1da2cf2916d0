"""Tests of `SetPoint`, the pass-through controller of set-position plants."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.base import ReferenceWindow
from microfab.control.setpoint import SetPoint, setpoint_step
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI
from microfab.sim.loop import simulate, simulate_python


def test_kernel_and_python_step_copy_the_reference():
    c = SetPoint(3)
    ref = np.arange(24.0).reshape(4, 2, 3)  # (samples, orders, axes)
    u = np.empty(3)
    setpoint_step(c.packed_params(), c.init(), ref, 2, np.full(3, 99.0), u)
    np.testing.assert_array_equal(u, ref[2, 0])
    v, state = c.step(c.init(), ReferenceWindow.from_array(ref[2:3]), np.full(3, 99.0))
    np.testing.assert_array_equal(v, ref[2, 0])
    assert state.size == 0 and c.preview == 1


def test_open_loop_run_equals_the_plant_driven_by_the_reference():
    sys = DiscreteLTI([[0.9, 0.1], [0.0, 0.8]], [[0.0], [0.2]], [[1.0, 0.0]], [[0.0]], 1e-3)
    plant = LTIPlant(sys)
    r = np.sin(np.arange(50) / 5.0)[:, None]
    out = simulate(plant, SetPoint(1), r)
    np.testing.assert_allclose(
        out.output, simulate_python(plant, SetPoint(1), r).output, atol=1e-12
    )
    x, y = np.zeros(2), []
    for u in r[:, 0]:
        y.append(sys.C @ x)
        x = sys.A @ x + sys.B[:, 0] * u
    np.testing.assert_allclose(out.output, np.array(y), atol=1e-12)


def test_needs_at_least_one_axis():
    with pytest.raises(ValueError, match="n_axes must be an integer >= 1"):
        SetPoint(0)
