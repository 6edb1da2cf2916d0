"""The simulated (twin) machine: paths, run modes, limits, reproducibility, shapes."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.base import Delay, Loop, LTIController, LTIObserver
from microfab.core.limits import AxisLimits, LimitViolation
from microfab.machines.base import Machine, Measurement
from microfab.machines.galvo.machine import GALVO_LIMITS, discrete_controller, galvo_twin
from microfab.machines.simulated import EncoderNoise, Settling, SimPath, SimulatedMachine
from microfab.plants.base import LTIPlant
from microfab.plants.galvo import default_galvo_axes
from microfab.plants.lti import DiscreteLTI
from microfab.sim.lti_fast import LTILoop
from microfab.trajectory.periodic import square_scan

FS = 1e6  # seed 000 §3.1: 1 Msps
HALF = (1.0, 1.44)  # seed 000 §4.3: 1 V (x), 1.44 V (y)


@pytest.fixture(scope="module")
def square() -> np.ndarray:
    return square_scan(400, HALF, FS)  # seed 000 §4: 400 features/s, N = 2500


def test_twin_is_a_machine(square):
    m = galvo_twin()
    assert isinstance(m, Machine)
    assert m.axes == ("x", "y")
    assert m.dt == pytest.approx(1 / FS)
    assert m.limits == GALVO_LIMITS
    assert m.path is SimPath.LIFTED
    assert m.path == "lifted"


def test_measurement_shape_and_fields(square):
    m = galvo_twin(settle_periods=2)
    meas = m.run(square)
    assert isinstance(meas, Measurement)
    assert meas.output.shape == square.shape == (2500, 2)
    np.testing.assert_array_equal(meas.command, square)
    assert meas.axes == ("x", "y")
    assert meas.dt == m.dt
    assert meas.actuator is None
    assert meas.settled is None
    assert meas.n_samples == 2500
    np.testing.assert_allclose(meas.time[[0, -1]], [0.0, 2499e-6], rtol=1e-12)
    assert m.samples_simulated == 3 * square.shape[0]
    # tracks the square up to the feedback error (seed 000 Table 1: FB PP < 0.6 V)
    assert np.max(np.abs(meas.output - square)) < 0.6
    with_act = m.run(square, with_actuator=True)
    assert with_act.actuator is not None
    assert with_act.actuator.shape == square.shape
    assert m.samples_simulated == 6 * square.shape[0]


def test_command_beyond_limits_is_refused_without_advancing(square):
    m = galvo_twin(seed=4)
    too_big = 20.0 * square / np.abs(square).max()  # 20 V > the 10 V position limit
    with pytest.raises(LimitViolation, match=r"axis x: position"):
        m.run(too_big)
    assert m.samples_simulated == 0
    for st in m.state:
        np.testing.assert_array_equal(st, 0.0)
    # neither the loop nor the noise generator moved: the next run equals a fresh machine's
    fresh = galvo_twin(seed=4)
    np.testing.assert_array_equal(m.run(square).output, fresh.run(square).output)
    # a refused command later on leaves the running machine where it was
    before = m.state
    n_before = m.samples_simulated
    fast = square.copy()
    fast[1000, 1] += 0.5  # a 0.5 V step in 1 us: 5e5 V/s > 5e4 V/s velocity limit
    with pytest.raises(LimitViolation, match=r"axis y: velocity"):
        m.run(fast)
    assert m.samples_simulated == n_before
    for b, st in zip(before, m.state, strict=True):
        np.testing.assert_array_equal(st, b)
    np.testing.assert_array_equal(m.run(square).output, fresh.run(square).output)


def test_same_seed_same_measurement(square):
    a = galvo_twin(seed=123).run(square).output
    b = galvo_twin(seed=123).run(square).output
    c = galvo_twin(seed=124).run(square).output
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    # the seeds differ only by the encoder noise: a few noise sigmas at most
    sigma = max(ax.noise_rms_v for ax in default_galvo_axes().values())
    assert 0 < np.max(np.abs(a - c)) < 10 * sigma


def test_noise_level_matches_declared_rms(square):
    axes = default_galvo_axes()
    noisy = galvo_twin(axes, seed=9).run(square).output
    clean_axes = {k: a.with_calibration(noise_rms_v=0.0) for k, a in axes.items()}
    clean = galvo_twin(clean_axes, seed=9).run(square).output
    diff = noisy - clean
    for i, ax in enumerate(axes.values()):
        # 2500 samples: the sample std is within ~5 % of sigma with high probability
        assert np.std(diff[:, i]) == pytest.approx(ax.noise_rms_v, rel=0.1)


def test_machine_keeps_running_between_calls(square):
    # with no settling, the first period starts at rest and differs from the second
    m = galvo_twin(
        axes={k: a.with_calibration(noise_rms_v=0.0) for k, a in default_galvo_axes().items()},
        settle_periods=0,
    )
    first = m.run(square).output
    second = m.run(square).output
    third = m.run(square).output
    assert np.max(np.abs(first - second)) > 1e-3
    # periodic steady state is reached quickly: period 3 ~ period 2
    assert np.max(np.abs(third - second)) < 0.05 * np.max(np.abs(first - second))


def clean_axes() -> dict:
    return {k: a.with_calibration(noise_rms_v=0.0) for k, a in default_galvo_axes().items()}


def galvo_parts() -> tuple[list[LTIPlant], list[LTIController]]:
    axes = default_galvo_axes()
    return (
        [LTIPlant(a.discrete_plant()) for a in axes.values()],
        [LTIController(discrete_controller(a)) for a in axes.values()],
    )


def test_galvo_twin_reproduces_the_previous_machine_exactly(square):
    """The twin before the component rewrite: one LTILoop per axis, noise drawn per run as
    ``rng.standard_normal(shape) * rms``, once per settle period then for the recorded one."""
    axes = default_galvo_axes()
    loop = LTILoop(
        [a.discrete_plant() for a in axes.values()],
        [discrete_controller(a) for a in axes.values()],
        tuple(axes),
    )
    rng = np.random.default_rng(0)
    rms = np.array([a.noise_rms_v for a in axes.values()])

    def old_run(cmd, with_actuator=False):
        loop.run(cmd, rng.standard_normal(cmd.shape) * rms[None, :], with_command=False)
        res = loop.run(cmd, rng.standard_normal(cmd.shape) * rms[None, :], with_actuator)
        return res.measured, res.command

    m = galvo_twin(seed=0)
    other = square_scan(200, HALF, FS)
    for cmd, act in ((square, False), (square, True), (other, True), (square, False)):
        want_y, want_u = old_run(cmd, act)
        got = m.run(cmd, with_actuator=act)
        np.testing.assert_array_equal(got.output, want_y)
        if act:
            np.testing.assert_array_equal(got.actuator, want_u)


def test_path_selection():
    plants, ctrls = galvo_parts()
    lims = GALVO_LIMITS
    assert SimulatedMachine(plants, ctrls, axes=("x", "y"), limits=lims).path == "lifted"
    # a feedforward runs before the loop on every path: still lifted
    ff = [Loop(controller=c, feedforward=Delay(samples=3)) for c in ctrls]
    assert SimulatedMachine(plants, ff, axes=("x", "y"), limits=lims).path == "lifted"
    # an observer is not folded into the lifted model, but it is compiled
    ident = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), [[0.0, 1.0]], 1e-6)
    obs = [Loop(controller=c, observer=LTIObserver(ident, n_commands=1)) for c in ctrls]
    m = SimulatedMachine(plants, obs, axes=("x", "y"), limits=lims)
    assert m.path is SimPath.COMPILED
    # any part without kernels: Python
    sat = SaturatingPlant(gain=1e3, limit=1.0, dt=1e-6)
    m = SimulatedMachine([sat, plants[1]], ctrls, axes=("x", "y"), limits=lims)
    assert m.path is SimPath.PYTHON
    with pytest.raises(ValueError, match="lifted path needs an LTIPlant"):
        SimulatedMachine(plants, obs, axes=("x", "y"), limits=lims, path=SimPath.LIFTED)
    with pytest.raises(ValueError, match="compiled path needs Compiled"):
        SimulatedMachine([sat, plants[1]], ctrls, axes=("x", "y"), limits=lims, path="compiled")
    forced = SimulatedMachine(plants, ctrls, axes=("x", "y"), limits=lims, path=SimPath.PYTHON)
    assert forced.path is SimPath.PYTHON


@pytest.fixture(scope="module")
def three_paths(square):
    """The galvo twin forced down each path, same seed: periodic and one-shot runs."""
    ramp = np.linspace(0.0, 1.0, 800)[:, None] * np.array([[0.5, -0.7]])
    out = {}
    for path in SimPath:
        m = galvo_twin(seed=7, path=path)
        assert m.path is path
        fast = square_scan(1000, HALF, FS)  # 1000 samples per period; 2 periods played
        periodic = m.run(fast, with_actuator=True)
        once = m.run_once(ramp, with_actuator=True, settle_s=2e-3)
        out[path] = (periodic, once)
    return out


@pytest.mark.parametrize("mode", [0, 1], ids=["run", "run_once"])
def test_the_three_paths_agree(three_paths, mode):
    ref = three_paths[SimPath.LIFTED][mode]
    for path in (SimPath.COMPILED, SimPath.PYTHON):
        got = three_paths[path][mode]
        assert got.output.shape == ref.output.shape
        for field in ("output", "actuator"):
            a, b = getattr(got, field), getattr(ref, field)
            for i in range(2):
                err = np.max(np.abs(a[:, i] - b[:, i])) / np.max(np.abs(b[:, i]))
                assert err <= 1e-9, (path, field, i, err)
        np.testing.assert_array_equal(got.command, ref.command)
        assert got.settled == ref.settled


def ramp_hold(level: tuple[float, float], n_ramp: int = 500, n_hold: int = 300) -> np.ndarray:
    r = np.concatenate([np.linspace(0, 1, n_ramp), np.ones(n_hold)])
    return r[:, None] * np.asarray(level)[None, :]


def test_run_once_from_rest_settles_and_returns_the_whole_record(square):
    m = galvo_twin(axes=clean_axes())
    m.run(square)  # the machine is moving ...
    cmd = ramp_hold((0.5, -0.8))
    meas = m.run_once(cmd, with_actuator=True)
    # ... but run_once starts from rest: same as a fresh machine
    fresh = galvo_twin(axes=clean_axes()).run_once(cmd, with_actuator=True)
    np.testing.assert_array_equal(meas.output, fresh.output)
    st = Settling()
    dwell = round(st.dwell_s / m.dt)
    n = cmd.shape[0]
    assert meas.settled is True
    assert meas.n_samples > n
    assert (meas.n_samples - n) % dwell == 0  # held in dwell steps
    assert meas.n_samples - n <= round(st.max_hold_s / m.dt)
    np.testing.assert_array_equal(meas.command[:n], cmd)
    np.testing.assert_array_equal(meas.command[n:], np.repeat(cmd[-1:], meas.n_samples - n, 0))
    assert meas.actuator.shape == meas.output.shape
    np.testing.assert_array_equal(meas.output[0], 0.0)  # from rest
    # settled: the last dwell samples within the tolerance of the final command
    assert np.max(np.abs(meas.output[-dwell:] - cmd[-1])) <= st.tolerance
    # and not settled one dwell step earlier (the hold stopped as soon as it could)
    assert np.max(np.abs(meas.output[-2 * dwell : -dwell] - cmd[-1])) > st.tolerance
    assert meas.time[-1] == pytest.approx((meas.n_samples - 1) * m.dt)
    assert m.samples_simulated == 2 * square.shape[0] + meas.n_samples


def test_run_once_gives_up_after_the_longest_hold():
    m = galvo_twin(axes=clean_axes(), settle_periods=0)
    cmd = ramp_hold((0.5, -0.8), n_ramp=300, n_hold=0)
    meas = m.run_once(cmd, settle_s=250e-6)
    assert meas.settled is False
    assert meas.n_samples == 300 + 250
    tight = SimulatedMachine(
        *galvo_parts(),
        axes=("x", "y"),
        limits=GALVO_LIMITS,
        settling=Settling(tolerance=1e-12, dwell_s=1e-4, max_hold_s=5e-4),
    )
    meas = tight.run_once(cmd)
    assert meas.settled is False
    assert meas.n_samples == 300 + 500
    with pytest.raises(ValueError, match="settle_s"):
        m.run_once(cmd, settle_s=-1.0)


def test_run_once_refuses_limits_before_running(square):
    m = galvo_twin(seed=4)
    # the square starts at (-1, -1.44) V: a jump from rest in one sample (1e6 V/s)
    with pytest.raises(LimitViolation, match=r"axis x: velocity"):
        m.run_once(square)
    assert m.samples_simulated == 0
    with pytest.raises(LimitViolation, match=r"position"):
        m.run_once(ramp_hold((12.0, 0.0), n_ramp=5000))
    assert m.samples_simulated == 0
    # the noise generator did not move either
    cmd = ramp_hold((0.2, 0.3))
    np.testing.assert_array_equal(m.run_once(cmd).output, galvo_twin(seed=4).run_once(cmd).output)


def test_feedforward_runs_before_the_loop(square):
    plants, ctrls = galvo_parts()
    d = 40
    plain = SimulatedMachine(plants, ctrls, axes=("x", "y"), limits=GALVO_LIMITS)
    loops = [Loop(controller=c, feedforward=Delay(samples=d)) for c in ctrls]
    delayed = SimulatedMachine(plants, loops, axes=("x", "y"), limits=GALVO_LIMITS)
    # periodic: the delayed command is the period rotated by d samples
    a = plain.run(np.roll(square, d, axis=0)).output
    b = delayed.run(square).output
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    # one-shot: the response is delayed, and the record longer by d samples
    cmd = ramp_hold((0.5, -0.8))
    once = plain.run_once(cmd)
    later = delayed.run_once(cmd, settle_s=0.0)
    assert later.n_samples == cmd.shape[0] + d
    np.testing.assert_allclose(later.output[d:], once.output[: cmd.shape[0]], rtol=0, atol=1e-12)


class SaturatingPlant:
    """``x[k+1] = clip(x[k] + g dt u[k], -lim, lim)``, ``y = x``: a Python plant."""

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


def test_nonlinear_machine_runs_on_the_python_path():
    dt = 1e-4
    kp = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[20.0]], dt)
    lim = {"s": AxisLimits(position=2.0, velocity=1e4, acceleration=1e9)}
    m = SimulatedMachine(
        SaturatingPlant(gain=100.0, limit=0.6, dt=dt),
        LTIController(kp),
        EncoderNoise(rms=(1e-4,), seed=1),
        axes=("s",),
        limits=lim,
        settling=Settling(tolerance=1e-3, dwell_s=5e-3, max_hold_s=0.2),
    )
    assert m.path is SimPath.PYTHON
    cmd = np.concatenate([np.linspace(0, 1.0, 200), np.full(100, 1.0)])
    meas = m.run_once(cmd)
    # the output saturates at 0.6 and can never reach the 1.0 command
    assert meas.settled is False
    assert np.max(np.abs(meas.output - 0.6)) < 0.61
    assert meas.n_samples == 300 + 2000
    per = m.run(0.5 * np.sin(2 * np.pi * np.arange(400) / 400))
    assert per.output.shape == (400, 1)
    assert m.samples_simulated == 2300 + 2 * 400


def test_validation(square):
    plants, ctrls = galvo_parts()
    xy = ("x", "y")
    with pytest.raises(ValueError, match="noise level"):
        SimulatedMachine(plants, ctrls, EncoderNoise(rms=(1e-3,)), axes=xy, limits=GALVO_LIMITS)
    with pytest.raises(ValueError, match="settle_periods"):
        SimulatedMachine(plants, ctrls, axes=xy, limits=GALVO_LIMITS, settle_periods=-1)
    with pytest.raises(ValueError, match="one controller per plant"):
        SimulatedMachine(plants, ctrls[:1], axes=xy, limits=GALVO_LIMITS)
    with pytest.raises(ValueError, match="one axis name per plant output"):
        SimulatedMachine(plants, ctrls, axes=("x",), limits=GALVO_LIMITS)
    with pytest.raises(TypeError, match="not a Plant"):
        SimulatedMachine([object(), plants[1]], ctrls, axes=xy, limits=GALVO_LIMITS)
    with pytest.raises(ValueError, match="noise rms of axis 1"):
        EncoderNoise(rms=(1e-3, -1.0))
    with pytest.raises(ValueError, match="dwell_s must be positive"):
        Settling(dwell_s=0.0)
    with pytest.raises(ValueError, match="max_hold_s"):
        Settling(max_hold_s=float("nan"))
    m = SimulatedMachine(plants, ctrls, axes=xy, limits=GALVO_LIMITS)
    with pytest.raises(ValueError, match="2 columns"):
        m.run(square[:, :1])
    # an axis without declared limits is refused
    m = SimulatedMachine(
        plants,
        ctrls,
        axes=xy,
        limits={"x": AxisLimits(position=10, velocity=5e4, acceleration=2e10)},
    )
    with pytest.raises(LimitViolation, match="'y' has no declared limits"):
        m.run(square)
    assert m.samples_simulated == 0


def test_one_mimo_plant_is_one_loop(square):
    """Both axes as one block-diagonal plant and controller: same numbers, one loop."""
    from microfab.plants.lti import block_diag

    axes = default_galvo_axes()
    plant = LTIPlant(block_diag(*(a.discrete_plant() for a in axes.values())))
    ctrl = LTIController(block_diag(*(discrete_controller(a) for a in axes.values())))
    noise = EncoderNoise(rms=tuple(a.noise_rms_v for a in axes.values()), seed=3)
    m = SimulatedMachine(plant, ctrl, noise, axes=("x", "y"), limits=GALVO_LIMITS)
    assert m.path is SimPath.LIFTED
    assert len(m.state) == 1
    got = m.run(square).output
    want = galvo_twin(seed=3).run(square).output
    assert np.max(np.abs(got - want)) / np.max(np.abs(want)) <= 1e-9


@pytest.mark.parametrize("path", ["lifted", "compiled"])
def test_snapshot_and_restore_continue_bit_for_bit(square, path):
    """A machine restored from a JSON round trip of a snapshot runs on exactly as the
    original does (loops and noise generator)."""
    import json

    from microfab.machines.base import Resumable

    a = galvo_twin(seed=9, path=path)
    assert isinstance(a, Resumable)
    a.run(square)
    snap = json.loads(json.dumps(a.snapshot()))
    b = galvo_twin(seed=123, path=path)  # another seed: everything must come from snap
    b.restore(snap)
    for _ in range(2):
        np.testing.assert_array_equal(b.run(square).output, a.run(square).output)
    with pytest.raises(ValueError, match="another machine"):
        b.restore({"kind": "file"})
