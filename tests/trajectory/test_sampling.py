"""Constant-speed sampling (seed 002 eq. 15) and periodic repetition (seed 000)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.geometry.shapes import circle, rectangle, spiral, square
from microfab.trajectory.sampling import constant_speed, periodic


def test_constant_speed_follows_the_path_at_the_speed_asked() -> None:
    p = spiral(0.005, 0.0, 4 * np.pi)
    tr = constant_speed(p, sample_rate_hz=10_000, speed=0.05)
    assert tr.duration == pytest.approx(p.length / 0.05, rel=1e-3)
    assert np.allclose(tr.position[0], p.start) and np.allclose(tr.position[-1], p.end)
    speed = np.linalg.norm(tr.velocity, axis=1)
    assert np.allclose(speed, 0.05, rtol=1e-9)
    # finite differences of the samples agree with the analytic derivatives
    fd_v = np.diff(tr.position, axis=0) / tr.dt
    mid_v = 0.5 * (tr.velocity[1:] + tr.velocity[:-1])
    assert np.max(np.abs(fd_v - mid_v)) < 1e-5 * 0.05
    fd_a = np.diff(tr.position, 2, axis=0) / tr.dt**2
    assert np.max(np.abs(fd_a - tr.acceleration[1:-1])) < 1e-3 * np.abs(tr.acceleration).max()


def test_duration_form_of_eq15() -> None:
    p = square(0.01)
    tr = constant_speed(p, sample_rate_hz=1000, duration=0.8)
    assert tr.meta["speed_m_s"] == pytest.approx(p.length / 0.8)
    assert tr.n_samples == 801


def test_constant_speed_from_rest_is_refused_by_the_limit_check() -> None:
    tr = constant_speed(circle(0.01), sample_rate_hz=10_000, speed=0.1)
    with pytest.raises(LimitViolation, match=r"axis y: acceleration .* at t = 0 s"):
        check_trajectory(tr, MachineLimits.seed002_stage())


def test_periodic_circle_passes_and_square_corner_is_refused() -> None:
    lim = MachineLimits.seed002_stage()
    tr = periodic(circle(0.01), features_per_s=10, sample_rate_hz=10_000)
    assert not tr.at_rest and tr.n_samples == 1000
    check_trajectory(tr, lim)  # centripetal 0.01*(2π·10)² ≈ 39.5 m/s² < 40
    too_fast = periodic(circle(0.01), features_per_s=10.1, sample_rate_hz=10_100)
    with pytest.raises(LimitViolation, match="acceleration"):
        check_trajectory(too_fast, lim)
    with pytest.raises(LimitViolation, match=r"axis x: acceleration .* t = 0\.0125 s"):
        check_trajectory(periodic(square(0.01), features_per_s=10, sample_rate_hz=10_000), lim)


def test_periodic_input_errors() -> None:
    with pytest.raises(ValueError, match="closed"):
        periodic(spiral(), features_per_s=1, sample_rate_hz=1000)
    with pytest.raises(ValueError, match="whole number"):
        periodic(rectangle(0.01, 0.02), features_per_s=3, sample_rate_hz=1000)
    with pytest.raises(ValueError, match="exactly one"):
        constant_speed(circle(0.01), sample_rate_hz=1000)
    with pytest.raises(ValueError, match="speed must be positive"):
        constant_speed(circle(0.01), sample_rate_hz=1000, speed=-1)


def test_samples_per_period() -> None:
    from microfab.trajectory.periodic import samples_per_period, square_scan

    assert samples_per_period(1e6, 400) == 2500
    with pytest.raises(ValueError, match="whole number"):
        samples_per_period(1000, 3)
    with pytest.raises(ValueError, match="sample rate must be positive"):
        samples_per_period(-1, 3)
    with pytest.raises(ValueError, match="repetition rate must be positive"):
        square_scan(0.0, (1.0, 1.0), 1e6)


def test_a_reference_too_long_to_hold_is_refused_not_overflowed() -> None:
    # --speed 1e-308 overflowed round(inf); a millimetre per second over a long path asks
    # for more samples than a reference may hold
    c = circle(0.005)
    for speed in (1e-308, 1e-6):
        with pytest.raises(ValueError, match="10,000,000 a reference may hold"):
            constant_speed(c, sample_rate_hz=10_000.0, speed=speed)


def test_a_speed_whose_derivatives_overflow_is_refused() -> None:
    with pytest.raises(ValueError, match="derivatives overflow"):
        constant_speed(circle(0.005), sample_rate_hz=10_000.0, speed=1e200)
