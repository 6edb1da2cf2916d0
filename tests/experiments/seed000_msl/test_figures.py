"""Seed 000 Figs. 7 and 8 redrawn: beam speed along the path, cured line width."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import LineCollection

from microfab.experiments.seed000_msl.figures import fig_line_width, fig_velocity
from microfab.machines.galvo.ilc import beam_exposure, run_msl_ilc


@pytest.fixture(scope="module")
def result():
    return run_msl_ilc(400, 4)


@pytest.fixture(scope="module")
def exposure(result):
    return beam_exposure(result)


def test_exposure_computed_in_the_run_matches_table_2(result, exposure):
    assert exposure.stats == result.velocity_stats()
    n = result.reference.shape[0]
    assert exposure.speed_mm_s["fb"].shape == exposure.line["ilc"].width_m.shape == (n,)
    assert 1e-6 < exposure.target_width_m < 1e-4


def test_fig_velocity_shared_colour_scale(result, exposure):
    fig = fig_velocity(result, exposure)
    assert len(fig.axes) == 3  # FB, ILC, colour bar
    cols = [next(c for c in ax.collections if isinstance(c, LineCollection)) for ax in fig.axes[:2]]
    assert cols[0].norm.vmin == cols[1].norm.vmin
    assert cols[0].norm.vmax == cols[1].norm.vmax
    n = result.reference.shape[0]
    for c in cols:
        assert len(c.get_segments()) == n
        assert c.get_array().shape == (n,)
    stats = result.velocity_stats()
    assert f"{stats['fb_mean']:.0f}" in fig.axes[0].get_title()
    assert f"{stats['ilc_max']:.0f}" in fig.axes[1].get_title()
    assert "mm/s" in fig.axes[2].get_ylabel()


def test_fig_line_width_legend_uniformity(result, exposure):
    fig = fig_line_width(result, exposure)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert len(ax.lines) == 3  # FB, ILC, width at target speed
    labels = [line.get_label() for line in ax.lines]
    assert sum("std/mean" in lab for lab in labels) == 2
    width_um = np.asarray(ax.lines[0].get_ydata())
    assert width_um.shape == (result.reference.shape[0],)
    assert np.all((width_um > 1) & (width_um < 100))  # µm, not m
    assert "µm" in ax.get_ylabel()
