"""Components through the per-sample loops: nonlinear plant, preview, observer, feedforward."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from numba import njit

from microfab.control.base import (
    CompiledController,
    Controller,
    Delay,
    Loop,
    LTIController,
    LTIObserver,
    ReferenceWindow,
)
from microfab.core.compiled import pack_lti
from microfab.plants.base import LTIPlant, Plant
from microfab.plants.lti import DiscreteLTI
from microfab.sim.loop import (
    LoopStepper,
    filter_reference,
    is_compiled,
    reference_array,
    simulate,
    simulate_python,
)

DT = 1e-3


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


# ------------------------------------------------------------------ nonlinear plant
class CubicSpringMass:
    """Mass on a hardening spring: ``m a = u - k x - k3 x^3 - c v`` (semi-implicit Euler).

    A plain Python plant (no kernels); its state is a tuple ``(x, v)``.
    """

    n_inputs = 1
    n_outputs = 1

    def __init__(self, k: float, k3: float, c: float, m: float, dt: float) -> None:
        self.k, self.k3, self.c, self.m, self.dt = k, k3, c, m, dt

    def init(self) -> tuple[float, float]:
        return (0.0, 0.0)

    def output(self, state: tuple[float, float]) -> np.ndarray:
        return np.array([state[0]])

    def update(self, state: tuple[float, float], command: np.ndarray) -> tuple[float, float]:
        x, v = state
        a = (float(command[0]) - self.k * x - self.k3 * x**3 - self.c * v) / self.m
        v = v + self.dt * a
        return (x + self.dt * v, v)


def p_controller(kp: float) -> LTIController:
    return LTIController(
        DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[kp]], DT)
    )


def run_cubic(amplitude: float, noise: np.ndarray | None = None):
    plant = CubicSpringMass(k=100.0, k3=4e5, c=8.0, m=1.0, dt=DT)
    ref = amplitude * np.sin(2 * np.pi * 3.0 * np.arange(600) * DT)
    return plant, simulate(plant, p_controller(300.0), ref, noise, axes=("z",))


def test_nonlinear_python_plant_runs_through_the_python_loop():
    plant, res = run_cubic(0.05, 1e-4 * np.random.default_rng(2).standard_normal(600))
    assert isinstance(plant, Plant)
    assert not is_compiled(plant, p_controller(1.0))
    # independent recursion of the same loop
    ref = 0.05 * np.sin(2 * np.pi * 3.0 * np.arange(600) * DT)
    noise = 1e-4 * np.random.default_rng(2).standard_normal(600)
    x = v = 0.0
    y = np.empty(600)
    for k in range(600):
        y[k] = x
        u = 300.0 * (ref[k] - (x + noise[k]))
        v += DT * (u - 100.0 * x - 4e5 * x**3 - 8.0 * v)
        x += DT * v
    np.testing.assert_allclose(res.output[:, 0], y, rtol=0, atol=1e-15)
    assert res.final_state.plant == pytest.approx((x, v))
    assert res.axes == ("z",)


def test_the_cubic_spring_is_really_nonlinear():
    _, small = run_cubic(0.001)
    _, large = run_cubic(0.05)
    lin = 50.0 * small.output
    # 50x the amplitude is not 50x the response: the cubic term stiffens the spring
    assert np.max(np.abs(large.output - lin)) > 0.05 * np.max(np.abs(lin))


# ------------------------------------------------------------------ preview controllers
class WindowSpy:
    """Commands nothing; records every window it is shown."""

    def __init__(self, preview: int) -> None:
        self.preview = preview
        self.seen: list[ReferenceWindow] = []

    def init(self) -> Any:
        return 0

    def step(self, state: Any, window: ReferenceWindow, measurement: np.ndarray):
        self.seen.append(window)
        return np.zeros(1), state + 1


@pytest.mark.parametrize("periodic", [True, False])
def test_preview_controller_sees_the_next_samples(periodic):
    plant = LTIPlant(DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[0.0]], DT))
    spy = WindowSpy(preview=4)
    assert isinstance(spy, Controller)
    ref = np.arange(10.0)[:, None] ** 2
    vel = 2 * np.arange(10.0)[:, None]
    res = simulate(plant, spy, ref, derivatives=[vel], periodic=periodic)
    assert res.final_state.controller == 10
    assert len(spy.seen) == 10
    for k, w in enumerate(spy.seen):
        assert w.preview == 4
        assert w.acceleration is None
        for i in range(4):
            j = k + i
            if j < 10:
                want_p, want_v = ref[j], vel[j]
            elif periodic:  # the command repeats
                want_p, want_v = ref[j - 10], vel[j - 10]
            else:  # the last position is held, at rest
                want_p, want_v = ref[-1], 0.0
            np.testing.assert_array_equal(w.position[i], want_p)
            np.testing.assert_array_equal(w.velocity[i], want_v)


@njit
def preview_p_step(p, x, ref, k, ym, u):
    """``u = kp (r[k + P - 1] - y) + kv v[k + P - 1]``: acts on the reference P-1 ahead."""
    kp, kv, P = p[0], p[1], int(p[2])
    j = k + P - 1
    u[0] = kp * (ref[j, 0, 0] - ym[0]) + kv * ref[j, 1, 0]


class PreviewP(CompiledController):
    """Proportional control on the reference ``preview - 1`` samples ahead, plus velocity."""

    kernel_step: ClassVar[Any] = preview_p_step

    def __init__(self, kp: float, kv: float, preview: int) -> None:
        self.preview = preview
        self.params = np.array([kp, kv, float(preview)])

    def init(self) -> np.ndarray:
        return np.zeros(0)

    def step(self, state, window, measurement):
        kp, kv = self.params[:2]
        u = kp * (window.position[-1] - measurement) + kv * window.velocity[-1]
        return u, state


@pytest.fixture(scope="module")
def preview_setup():
    plant = LTIPlant(DiscreteLTI([[0.95]], [[0.05]], [[1.0]], [[0.0]], DT))
    t = np.arange(400) * DT
    ref = np.sin(2 * np.pi * 5 * t)[:, None]
    vel = (2 * np.pi * 5 * np.cos(2 * np.pi * 5 * t))[:, None]
    noise = 1e-3 * np.random.default_rng(4).standard_normal((400, 1))
    return plant, ref, vel, noise


def test_compiled_preview_controller_matches_python_and_looks_ahead(preview_setup):
    plant, ref, vel, noise = preview_setup
    ctrl = PreviewP(kp=2.0, kv=0.01, preview=6)
    assert is_compiled(plant, ctrl)
    fast = simulate(plant, ctrl, ref, noise, derivatives=[vel], periodic=True)
    slow = simulate_python(plant, ctrl, ref, noise, derivatives=[vel], periodic=True)
    for sig in ("output", "measured", "command"):
        assert rel_diff(getattr(fast, sig), getattr(slow, sig)) <= 1e-12, sig
    # a change at sample 200 reaches the command 5 samples earlier, and no sooner
    bumped = ref.copy()
    bumped[200] += 0.3
    other = simulate(plant, ctrl, bumped, noise, derivatives=[vel], periodic=True)
    np.testing.assert_array_equal(other.command[:195], fast.command[:195])
    assert other.command[195, 0] == pytest.approx(fast.command[195, 0] + 2.0 * 0.3)


def test_preview_needs_the_derivatives_it_reads(preview_setup):
    plant, ref, _, _ = preview_setup
    with pytest.raises(ValueError, match="velocity must be shaped"):
        simulate(plant, PreviewP(kp=1.0, kv=0.0, preview=2), ref, derivatives=[np.zeros((3, 1))])


# ------------------------------------------------------------------ observer
def test_observer_runs_compiled_and_in_python(preview_setup):
    plant, ref, _, noise = preview_setup
    # measurement low-pass est[k] = 0.7 est[k-1] + 0.3 m[k] (feed-through), no command input
    lp = DiscreteLTI([[0.7]], [[0.0, 0.3]], [[0.7]], [[0.0, 0.3]], DT)
    loop = Loop(controller=p_controller(3.0), observer=LTIObserver(lp, n_commands=1))
    assert is_compiled(plant, loop)
    fast = simulate(plant, loop, ref, noise)
    slow = simulate_python(plant, loop, ref, noise)
    for sig in ("output", "measured", "command"):
        assert rel_diff(getattr(fast, sig), getattr(slow, sig)) <= 1e-12, sig
    # the controller sees the filtered measurement: not what it sees without the observer
    plain = simulate(plant, p_controller(3.0), ref, noise)
    assert np.max(np.abs(plain.command - fast.command)) > 1e-3
    # an observer passing the measurement straight through changes nothing
    ident = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), [[0.0, 1.0]], DT)
    same = simulate(
        plant, Loop(controller=p_controller(3.0), observer=LTIObserver(ident, 1)), ref, noise
    )
    np.testing.assert_allclose(same.command, plain.command, rtol=0, atol=1e-15)


def test_observer_sees_the_previous_command(preview_setup):
    plant, ref, _, _ = preview_setup

    class CommandEcho:
        """Estimate = measurement; records the command it is given."""

        n_outputs = 1

        def __init__(self) -> None:
            self.commands: list[float] = []

        def init(self) -> Any:
            return None

        def step(self, state, command, measurement):
            self.commands.append(float(command[0]))
            return measurement, state

    echo = CommandEcho()
    res = simulate(plant, Loop(controller=p_controller(2.0), observer=echo), ref[:50])
    assert echo.commands[0] == 0.0  # at rest
    np.testing.assert_array_equal(echo.commands[1:], res.command[:-1, 0])


# ------------------------------------------------------------------ feedforward, helpers
def test_feedforward_delay_in_the_loop(preview_setup):
    plant, ref, _, _ = preview_setup
    d = 7
    base = simulate(plant, p_controller(2.0), ref)
    delayed = simulate(plant, Loop(controller=p_controller(2.0), feedforward=Delay(samples=d)), ref)
    assert delayed.output.shape[0] == ref.shape[0] + d
    np.testing.assert_allclose(delayed.output[d:], base.output, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(delayed.output[: d + 1], 0.0)  # ref[0] = 0: at rest
    with pytest.raises(ValueError, match="noise must be shaped"):
        simulate(
            plant,
            Loop(controller=p_controller(2.0), feedforward=Delay(samples=d)),
            ref,
            np.zeros_like(ref),
        )
    # periodic: the delay is a rotation of the period
    pos, derivs = filter_reference(Delay(samples=d), ref, DT, periodic=True)
    np.testing.assert_array_equal(pos, np.roll(ref, d, axis=0))
    assert derivs == ()


def test_reference_array_layout_and_checks():
    pos = np.arange(8.0).reshape(4, 2)
    vel = -pos
    R = reference_array(pos, [vel], preview=3, periodic=False)
    assert R.shape == (6, 2, 2)
    assert not R.flags.writeable
    np.testing.assert_array_equal(R[:4, 0], pos)
    np.testing.assert_array_equal(R[4:, 0], [pos[-1], pos[-1]])
    np.testing.assert_array_equal(R[4:, 1], 0.0)
    Rp = reference_array(pos, [vel], preview=3, periodic=True)
    np.testing.assert_array_equal(Rp[4:, 0], pos[:2])
    np.testing.assert_array_equal(Rp[4:, 1], vel[:2])
    # a preview longer than the reference wraps as often as needed
    np.testing.assert_array_equal(
        reference_array(pos[:2], preview=5, periodic=True)[:, 0], pos[[0, 1, 0, 1, 0, 1]]
    )
    with pytest.raises(ValueError, match="preview"):
        reference_array(pos, preview=0)
    with pytest.raises(ValueError, match="NaN"):
        reference_array(np.array([[np.inf]]))
    with pytest.raises(ValueError, match="at most 3"):
        reference_array(pos, [vel, vel, vel, vel])


def test_pack_lti_layout():
    p = pack_lti(np.eye(2), np.ones((2, 1)), np.ones((1, 2)), np.zeros((1, 1)))
    assert p.dtype == np.float64
    np.testing.assert_array_equal(p[:3], [2, 1, 1])
    assert p.size == 3 + 4 + 2 + 2 + 1


def test_stepper_in_pieces_equals_one_simulate_call():
    plant = LTIPlant(DiscreteLTI([[0.95, 0.01], [-0.5, 0.9]], [[0.0], [0.1]], [[1.0, 0.0]],
                                 [[0.0]], DT))  # fmt: skip
    ctrl = p_controller(3.0)
    rng = np.random.default_rng(0)
    ref = np.sin(np.arange(700) * 0.02)[:, None]
    noise = 1e-3 * rng.standard_normal((700, 1))
    whole = simulate(plant, ctrl, ref, noise)
    stepper = LoopStepper(plant, ctrl, ref, noise)
    for m in (1, 0, 250, 3, 10_000):
        stepper.advance(m)
    assert stepper.position == 700 and stepper.advance(5) == 700
    got = stepper.result()
    for name in ("output", "measured", "command", "reference"):
        np.testing.assert_array_equal(getattr(got, name), getattr(whole, name), err_msg=name)
    np.testing.assert_array_equal(got.final_state.plant, whole.final_state.plant)
    part = LoopStepper(plant, ctrl, ref, noise)
    part.advance(300)
    mid = part.result()  # a copy of the state: advancing further does not change it
    before = np.array(mid.final_state.plant)
    part.advance()
    np.testing.assert_array_equal(mid.final_state.plant, before)
    assert mid.output.shape == (300, 1)
    with pytest.raises(ValueError, match="n_samples"):
        part.advance(-1)


def test_stepper_refuses_a_python_loop():
    plant = CubicSpringMass(k=100.0, k3=4e5, c=8.0, m=1.0, dt=DT)
    with pytest.raises(TypeError, match="use simulate"):
        LoopStepper(plant, p_controller(1.0), np.zeros((5, 1)))
