"""The per-sample loop (numba and Python) and the vectorised LTI loop agree."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.base import Controller, LTIController
from microfab.machines.galvo.machine import discrete_controller
from microfab.plants.base import LTIPlant, Plant
from microfab.plants.galvo import GalvoAxis, default_galvo_axes
from microfab.plants.lti import DiscreteLTI, block_diag
from microfab.sim.loop import LoopState, is_compiled, simulate, simulate_python
from microfab.sim.lti_fast import BlockSimulator, LTILoop, closed_loop_ss
from microfab.trajectory.periodic import square_scan

FS = 1e6  # seed 000 §3.1: 1 Msps
RATE = 400  # seed 000 §4: 400 features/s
HALF = (1.0, 1.44)  # seed 000 §4.3: 1 V (x), 1.44 V (y)
SIGNALS = ("output", "measured", "command")


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.fixture(scope="module")
def axes() -> dict[str, GalvoAxis]:
    return default_galvo_axes()


@pytest.fixture(scope="module")
def names(axes) -> tuple[str, ...]:
    return tuple(axes)


@pytest.fixture(scope="module")
def ref_noise(axes):
    ref = np.tile(square_scan(RATE, HALF, FS), (4, 1))  # 4 periods = 10 000 samples
    rng = np.random.default_rng(20240611)
    sigma = np.array([a.noise_rms_v for a in axes.values()])
    return ref, rng.standard_normal(ref.shape) * sigma


@pytest.fixture(scope="module")
def per_sample(axes):
    """Both axes as one block-diagonal plant and controller for the per-sample loop."""
    plant = LTIPlant(block_diag(*(a.discrete_plant() for a in axes.values())))
    ctrl = LTIController(block_diag(*(discrete_controller(a) for a in axes.values())))
    return plant, ctrl


@pytest.fixture(scope="module")
def numba_run(per_sample, ref_noise, names):
    plant, ctrl = per_sample
    ref, noise = ref_noise
    return simulate(plant, ctrl, ref, noise, axes=names)


def make_loop(axes, names) -> LTILoop:
    return LTILoop(
        [a.discrete_plant() for a in axes.values()],
        [discrete_controller(a) for a in axes.values()],
        names,
    )


def test_components_have_kernels(per_sample):
    plant, ctrl = per_sample
    assert is_compiled(plant, ctrl)
    assert isinstance(plant, Plant)
    assert isinstance(ctrl, Controller)


def test_numba_loop_and_vectorised_loop_agree(numba_run, ref_noise, axes, names):
    """Acceptance criterion: 1e-9 relative on output, measured and command, 4 periods of
    the 400 features/s square with seeded noise."""
    ref, noise = ref_noise
    vec = make_loop(axes, names).run(ref, noise)
    for sig in SIGNALS:
        a, b = getattr(numba_run, sig), getattr(vec, sig)
        assert a.shape == b.shape == ref.shape
        assert rel_diff(a, b) <= 1e-9, (sig, rel_diff(a, b))
        for i in range(ref.shape[1]):  # per axis too (y's scale is larger than x's)
            assert rel_diff(a[:, i], b[:, i]) <= 1e-9, (sig, i)
    # the loop actually tracks: the signals are not trivially small
    assert np.max(np.abs(numba_run.output)) > 0.9
    np.testing.assert_array_equal(numba_run.measured, numba_run.output + noise)
    assert numba_run.axes == vec.axes == names
    assert numba_run.dt == vec.dt == pytest.approx(1e-6)


def test_python_loop_agrees_with_numba_loop(per_sample, ref_noise, numba_run):
    plant, ctrl = per_sample
    ref, noise = ref_noise
    n = 2000
    py = simulate_python(plant, ctrl, ref[:n], noise[:n])
    for sig in SIGNALS:
        a, b = getattr(py, sig), getattr(numba_run, sig)[:n]
        assert rel_diff(a, b) <= 1e-12, sig


def test_numba_loop_continues_from_final_state(per_sample, ref_noise, numba_run):
    plant, ctrl = per_sample
    ref, noise = ref_noise
    k = 3333
    first = simulate(plant, ctrl, ref[:k], noise[:k])
    assert isinstance(first.final_state, LoopState)
    kept = first.final_state.copy()
    second = simulate(plant, ctrl, ref[k:], noise[k:], state=first.final_state)
    for sig in SIGNALS:
        joined = np.vstack([getattr(first, sig), getattr(second, sig)])
        np.testing.assert_array_equal(joined, getattr(numba_run, sig))
    # continuing does not modify the state it continues from
    np.testing.assert_array_equal(first.final_state.plant, kept.plant)
    np.testing.assert_array_equal(first.final_state.controller, kept.controller)
    # and the Python loop continues from the compiled loop's state alike
    py = simulate_python(plant, ctrl, ref[k : k + 500], noise[k : k + 500], first.final_state)
    assert rel_diff(py.output, second.output[:500]) <= 1e-12


@pytest.mark.parametrize("split", [5001, 4992, 7])
def test_lti_loop_in_two_halves_equals_one_run(ref_noise, axes, names, split):
    ref, noise = ref_noise
    whole = make_loop(axes, names).run(ref, noise)
    loop = make_loop(axes, names)
    h1 = loop.run(ref[:split], noise[:split])
    h2 = loop.run(ref[split:], noise[split:])
    for sig in SIGNALS:
        joined = np.vstack([getattr(h1, sig), getattr(h2, sig)])
        assert rel_diff(joined, getattr(whole, sig)) <= 1e-12, sig
    for s1, s2 in zip(h2.final_state, whole.final_state, strict=True):
        np.testing.assert_allclose(s1, s2, rtol=1e-9, atol=1e-12 * np.max(np.abs(s2)))
    # reset returns to rest: the next run repeats the first
    loop.reset()
    again = loop.run(ref[:split], noise[:split])
    np.testing.assert_array_equal(again.output, h1.output)


def test_lti_loop_without_command(ref_noise, axes, names):
    ref, noise = ref_noise
    res = make_loop(axes, names).run(ref[:1000], noise[:1000], with_command=False)
    assert res.command is None
    full = make_loop(axes, names).run(ref[:1000], noise[:1000])
    # equal to rounding: without the command rows the output product has another shape,
    # and an OpenBLAS build may then sum in another order (seen: 2e-16 on 1e-5)
    np.testing.assert_allclose(
        res.output, full.output, rtol=1e-13, atol=1e-13 * np.abs(full.output).max()
    )


def test_lti_loop_validation(axes, names, ref_noise):
    ref, noise = ref_noise
    loop = make_loop(axes, names)
    with pytest.raises(ValueError, match="columns"):
        loop.run(ref[:100, :1])
    with pytest.raises(ValueError, match="noise"):
        loop.run(ref[:100], noise[:99])
    with pytest.raises(ValueError, match="one plant and one controller"):
        LTILoop([axes["x"].discrete_plant()], [], names)
    # a controller with the wrong sign makes the loop unstable
    c = discrete_controller(axes["x"])
    neg = DiscreteLTI(c.A, c.B, -c.C, -c.D, c.dt)
    with pytest.raises(ValueError, match="unstable"):
        LTILoop([axes["x"].discrete_plant()], [neg])


def test_block_simulator_matches_direct_recursion():
    rng = np.random.default_rng(5)
    A = np.diag([0.9, -0.5, 0.3]) + 0.05 * rng.standard_normal((3, 3))
    sys = DiscreteLTI(
        A,
        rng.standard_normal((3, 2)),
        rng.standard_normal((2, 3)),
        rng.standard_normal((2, 2)),
        1e-3,
    )
    u = rng.standard_normal((101, 2))
    x = np.zeros(3)
    y = np.empty((101, 2))
    for k in range(101):
        y[k] = sys.C @ x + sys.D @ u[k]
        x = sys.A @ x + sys.B @ u[k]
    bs = BlockSimulator(sys, block=8)
    np.testing.assert_allclose(bs.run(u), y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(bs.state, x, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="block"):
        BlockSimulator(sys, block=0)


def test_closed_loop_ss_validation(axes):
    p = axes["x"].discrete_plant()
    c = discrete_controller(axes["x"])
    with pytest.raises(ValueError, match="strictly proper"):
        closed_loop_ss(c, c)  # the Tustin controller has feed-through
    with pytest.raises(ValueError, match="controller must map"):
        closed_loop_ss(p, block_diag(c, c))


# -------------------------------------------------------- Python fallback path
class SaturatingIntegrator:
    """``x[k+1] = clip(x[k] + g dt u[k], -lim, lim)``, ``y = x``: no kernels."""

    n_inputs = 1
    n_outputs = 1

    def __init__(self, gain: float, limit: float, dt: float) -> None:
        self.gain, self.limit, self.dt = gain, limit, dt

    def init(self) -> np.ndarray:
        return np.zeros(1)

    def output(self, state: np.ndarray) -> np.ndarray:
        return state.copy()

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        return np.clip(state + self.gain * self.dt * command, -self.limit, self.limit)


def test_plant_without_kernels_runs_through_python_fallback():
    dt, gain, limit, kp = 1e-3, 50.0, 0.5, 4.0
    plant = SaturatingIntegrator(gain, limit, dt)
    assert isinstance(plant, Plant)
    # static proportional controller u = kp (r - y)
    ctrl = LTIController(
        DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[kp]], dt)
    )
    assert not is_compiled(plant, ctrl)
    n = 400
    ref = np.where(np.arange(n) < n // 2, 1.0, -0.2)  # steps beyond the saturation
    rng = np.random.default_rng(7)
    noise = 1e-3 * rng.standard_normal(n)
    res = simulate(plant, ctrl, ref, noise, axes=("s",))
    # independent reference implementation of the same recursion
    x, y, u = 0.0, np.empty(n), np.empty(n)
    for k in range(n):
        y[k] = x
        u[k] = kp * (ref[k] - (x + noise[k]))
        x = min(max(x + gain * dt * u[k], -limit), limit)
    np.testing.assert_allclose(res.output[:, 0], y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(res.command[:, 0], u, rtol=0, atol=1e-14)
    np.testing.assert_allclose(res.measured[:, 0], y + noise, rtol=0, atol=1e-15)
    # the nonlinearity is exercised: the output sits on the limit for a while
    assert np.isclose(res.output.max(), limit)
    assert np.sum(np.isclose(res.output[:, 0], limit)) > 50
    assert res.final_state.plant[0] == pytest.approx(x)
    assert res.axes == ("s",)


def test_simulate_validation(per_sample):
    plant, ctrl = per_sample
    with pytest.raises(ValueError, match="NaN"):
        simulate(plant, ctrl, np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match="reference"):
        simulate(plant, ctrl, np.zeros((0, 2)))
    with pytest.raises(ValueError, match="noise"):
        simulate(plant, ctrl, np.zeros((10, 2)), noise=np.zeros((10, 3)))
    with pytest.raises(ValueError, match="strictly proper"):
        LTIPlant(DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[1.0]], 1e-3))
