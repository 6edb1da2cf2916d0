"""Seed 001 Figs. 8 and 10 on the twin: the project's targets (paper.FIG_TARGETS)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.experiments.seed001_nanomanipulator.compare import (
    CONTROLLERS,
    ComparisonResult,
    compare_controllers,
)


@pytest.fixture(scope="module")
def result() -> ComparisonResult:
    return compare_controllers()  # noise off, 8 periods, circle 0.25 mm off-centre


def test_every_controller_tracks_and_the_table_lists_them(result: ComparisonResult) -> None:
    assert tuple(result.rms_nm) == CONTROLLERS
    for name, r in result.rms_nm.items():
        assert r.shape == (8,) and np.all(np.isfinite(r)), name
        assert r[-1] < 5_000.0, (name, r)  # every loop holds the 75 µm circle within 5 µm
    assert all(name in result.table() for name in CONTROLLERS)


def test_fig10_rc_cuts_the_rbf_error_at_least_fivefold(result: ComparisonResult) -> None:
    # issue 14 target (noise off, within 10 periods): RBF + RC >= 5x below RBF alone
    gain = result.final("RBF") / result.final("RBF+RC")
    assert gain >= paper.FIG_TARGETS["fig10_rc_gain_min"], result.table()
    assert result.final("PID+RC") < result.final("PID") / 5, result.table()


@pytest.mark.xfail(
    strict=True,
    reason="Fig. 8 target not reproduced: with the default RBF rule and a PID designed for "
    "200 Hz crossover on eq. 9, the RBF's error on the nonlinear circle is about 3x the "
    "PID's (464 nm against 154 nm), not 1/3 of it",
)
def test_fig8_rbf_beats_pid_threefold_on_the_nonlinear_circle(result: ComparisonResult) -> None:
    ratio = result.final("RBF") / result.final("PID")
    assert ratio <= paper.FIG_TARGETS["fig8_rbf_over_pid_max"], result.table()
