"""Declared machine limits: every command is checked before anything is emitted."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import AxisLimits, LimitViolation, check_command

DT = 1e-3
N = 1000  # one period of 1 s


def sine(amplitude: float) -> np.ndarray:
    """One period of ``A sin(2 pi t)``: |x| <= A, |v| ~ 2 pi A, |a| ~ (2 pi)^2 A."""
    return amplitude * np.sin(2 * np.pi * np.arange(N) / N)


LOOSE = AxisLimits(position=10.0, velocity=1e3, acceleration=1e5)


def test_command_inside_limits_passes():
    x = sine(1.0)  # |x| 1, |v| ~6.28, |a| ~39.5
    lim = AxisLimits(position=1.01, velocity=6.3, acceleration=39.6)
    check_command(x, DT, {"x": lim}, ("x",))
    check_command(np.column_stack([x, 0.5 * x]), DT, {"x": lim, "y": lim}, ("x", "y"))


@pytest.mark.parametrize(
    ("limits", "quantity"),
    [
        (AxisLimits(position=0.99, velocity=1e3, acceleration=1e5), "position"),
        (AxisLimits(position=10.0, velocity=6.2, acceleration=1e5), "velocity"),
        (AxisLimits(position=10.0, velocity=1e3, acceleration=39.0), "acceleration"),
    ],
)
def test_each_quantity_beyond_its_limit_is_refused(limits, quantity):
    x = sine(1.0)
    with pytest.raises(LimitViolation, match=rf"axis x: {quantity} ") as exc:
        check_command(x, DT, {"x": limits}, ("x",))
    msg = str(exc.value)
    assert "exceeds the declared limit" in msg
    assert "nothing was emitted" in msg
    assert isinstance(exc.value, ValueError)


def test_violation_names_the_offending_axis():
    ok = sine(0.1)
    bad = sine(20.0)
    lims = {"x": LOOSE, "y": LOOSE}
    with pytest.raises(LimitViolation, match=r"axis y: position -?20"):
        check_command(np.column_stack([ok, bad]), DT, lims, ("x", "y"))
    with pytest.raises(LimitViolation, match=r"axis x: position"):
        check_command(np.column_stack([bad, ok]), DT, lims, ("x", "y"))


def test_velocity_value_and_sample_in_message():
    # a ramp of slope 2 unit/s with one 0.01 jump at sample 500: velocity 10 /s there
    x = 2.0 * DT * np.arange(N) - 1.0
    x[500:] += 0.01
    lim = AxisLimits(position=10.0, velocity=5.0, acceleration=1e9)
    pattern = r"velocity 12 V/s .* limit 5 V/s at t = 0.499 s \(near sample 499\)"
    with pytest.raises(LimitViolation, match=pattern):
        check_command(x, DT, {"x": lim}, ("x",), periodic=False)
    # periodic: the same sample, in the command's own numbering (not the padded one)
    spike = np.zeros(N)
    spike[500] = 0.012  # +12 /s from sample 499 to 500, then -12 /s
    with pytest.raises(LimitViolation, match=pattern):
        check_command(spike, DT, {"x": lim}, ("x",), periodic=True)


def test_periodic_index_of_an_acceleration_peak_is_the_command_sample():
    x = np.zeros(N)
    x[7] = 1e-3  # a spike: the acceleration peaks at sample 7
    lim = AxisLimits(position=1.0, velocity=1e9, acceleration=1.0)
    for periodic in (False, True):
        with pytest.raises(LimitViolation, match=r"acceleration .* \(near sample 7\)"):
            check_command(x, DT, {"x": lim}, ("x",), periodic=periodic)


def test_periodic_wrap_counts():
    # a sawtooth is smooth within the period but jumps from +1 to -1 at the wrap
    x = np.linspace(-1.0, 1.0, N)
    lim = AxisLimits(position=1.5, velocity=10.0, acceleration=1e9)
    check_command(x, DT, {"x": lim}, ("x",), periodic=False)  # slope ~2 unit/s
    with pytest.raises(LimitViolation, match="velocity"):
        check_command(x, DT, {"x": lim}, ("x",), periodic=True)  # jump of 2 in 1 ms


def test_missing_axis_is_refused():
    with pytest.raises(LimitViolation, match=r"axis 'z' has no declared limits"):
        check_command(np.column_stack([sine(0.1), sine(0.1)]), DT, {"x": LOOSE}, ("x", "z"))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_command_is_refused(bad):
    x = sine(0.1)
    x[17] = bad
    with pytest.raises(LimitViolation, match="NaN or inf"):
        check_command(x, DT, {"x": LOOSE}, ("x",))


def test_short_commands():
    # one sample: only the position can be checked without wrapping
    check_command(np.array([[0.5]]), DT, {"x": LOOSE}, ("x",), periodic=False)
    with pytest.raises(LimitViolation, match="position"):
        check_command(np.array([[11.0]]), DT, {"x": LOOSE}, ("x",), periodic=False)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"position": 0.0, "velocity": 1.0, "acceleration": 1.0}, "position"),
        ({"position": 1.0, "velocity": -1.0, "acceleration": 1.0}, "velocity"),
        ({"position": 1.0, "velocity": 1.0, "acceleration": np.nan}, "acceleration"),
    ],
)
def test_axis_limits_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        AxisLimits(**kwargs)


# ---------------------------------------------------------------- MachineLimits
from microfab.core.limits import MachineLimits, check_trajectory  # noqa: E402
from microfab.trajectory.base import Trajectory  # noqa: E402


def _line_traj(x: np.ndarray, dt: float, at_rest: bool = True) -> Trajectory:
    return Trajectory(dt=dt, position=np.column_stack([x, np.zeros_like(x)]), at_rest=at_rest)


def test_machine_limits_validation() -> None:
    with pytest.raises(ValueError, match="workspace of axis x"):
        MachineLimits(workspace=((1, 0), (0, 1)), velocity=(1, 1), acceleration=(1, 1))
    with pytest.raises(ValueError, match="acceleration limit of axis y must be positive"):
        MachineLimits(workspace=((0, 1), (0, 1)), velocity=(1, 1), acceleration=(1, -1))
    with pytest.raises(ValueError, match="one entry per axis"):
        MachineLimits(workspace=((0, 1),), velocity=(1, 1), acceleration=(1, 1))
    lim = MachineLimits.seed002_stage()
    assert lim.jerk == (np.inf, np.inf)
    assert lim.with_jerk(500.0).jerk == (500.0, 500.0)


def test_check_trajectory_names_axis_time_value_and_limit() -> None:
    lim = MachineLimits.seed002_stage().with_jerk(1e4)
    dt = 1e-4
    t = np.arange(2001) * dt
    # a smooth move (cosine ramp) of 1 cm in 0.2 s: peak v ≈ 0.079 m/s, a ≈ 2.5 m/s²
    x = 0.005 * (1 - np.cos(np.pi * t / 0.2))
    check_trajectory(_line_traj(x, dt), lim)
    with pytest.raises(LimitViolation, match=r"axis x: position 0\.3 m at t = 0\.2 s is above"):
        check_trajectory(_line_traj(x * 30, dt), lim)
    fast = 0.08 * (1 - np.cos(np.pi * t / 0.16))  # peak v ≈ 1.571 m/s > 1.5 at t = 0.08 s
    with pytest.raises(LimitViolation, match=r"axis x: velocity 1\.57\d* m/s at t = 0\.08\d* s"):
        check_trajectory(_line_traj(fast, dt), lim)
    # a cosine ramp starts with a = 5 m/s² straight from rest: a jerk of ~a/(2 dt)
    jerky = 5.0 * 0.04 / np.pi**2 * (1 - np.cos(np.pi * t / 0.2))
    with pytest.raises(LimitViolation, match=r"axis x: jerk .* exceeds the limit 10000 m/s\^3"):
        check_trajectory(_line_traj(jerky, dt), lim)


def test_check_trajectory_uses_analytic_derivatives_when_given() -> None:
    lim = MachineLimits.seed002_stage()
    x = np.zeros((10, 2))
    acc = np.zeros((10, 2))
    acc[4, 1] = 41.0
    tr = Trajectory(dt=1e-3, position=x, acceleration=acc)
    with pytest.raises(LimitViolation, match=r"axis y: acceleration 41 m/s\^2 at t = 0\.004 s"):
        check_trajectory(tr, lim)


def test_absurd_sample_times_do_not_overflow() -> None:
    # dt**2 and dt**3 raised OverflowError for a trial or reference sampled every 1e257 s
    check_command(sine(1.0), 1e200, {"x": LOOSE}, ("x",), periodic=True)
    traj = Trajectory(dt=1e257, position=np.array([[0.0, 0.0], [0.01, 0.0]]))
    check_trajectory(traj, MachineLimits.seed002_stage())


def test_seed001_stage_limits():
    from microfab.core.limits import MachineLimits

    lim = MachineLimits.seed001_stage()
    assert lim.axes == ("x", "y")
    assert lim.workspace == ((-1.5e-3, 1.5e-3), (-1.5e-3, 1.5e-3))  # seed 001 §2
    assert lim.velocity == (0.02, 0.02)
    assert lim.acceleration == (5.0, 5.0)
    assert lim.jerk == (float("inf"), float("inf"))

    from microfab.core.limits import check_trajectory
    from microfab.trajectory.base import Trajectory

    def circle(radius_m: float, centre_m: float, hz: float) -> Trajectory:
        t = np.arange(10_000) * 1e-4  # one 1 s period at 10 kHz
        w = 2 * np.pi * hz
        ph = w * t
        pos = centre_m + radius_m * np.column_stack([np.cos(ph), np.sin(ph)])
        vel = radius_m * w * np.column_stack([-np.sin(ph), np.cos(ph)])
        return Trajectory(dt=1e-4, position=pos, velocity=vel, at_rest=False)

    check_trajectory(circle(0.075e-3, 0.25e-3, 1.0), lim)  # seed 001 §4.2 circle, 0.47 mm/s
    with pytest.raises(LimitViolation, match="above the workspace maximum"):
        check_trajectory(circle(0.075e-3, 1.45e-3, 1.0), lim)  # beyond +1.5 mm
    with pytest.raises(LimitViolation, match="velocity"):
        check_trajectory(circle(0.075e-3, 0.25e-3, 50.0), lim)  # 23.6 mm/s > 20 mm/s


def test_seed004_stage_limits():
    lim = MachineLimits.seed004_stage()
    assert lim.axes == ("x", "y")
    assert lim.workspace == ((-0.025, 0.025), (-0.025, 0.025))  # assumed ±25 mm
    assert lim.velocity == (0.1, 0.1)  # seed 004 Table I
    assert lim.acceleration == (5.0, 5.0)  # seed 004 Table I
    assert lim.jerk == (float("inf"), float("inf"))

    def circle(radius_m: float, speed_m_s: float) -> Trajectory:
        n = round(2 * np.pi * radius_m / speed_m_s / 1e-4)  # one period, wrapped
        w = 2 * np.pi / (n * 1e-4)
        ph = w * np.arange(n) * 1e-4
        pos = radius_m * np.column_stack([np.cos(ph), np.sin(ph)])
        vel = radius_m * w * np.column_stack([-np.sin(ph), np.cos(ph)])
        acc = -radius_m * w * w * np.column_stack([np.cos(ph), np.sin(ph)])
        return Trajectory(dt=1e-4, position=pos, velocity=vel, acceleration=acc, at_rest=False)

    # seed 004 Fig. 7: a 100 µm circle at 10 mm/s needs 1 m/s^2, inside Table I
    check_trajectory(circle(100e-6, 0.01), lim)
    # about the same speed on a 10 µm circle (63 samples a lap) needs 9.95 m/s^2 > 5 m/s^2
    with pytest.raises(LimitViolation, match=r"axis x: acceleration -9\.94\d* m/s\^2 .* limit 5 m"):
        check_trajectory(circle(10e-6, 0.01), lim)
    with pytest.raises(LimitViolation, match=r"velocity -?0\.12\d* m/s .* limit 0\.1 m/s"):
        check_trajectory(circle(5e-3, 0.12), lim)
    with pytest.raises(LimitViolation, match="position"):
        check_trajectory(circle(0.03, 0.05), lim)
