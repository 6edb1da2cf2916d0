"""The figure of the seed 001 RBF learning study draws what it is given."""

from __future__ import annotations

import numpy as np

from microfab.report.nanomanipulator_study import fig_learning_study


def test_draws_one_error_line_per_variant_and_weights_only_where_there_are_some() -> None:
    rms = {"adaptive": np.array([500.0, 490.0]), "oracle": np.array([240.0, 250.0])}
    wn = {"adaptive": np.array([0.055, 0.054]), "oracle": np.full(2, np.nan)}
    fig = fig_learning_study(rms, wn)
    top, bottom = fig.axes
    assert len(top.get_lines()) == 2
    assert len(bottom.get_lines()) == 1
    np.testing.assert_allclose(bottom.get_lines()[0].get_ydata(), [55.0, 54.0])
