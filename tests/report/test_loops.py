"""Bode plot of open loops with their margins (the galvo's loops, seed 000)."""

from __future__ import annotations

from microfab.control.margins import loop_margins
from microfab.machines.galvo.machine import open_loop
from microfab.plants.galvo import default_galvo_axes
from microfab.report.loops import fig_bode


def test_bode_marks_each_axis_margins() -> None:
    axes = default_galvo_axes()
    fig = fig_bode({name: open_loop(axis) for name, axis in axes.items()})
    ax_m, ax_p = fig.axes
    texts = [t.get_text() for t in ax_p.texts + ax_m.texts]
    for name, axis in axes.items():
        m = loop_margins(open_loop(axis), f_min_hz=10.0, n_points=20_000)
        assert any(t.startswith(f"{name}: PM {m.pm_deg:.1f}") for t in texts), texts
        assert any(t.startswith(f"{name}: GM {m.gm_db:.1f} dB") for t in texts), texts
