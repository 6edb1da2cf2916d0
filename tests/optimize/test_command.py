"""The 400 Hz input as a 10 kHz command: exact at the knots, at rest at both ends, bounded."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation, MachineLimits
from microfab.optimize.command import LEAD, checked_command, command_from_input, input_bounds

LIM = MachineLimits.seed002_stage()


def random_input(rng, m, dv, d2):
    """A random input within the bounds, from rest and back to rest (symmetric accelerations)."""
    half = (
        np.where(rng.uniform(size=(m // 2, 2)) > 0.5, 1.0, -1.0) * d2 * rng.uniform(0.5, 1, (1, 2))
    )
    acc = np.vstack([half, -half[::-1]])
    return np.cumsum(np.cumsum(acc, axis=0), axis=0)[:-1]


def test_exact_at_the_knots_and_at_rest_at_both_ends():
    rng = np.random.default_rng(0)
    dv, d2 = input_bounds(LIM)
    rest = np.array([0.01, -0.02])
    r = random_input(rng, 120, dv, d2) + rest
    c = command_from_input(r, rest=rest)
    assert c.shape == (25 * (len(r) - 1 + 2 * LEAD) + 1, 2)
    assert np.array_equal(c[25 * LEAD :: 25][: len(r)], r)
    assert np.array_equal(c[0], rest) and np.array_equal(c[-1], r[-1])
    # zero slope at both ends: the first and last 0.1 ms steps are sub-micrometre
    assert np.abs(c[1] - c[0]).max() < 1e-7 and np.abs(c[-1] - c[-2]).max() < 1e-7


def test_inputs_within_the_bounds_give_commands_within_table_i():
    rng = np.random.default_rng(1)
    dv, d2 = input_bounds(LIM)
    worst = 0.0
    for _ in range(60):
        r = random_input(rng, 200, dv, d2)
        full = np.vstack([[0, 0], [0, 0], r, r[-1], r[-1]])
        if np.abs(np.diff(full, 2, axis=0)).max() > d2.max() or np.abs(r).max() > 0.18:
            continue
        if np.abs(np.diff(full, axis=0)).max() > dv.max():
            continue
        traj = checked_command(r, rest=np.zeros(2), limits=LIM)  # raises if not
        a = np.abs(np.diff(traj.position, 2, axis=0)).max() / traj.dt**2
        worst = max(worst, a)
    assert 0.5 * LIM.acceleration[0] < worst <= LIM.acceleration[0]  # the bound is tight-ish


def test_a_command_over_the_limits_is_refused_naming_the_axis():
    r = np.zeros((50, 2))
    r[25:, 1] = 1e-3  # a 1 mm step in y
    with pytest.raises(LimitViolation, match="axis y"):
        checked_command(r, rest=np.zeros(2), limits=LIM)


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"\(M, 2\)"):
        command_from_input(np.zeros((5, 3)), rest=np.zeros(2))
    with pytest.raises(ValueError, match="integer"):
        command_from_input(np.zeros((5, 2)), rest=np.zeros(2), run_rate_hz=1000.5)
