"""Seed 004 metrics: axis errors and the per-lap contour figures."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.measure.contour import ContourErrors, axis_errors


def test_steady_max_leaves_out_lap_one_when_there_are_more():
    three = ContourErrors(error_m=np.zeros(3), lap_max_m=np.array([5.0, 2.0, 3.0]),
                          lap_rms_m=np.ones(3))  # fmt: skip
    one = ContourErrors(error_m=np.zeros(1), lap_max_m=np.array([5.0]), lap_rms_m=np.ones(1))
    assert three.steady_max() == 3.0 and three.steady_label == "max after lap 1"
    assert one.steady_max() == 5.0 and one.steady_label == "max"
    with pytest.raises(ValueError, match="two laps"):
        one.after_first_lap_max()


def test_axis_errors_band_and_peak():
    r = np.zeros((4, 2))
    y = np.array([[0.1e-6, 0.0], [0.6e-6, 0.0], [-0.2e-6, 0.9e-6], [0.0, 0.0]])
    a = axis_errors(r, y)
    assert a.fraction_below == (0.75, 0.75)
    assert a.peak_m == (0.6e-6, 0.9e-6)
    with pytest.raises(ValueError, match="shaped"):
        axis_errors(r, y[:, :1])


def test_rms_over_the_laps_is_the_rms_of_all_their_samples():
    err = np.array([1.0, -1.0, 3.0, -3.0]) * 1e-9
    laps = (slice(0, 2), slice(2, 4))
    lap_rms = np.array([np.sqrt(np.mean(err[s] ** 2)) for s in laps])
    ce = ContourErrors(error_m=err, lap_max_m=np.array([1e-9, 3e-9]), lap_rms_m=lap_rms)
    assert ce.rms() == pytest.approx(np.sqrt(np.mean(err**2)))
