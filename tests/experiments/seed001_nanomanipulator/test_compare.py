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
from microfab.experiments.seed001_nanomanipulator.fig8 import CONTROLLERS as CONTROLLERS_FIG8
from microfab.experiments.seed001_nanomanipulator.fig8 import Fig8Sweep, fair_fig8


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


@pytest.fixture(scope="module")
def sweep() -> Fig8Sweep:
    return fair_fig8()  # 100/200/400 Hz, 45° margin, eq. 9 feedforward in every controller


def test_fig8_sweep_keeps_the_margin_and_prints_every_bandwidth(sweep: Fig8Sweep) -> None:
    assert [r.bandwidth_hz for r in sweep.rows] == [100.0, 200.0, 400.0]
    for r in sweep.rows:
        assert r.phase_margin_deg >= 44.5, r
        assert all(np.isfinite(r.final(c)) for c in CONTROLLERS_FIG8), r
        assert f"{r.bandwidth_hz:9.0f}" in sweep.table()
    assert len(sweep.as_table().rows) == 3


def test_fig8_direction_rbf_below_pid_at_every_bandwidth(sweep: Fig8Sweep) -> None:
    for r in sweep.rows:  # measured: 413 / 1440, 29 / 154, 12 / 20 nm
        assert r.final("RBF") < r.final("PID"), sweep.table()
        assert r.final("oracle") < r.final("RBF"), sweep.table()
    assert sweep.best("RBF")[0] < sweep.best("PID")[0], sweep.table()


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="Fig. 8 reproduced in direction only (0.15 mm circle 0.25 mm off-centre, noise off, "
    "d(t) on, last of 8 periods, every controller at 45° with eq. 9's feedforward): PID / "
    "RBF 1440 / 413 nm at 100 Hz, 154 / 29 nm at 200 Hz (5.3x), 20 / 12 nm at 400 Hz; best "
    "against best 20 / 12 nm = 0.6, not <= 1/3 (800 Hz diverges for all). Cause: at 400 Hz the "
    "PID's integral leaves 20 nm of the smooth §4.1 terms, and the network, still learning "
    "(550 -> 12 nm over the 8 periods), is not yet at its ideal (the true nonlinearity "
    "cancelled: 4 nm); the seed's own network (eq. 4 alone) gives 463 nm (study.py)",
)
def test_fig8_rbf_beats_pid_threefold_on_the_nonlinear_circle(sweep: Fig8Sweep) -> None:
    ratio = sweep.best("RBF")[0] / sweep.best("PID")[0]
    assert ratio <= paper.FIG_TARGETS["fig8_rbf_over_pid_max"], sweep.table()
