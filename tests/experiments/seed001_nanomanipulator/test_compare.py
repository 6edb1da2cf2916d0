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
    assert sweep.divergences == ()


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 45: the state-model RBF (the one that holds on Fig. 9's sines) beats the "
    "PID on the circle at 100 and 200 Hz (375 / 1440, 133 / 154 nm, last of 8 periods) but "
    "not at 400 Hz (39 / 20 nm): it is still learning there (129 -> 39 nm over the 8 "
    "periods) and has no memory of the path, which the orbit network (12 nm) has",
)
def test_fig8_state_model_rbf_below_pid_at_every_bandwidth(sweep: Fig8Sweep) -> None:
    for r in sweep.rows:
        assert r.final("RBF state") < r.final("PID"), sweep.table()


def test_a_divergence_is_reported_with_its_measured_cause() -> None:
    # 480 Hz: the PID's first samples throw the stage at ~1300 mm/s, where the §4.1 β is
    # 6.3x β_l (measured); eq. 9's sampled loop alone keeps its 45° there
    sweep = fair_fig8(bandwidths_hz=(480.0,), controllers=("PID",))
    (row,) = sweep.rows
    assert tuple(row.rms_nm) == ("PID",) and np.isnan(row.final("PID"))
    (d,) = sweep.divergences
    assert d.controller == "PID" and d.bandwidth_hz == 480.0 and d.sample < 10
    assert d.beta_ratio > 2.0 and d.speed_mm_s > 300.0, d
    assert d.phase_margin_deg >= 44.5 and d.nyquist_distance > 0.5, d
    assert "x2² term" in d.cause() and "diverged" in sweep.table()
    assert d.beta_term and "PID 480 Hz (sample" in sweep.as_table().note
    assert np.isnan(sweep.best("PID")[0])


def test_unknown_controllers_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown controllers"):
        fair_fig8(controllers=("LQR",))


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="Fig. 8 reproduced in direction only (0.15 mm circle 0.25 mm off-centre, noise off, "
    "d(t) on, last of 8 periods, every controller at 45° with eq. 9's feedforward): PID / "
    "RBF 1440 / 413 nm at 100 Hz, 154 / 29 nm at 200 Hz (5.3x), 20 / 12 nm at 400 Hz; best "
    "against best 20 / 12 nm = 0.6 here, 13 nm (470 Hz) / 12 nm (480 Hz) = 0.92 on "
    "fine_fig8's 10 Hz steps (from 480-490 Hz every loop diverges: the §4.1 β term, "
    "Fig8Sweep.divergences), not <= 1/3. Cause: at 400 Hz the "
    "PID's integral leaves 20 nm of the smooth §4.1 terms, and the network, still learning "
    "(550 -> 12 nm over the 8 periods), is not yet at its ideal (the true nonlinearity "
    "cancelled: 4 nm); the seed's own network (eq. 4 alone) gives 463 nm (study.py)",
)
def test_fig8_rbf_beats_pid_threefold_on_the_nonlinear_circle(sweep: Fig8Sweep) -> None:
    ratio = sweep.best("RBF")[0] / sweep.best("PID")[0]
    assert ratio <= paper.FIG_TARGETS["fig8_rbf_over_pid_max"], sweep.table()
