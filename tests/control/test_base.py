"""Control components: reference window, LTI controller and observer, Delay, Loop."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numba import njit

from microfab.control.base import (
    CompiledController,
    CompiledObserver,
    Controller,
    Delay,
    Feedforward,
    Loop,
    LTIController,
    LTIObserver,
    Observer,
    ReferenceWindow,
    as_loop,
)
from microfab.plants.lti import DiscreteLTI
from microfab.trajectory.base import Trajectory

DT = 1e-3


def pi_controller() -> DiscreteLTI:
    # u = 2 e + 0.5 * sum(e): one integrator state
    return DiscreteLTI([[1.0]], [[1.0]], [[0.5]], [[2.0]], DT)


def test_reference_window_fields_and_validation():
    pos = np.arange(6.0).reshape(3, 2)
    w = ReferenceWindow(position=pos, velocity=np.ones((3, 2)))
    assert w.preview == 3
    assert w.n_axes == 2
    assert w.acceleration is None and w.jerk is None
    with pytest.raises(ValueError, match="position must be shaped"):
        ReferenceWindow(position=np.zeros(3))
    with pytest.raises(ValueError, match="position must be shaped"):
        ReferenceWindow(position=np.zeros((0, 2)))
    with pytest.raises(ValueError, match="velocity must be shaped like position"):
        ReferenceWindow(position=pos, velocity=np.zeros((2, 2)))
    with pytest.raises(AttributeError):
        w.position = pos  # type: ignore[misc]  # frozen


def test_reference_window_from_stacked_array():
    R = np.arange(2 * 3 * 2, dtype=float).reshape(2, 3, 2)  # preview 2, pos+vel+acc, 2 axes
    w = ReferenceWindow.from_array(R)
    np.testing.assert_array_equal(w.position, R[:, 0])
    np.testing.assert_array_equal(w.velocity, R[:, 1])
    np.testing.assert_array_equal(w.acceleration, R[:, 2])
    assert w.jerk is None
    assert np.shares_memory(w.position, R)  # a view, no copy


def test_lti_controller_step_is_error_feedback():
    c = LTIController(pi_controller())
    assert isinstance(c, Controller)
    assert isinstance(c, CompiledController)
    assert c.preview == 1
    s0 = c.init()
    win = ReferenceWindow(position=np.array([[1.0], [99.0]]))  # only row 0 is used
    u, s1 = c.step(s0, win, np.array([0.25]))
    assert u == pytest.approx([2.0 * 0.75])
    assert s1[0] == pytest.approx(0.75)
    np.testing.assert_array_equal(s0, 0.0)  # the given state is not modified
    u2, _ = c.step(s1, win, np.array([0.25]))
    assert u2 == pytest.approx([2.0 * 0.75 + 0.5 * 0.75])


def test_lti_observer_filters_command_and_measurement():
    # est = 0.5 * x + 0.5 * m, x <- 0.5 x + u: inputs [u, m]
    sys = DiscreteLTI([[0.5]], [[1.0, 0.0]], [[0.5]], [[0.0, 0.5]], DT)
    obs = LTIObserver(sys, n_commands=1)
    assert isinstance(obs, Observer)
    assert isinstance(obs, CompiledObserver)
    assert obs.n_outputs == 1
    s = obs.init()
    est, s = obs.step(s, np.array([2.0]), np.array([4.0]))
    assert est == pytest.approx([2.0])
    est, s = obs.step(s, np.array([0.0]), np.array([0.0]))
    assert est == pytest.approx([1.0])
    with pytest.raises(ValueError, match="n_commands"):
        LTIObserver(sys, n_commands=3)


def test_delay_feedforward():
    traj = Trajectory(
        dt=DT,
        position=np.column_stack([np.arange(5.0), -np.arange(5.0)]),
        velocity=np.ones((5, 2)),
        s=np.arange(5.0),
    )
    d = Delay(samples=2)
    assert isinstance(d, Feedforward)
    out = d.apply(traj)
    assert out.n_samples == 7
    np.testing.assert_array_equal(out.position[:3, 0], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(out.position[2:], traj.position)
    np.testing.assert_array_equal(out.velocity[:2], 0.0)
    np.testing.assert_array_equal(out.s[:3], 0.0)
    assert out.acceleration is None
    assert Delay(samples=0).apply(traj) is traj
    with pytest.raises(ValueError, match="delay must be an integer >= 0"):
        Delay(samples=-1)


@njit
def _dummy_step(p, x, ref, k, ym, u):  # pragma: no cover - never run
    u[0] = 0.0


class _PreviewOnly:
    preview = 3

    def init(self) -> Any:
        return None

    def step(self, state, window, measurement):
        return window.position[-1], state


def test_loop_is_data_and_validates():
    c = LTIController(pi_controller())
    lp = Loop(controller=c, feedforward=Delay(samples=1))
    assert lp.preview == 1
    assert lp.observer is None
    assert as_loop(lp) is lp
    assert as_loop(c).controller is c
    assert Loop(controller=_PreviewOnly()).preview == 3
    with pytest.raises(TypeError, match="controller must have"):
        Loop(controller=object())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="feedforward must have"):
        Loop(controller=c, feedforward=object())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="observer must have"):
        Loop(controller=c, observer=object())  # type: ignore[arg-type]
    bad = _PreviewOnly()
    bad.preview = 0
    with pytest.raises(ValueError, match="preview must be an integer >= 1"):
        Loop(controller=bad)
    with pytest.raises(AttributeError):
        lp.controller = c  # type: ignore[misc]  # frozen


def test_compiled_controller_without_kernel_is_refused():
    class NoKernel(CompiledController):
        preview = 1

        def init(self) -> np.ndarray:
            return np.zeros(0)

    with pytest.raises(TypeError, match=r"NoKernel .* 'kernel_step'"):
        NoKernel()

    class PythonKernel(NoKernel):
        kernel_step = staticmethod(lambda p, x, r, k, ym, u: None)  # not numba

    with pytest.raises(TypeError, match="numba"):
        PythonKernel()

    class WithKernel(NoKernel):
        kernel_step = _dummy_step

        def __init__(self) -> None:
            self.params = np.zeros(2)

    ok = WithKernel()
    assert ok.kernels() == (_dummy_step,)
    np.testing.assert_array_equal(ok.packed_params(), [0.0, 0.0])
    ok.params = np.zeros(2, dtype=np.float32)
    with pytest.raises(TypeError, match="1-D float64"):
        ok.packed_params()
    ok.params = np.array([np.nan])
    with pytest.raises(ValueError, match="NaN"):
        ok.packed_params()


def test_packed_params_checks_writeable_params_at_every_call():
    class WithKernel(CompiledController):
        preview = 1
        kernel_step = _dummy_step

        def init(self) -> np.ndarray:
            return np.zeros(0)

    ok = WithKernel()
    ok.params = np.zeros(2)  # writeable: checked every time
    ok.packed_params()
    ok.params[0] = np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        ok.packed_params()
    frozen = np.zeros(2)
    frozen.setflags(write=False)
    ok.params = frozen
    assert ok.packed_params() is frozen
    frozen.setflags(write=True)  # made writeable again: checked again
    frozen[1] = np.nan
    with pytest.raises(ValueError, match="NaN or inf"):
        ok.packed_params()
