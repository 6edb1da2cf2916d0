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
    return fair_fig8()  # PID vs the same PID + network, 100/200/400 Hz, 45° margin


def test_fig8_sweep_keeps_the_margin_and_prints_every_bandwidth(sweep: Fig8Sweep) -> None:
    assert [r.bandwidth_hz for r in sweep.rows] == [100.0, 200.0, 400.0]
    for r in sweep.rows:
        assert r.phase_margin_deg >= 44.5, r
        assert all(np.isfinite(r.final(c)) for c in ("PID", "PID+RBF", "oracle")), r
        assert f"{r.bandwidth_hz:9.0f}" in sweep.table()
    assert len(sweep.as_table().rows) == 3


@pytest.mark.xfail(
    strict=True,
    reason="Fig. 8 not reproduced on the twin (0.15 mm circle 0.25 mm off-centre, noise off, "
    "d(t) on, last of 8 periods; PID vs the same PID + eq. 2-5 network, 45° margin): "
    "100 Hz PID 1437 / PID+RBF 694 nm, 200 Hz 154 / 124 nm, 400 Hz 20 / 25 nm; best PID "
    "20 nm against best PID+RBF 25 nm (800 Hz diverges). Cause: even a perfect network "
    "(eq. 6 with the true α, β, ε = 1/(2π f_c)) gives 189 / 96 / 49 nm, bounded by d(t) "
    "because eq. 6 has no integral action, while the PID's integrator rejects d(t) and the "
    "smooth §4.1 terms as a slow disturbance; the seed's own network (eq. 4 alone) gives "
    "463 nm, its default widths (~3.9 against an orbit of 2) making it one constant basis "
    "function (study.py)",
)
def test_fig8_rbf_beats_pid_threefold_on_the_nonlinear_circle(sweep: Fig8Sweep) -> None:
    ratio = sweep.best("PID+RBF")[0] / sweep.best("PID")[0]
    assert ratio <= paper.FIG_TARGETS["fig8_rbf_over_pid_max"], sweep.table()
