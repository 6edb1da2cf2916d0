from __future__ import annotations

import numpy as np
import pytest

from microfab.core.signals import Trace
from microfab.trajectory.base import Trajectory


def _traj(**kw):
    args = {"dt": 1e-3, "position": np.zeros((5, 2))} | kw
    return Trajectory(**args)


def test_arrays_are_read_only_float_copies():
    pos = np.arange(10).reshape(5, 2)
    vel = np.ones((5, 2))
    tr = _traj(position=pos, velocity=vel, s=np.arange(5))
    vel[0, 0] = 9.0
    for arr in (tr.position, tr.velocity, tr.s):
        assert arr.dtype == np.float64
        assert not arr.flags.writeable
    assert tr.velocity[0, 0] == 1.0
    assert tr.acceleration is None and tr.jerk is None
    assert tr.n_samples == 5
    np.testing.assert_array_equal(tr.time, np.arange(5) * 1e-3)


def test_to_trace_is_the_core_signal():
    tr = _traj(position=np.arange(10.0).reshape(5, 2))
    trace = tr.to_trace()
    assert isinstance(trace, Trace)
    assert (trace.dt, trace.axes, trace.unit) == (1e-3, ("x", "y"), "m")
    np.testing.assert_array_equal(trace.values, tr.position)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"dt": 0.0}, "dt must be positive"),
        ({"position": np.zeros((5, 3))}, r"position must have shape \(n_samples, 2\)"),
        ({"position": np.zeros(5)}, r"position must have shape .* got shape \(5,\)"),
        ({"position": np.zeros((0, 2))}, "position must hold at least 1 sample"),
        ({"velocity": np.zeros((4, 2))}, r"velocity must have shape \(5, 2\)"),
        ({"jerk": np.zeros((5, 1))}, r"jerk must have shape \(5, 2\)"),
        ({"s": np.zeros((5, 1))}, r"s must have shape \(5,\)"),
    ],
)
def test_shapes_are_checked(kw, match):
    with pytest.raises(ValueError, match=match):
        _traj(**kw)


@pytest.mark.parametrize("name", ["position", "velocity", "acceleration", "jerk"])
def test_non_finite_samples_name_field_axis_and_sample(name):
    arr = np.zeros((5, 2))
    arr[3, 1] = np.nan
    with pytest.raises(
        ValueError, match=rf"^{name} of axis 'y' must be finite, got nan at sample 3$"
    ):
        _traj(**{name: arr})


def test_non_finite_path_progress():
    with pytest.raises(ValueError, match=r"^s must be finite, got inf at sample 2$"):
        _traj(s=np.array([0.0, 1.0, np.inf, 3.0, 4.0]))
