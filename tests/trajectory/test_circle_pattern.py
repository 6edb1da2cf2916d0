"""The seed 001 §4.2 pattern reference: circles, pauses, derivatives, limits."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.trajectory.circle_pattern import (
    PatternConfig,
    circle_centres,
    pattern_reference,
)

DT = 1e-4


def test_four_circles_fill_the_half_millimetre_field() -> None:
    c = circle_centres(PatternConfig())
    assert c.shape == (4, 2)
    assert np.allclose(np.abs(c), 0.175)  # (0.5 - 0.15) / 2: the circles touch the edges
    assert len({tuple(x) for x in c}) == 4


def test_reference_runs_each_circle_at_full_rate_within_the_limits() -> None:
    cfg = PatternConfig(periods=3)
    r = pattern_reference(cfg, DT)
    check_trajectory(r.trajectory(), MachineLimits.seed001_stage())
    R, n = r.radius_mm, r.period_samples
    assert n == 10_000 and len(r.starts) == 4
    for i, c in enumerate(r.centres):
        ring = r.position[r.circle_slice(i)]
        assert ring.shape[0] == 3 * n
        assert np.allclose(np.hypot(*(ring - c).T), R, atol=1e-12)
        # angle 0 at the first sample of the first period, one turn per period
        assert np.allclose(ring[0], c + np.array([R, 0.0]), atol=1e-12)
        assert np.allclose(ring[n], ring[0], atol=1e-12)
        speed = np.hypot(*r.velocity[r.circle_slice(i)].T)
        assert np.allclose(speed, 2 * np.pi * R / cfg.period_s)
    # analytic derivatives agree with the samples (spin-up/down and moves included)
    v_fd = np.gradient(r.position, DT, axis=0)
    a_fd = np.gradient(r.velocity, DT, axis=0)
    assert np.max(np.abs(v_fd - r.velocity)) < 1e-5
    assert np.max(np.abs(a_fd - r.acceleration)) < 0.1  # mm/s², sampling of the quintic
    assert np.allclose(r.velocity[[0, -1]], 0.0) and np.allclose(r.position[0], 0.0)


def test_bad_patterns_are_refused() -> None:
    with pytest.raises(ValueError, match="whole number"):
        pattern_reference(PatternConfig(period_s=1.00005), DT)
    with pytest.raises(ValueError, match="field_mm"):
        PatternConfig(field_mm=0.1)
    with pytest.raises(ValueError, match="periods"):
        PatternConfig(periods=0)
    fast = pattern_reference(PatternConfig(period_s=0.002, periods=1), DT)
    with pytest.raises(LimitViolation, match="axis x"):
        check_trajectory(fast.trajectory(), MachineLimits.seed001_stage())
