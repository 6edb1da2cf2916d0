"""Deviation norms (seed 002 eqs. 16-18) and the baselines (eq. 15, stretched time-optimal)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from microfab.core.limits import MachineLimits, check_trajectory
from microfab.geometry.shapes import circle, rectangle
from microfab.optimize.baseline import constant_progress, stretched_time_optimal
from microfab.optimize.metrics import DeviationNorms, deviations, projected_speed
from microfab.trajectory.base import Trajectory


def test_deviation_of_points_off_a_circle():
    c = circle(5e-3)
    th = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    d = np.linspace(-30e-6, 30e-6, 50)
    pts = np.column_stack([(5e-3 + d) * np.cos(th), (5e-3 + d) * np.sin(th)])
    assert np.allclose(deviations(c, pts), np.abs(d), atol=1e-12)
    n = DeviationNorms.of(c, pts)
    assert n.l1 <= n.l2 <= n.linf == pytest.approx(30e-6)
    assert n.l2 == pytest.approx(np.sqrt(np.mean(d**2)))
    better = DeviationNorms(n.l1 / 2, n.l2 / 2, n.linf / 2, n.n)
    assert better.improvement_over(n) == pytest.approx({"l1": 50.0, "l2": 50.0, "linf": 50.0})
    with pytest.raises(ValueError, match="finite"):
        deviations(c, np.array([[np.nan, 0.0]]))


def test_tail_scored_apart_pooled_and_read_back():
    c = circle(5e-3)
    th = np.linspace(0, 2 * np.pi, 10, endpoint=False)
    d = np.array([10e-6] * 6 + [40e-6] * 4)
    pts = np.column_stack([(5e-3 + d) * np.cos(th), (5e-3 + d) * np.sin(th)])
    n = DeviationNorms.of(c, pts, tail_from=6)
    assert n.n == 6 and n.linf == pytest.approx(10e-6) and n.tail_linf == pytest.approx(40e-6)
    assert list(n.as_dict()) == ["l1", "l2", "linf", "tail_linf", "n"]
    assert DeviationNorms.from_dict(n.as_dict()) == n
    assert "tail_linf" not in DeviationNorms.of(c, pts).as_dict()
    assert DeviationNorms.of(c, pts, tail_from=10).tail_linf == 0.0
    both = DeviationNorms.pooled([n, DeviationNorms.of(c, pts[6:])])
    whole = DeviationNorms.of(c, pts)
    assert (both.n, both.linf) == (10, whole.linf) and both.tail_linf is None
    assert both.l1 == pytest.approx(whole.l1) and both.l2 == pytest.approx(whole.l2)


def test_constant_progress_and_projected_speed():
    sq = rectangle(8e-3, 6e-3)
    r = constant_progress(sq, 0.5, 400.0)
    assert r.shape == (201, 2)
    assert np.allclose(r[0], r[-1]) and np.allclose(r[0], sq.start)
    v = projected_speed(sq, r, 1 / 400.0)
    assert np.allclose(v, sq.length / 0.5, rtol=1e-9)  # on the path: S / T everywhere
    assert np.allclose(deviations(sq, r), 0.0, atol=1e-12)


def test_stretched_time_optimal_within_the_limits():
    sq = rectangle(8e-3, 6e-3, corner_radius=0.5e-3)
    lim = dataclasses.replace(MachineLimits.seed002_stage(), acceleration=(1.0, 1.0))
    q = stretched_time_optimal(sq, 1.5, lim, 1e4)
    assert q.shape == (15001, 2)
    check_trajectory(Trajectory(dt=1e-4, position=q), lim)
    with pytest.raises(ValueError, match="cannot be stretched"):
        stretched_time_optimal(sq, 0.01, lim, 1e4)
