"""`data_summary` / `summary_deviation`: data compared with a tolerance, not by digest."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.identify.ann_data import SUMMARY_POINTS, data_summary, summary_deviation


def _runs(seed: int = 0, n: int = 500) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [(0.05 * rng.standard_normal((n + k, 2)), 0.05 * rng.standard_normal((n + k, 2)))
            for k in range(3)]  # fmt: skip


def test_the_same_data_deviate_by_nothing_and_the_summary_is_json_ready():
    s = data_summary(_runs())
    assert s["samples"] == [500, 501, 502]
    assert np.shape(s["command"]) == (3, 2, 2 + SUMMARY_POINTS)
    assert summary_deviation(s, data_summary(_runs())) == 0.0


def test_a_perturbation_is_measured_relative_to_the_signal_scale():
    runs = _runs()
    bumped = [(c, m.copy()) for c, m in runs]
    bumped[1][1][-1, 0] += 1e-6  # the last sample of run 1, x: one of the kept samples
    dev = summary_deviation(data_summary(bumped), data_summary(runs))
    assert dev == pytest.approx(1e-6 / 0.05, rel=0.1)  # RMS scale of the column: 0.05 m


def test_other_runs_are_refused_not_compared():
    with pytest.raises(ValueError, match="count or length"):
        summary_deviation(data_summary(_runs(n=400)), data_summary(_runs()))
