"""The simulated (twin) machine: limits, reproducibility, shapes."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import AxisLimits, LimitViolation
from microfab.machines.base import Machine, Measurement
from microfab.machines.galvo import GALVO_LIMITS, discrete_controller, galvo_twin
from microfab.machines.simulated import SimulatedMachine
from microfab.plants.galvo import default_galvo_axes
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


def test_measurement_shape_and_fields(square):
    m = galvo_twin(settle_periods=2)
    meas = m.run(square)
    assert isinstance(meas, Measurement)
    assert meas.output.shape == square.shape == (2500, 2)
    np.testing.assert_array_equal(meas.command, square)
    assert meas.axes == ("x", "y")
    assert meas.dt == m.dt
    assert meas.actuator is None
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
    for lp in m.loop.loops:
        np.testing.assert_array_equal(lp.state, 0.0)
    # neither the loop nor the noise generator moved: the next run equals a fresh machine's
    fresh = galvo_twin(seed=4)
    np.testing.assert_array_equal(m.run(square).output, fresh.run(square).output)
    # a refused command later on leaves the running machine where it was
    before = [lp.state.copy() for lp in m.loop.loops]
    n_before = m.samples_simulated
    fast = square.copy()
    fast[1000, 1] += 0.5  # a 0.5 V step in 1 us: 5e5 V/s > 5e4 V/s velocity limit
    with pytest.raises(LimitViolation, match=r"axis y: velocity"):
        m.run(fast)
    assert m.samples_simulated == n_before
    for b, lp in zip(before, m.loop.loops, strict=True):
        np.testing.assert_array_equal(lp.state, b)
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


def test_validation(square):
    axes = default_galvo_axes()
    plants = [a.discrete_plant() for a in axes.values()]
    ctrls = [discrete_controller(a) for a in axes.values()]
    with pytest.raises(ValueError, match="noise level"):
        SimulatedMachine(plants, ctrls, ("x", "y"), [1e-3], GALVO_LIMITS)
    with pytest.raises(ValueError, match="settle_periods"):
        SimulatedMachine(plants, ctrls, ("x", "y"), [1e-3, 1e-3], GALVO_LIMITS, settle_periods=-1)
    m = SimulatedMachine(plants, ctrls, ("x", "y"), [0.0, 0.0], GALVO_LIMITS)
    with pytest.raises(ValueError, match="2 columns"):
        m.run(square[:, :1])
    # an axis without declared limits is refused
    m = SimulatedMachine(
        plants,
        ctrls,
        ("x", "y"),
        [0.0, 0.0],
        {"x": AxisLimits(position=10, velocity=5e4, acceleration=2e10)},
    )
    with pytest.raises(LimitViolation, match="'y' has no declared limits"):
        m.run(square)
    assert m.samples_simulated == 0
