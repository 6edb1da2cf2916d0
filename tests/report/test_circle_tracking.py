"""Seed 001 Figs. 12-13 and the per-period RMS drawn from a synthetic trace."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.measure.circle_tracking import tracking_metrics
from microfab.report import circle_tracking as figs
from microfab.report.canvas import render_png
from microfab.trajectory.circle_pattern import PatternConfig, pattern_reference

CFG = PatternConfig(n_circles=2, period_s=0.02, periods=3, pause_s=0.01, move_s=0.01, ramp_s=0.01)


def _case() -> tuple:
    ref = pattern_reference(CFG, 1e-4)
    y = ref.position + np.array([2e-4, -1e-4])
    laser = np.zeros(ref.n_samples, bool)
    laser[ref.starts[1] + 2 * ref.period_samples :][: ref.period_samples] = True
    m = tracking_metrics(
        ref.position,
        y,
        laser,
        starts=ref.starts,
        period_samples=ref.period_samples,
        periods=ref.periods,
        centres=ref.centres,
        radius=ref.radius_mm,
    )
    t = np.arange(ref.n_samples) * ref.dt
    return t, ref.position, y, laser, m


def test_each_figure_draws_its_curves() -> None:
    t, r, y, laser, m = _case()
    fig = figs.fig_xy(r, y, laser)
    (ax,) = fig.axes
    assert [ln.get_label() for ln in ax.lines] == ["output", "output, laser on", "reference"]
    lit = ax.lines[1].get_xydata()
    assert np.isfinite(lit[:, 0]).sum() == laser.sum()  # only the exposed samples
    fig = figs.fig_error_time(t, r, y, m)
    assert len(fig.axes) == 2
    assert np.allclose(fig.axes[0].lines[0].get_ydata(), -200.0)  # r − y of x, nm
    gates = [ln for ln in fig.axes[1].lines if ln.get_label() == "laser on"]
    assert len(gates) == 1 and gates[0].get_xdata()[0] == pytest.approx(t[m.gate_sample[1]])
    fig = figs.fig_contour_phase(m)
    curve = fig.axes[0].lines[0]
    np.testing.assert_array_equal(curve.get_ydata(), m.contour_vs_phase_nm)
    assert curve.get_xdata()[-1] < m.periods
    fig = figs.fig_period_rms(m, threshold_nm=300.0)
    labels = [ln.get_label() for ln in fig.axes[0].lines]
    assert "circle 1" in labels and "circle 2" in labels and "gate threshold 300 nm" in labels
    assert render_png(fig)[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_shapes_are_refused() -> None:
    t, r, y, laser, m = _case()
    with pytest.raises(ValueError, match="both be shaped"):
        figs.fig_xy(r, y[:, :1], laser)
    with pytest.raises(ValueError, match="laser must be shaped"):
        figs.fig_xy(r, y, laser[:-1])
    with pytest.raises(ValueError, match="time must be shaped"):
        figs.fig_error_time(t[:-1], r, y, m)
    with pytest.raises(ValueError, match="threshold_nm must be positive"):
        figs.fig_period_rms(m, threshold_nm=0.0)
