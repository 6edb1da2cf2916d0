"""Figures and the scan-time table of the SLM galvo scanner (they only draw and format)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.machines.slm_galvo.machine import SEED_MODEL_DEN, SEED_MODEL_NUM
from microfab.machines.slm_galvo.shaping import (
    LayerSettings,
    ShaperSettings,
    design_shapers,
    jump_response,
)
from microfab.process.slm.estimate import estimate_with_shaper
from microfab.process.slm.timing import CATEGORIES, RTCSettings
from microfab.report.slm import (
    plot_build,
    plot_jump_position,
    plot_jump_speed,
    plot_scan_time,
    plot_shaper_bode,
    plot_step_comparison,
)
from microfab.report.slm_tables import scan_table


@pytest.fixture(scope="module")
def shaper():
    return design_shapers((SEED_MODEL_NUM, SEED_MODEL_DEN), ShaperSettings())["zpetc"]


@pytest.fixture(scope="module")
def scan(shaper):
    twin = slm_galvo.twin()
    program = LayerSettings(source="lattice:z=8.2e-4,radius=1e-3").program()
    return estimate_with_shaper(program, twin.axis_model, RTCSettings(), prefilter=shaper.to_lti())


def test_shaper_bode_has_four_curves(shaper):
    mag, _ph = plot_shaper_bode(shaper).axes
    assert len(mag.lines) == 4


def test_jump_figures(shaper):
    twin = slm_galvo.twin()
    jumps = {
        "unshaped": jump_response(twin, 1.64e-3, 5.0, noise=False),
        "shaped": jump_response(twin, 1.64e-3, 5.0, shaper, noise=False),
    }
    ax = plot_jump_position(jumps, twin.config.bit_size_m).axes[0]
    assert len(ax.lines) == 4  # jump vector, shaped vector, two positions
    ax = plot_jump_speed(jumps, 5.0).axes[0]
    np.testing.assert_allclose(ax.lines[0].get_ydata(), jumps["unshaped"].speed_m_s)


def test_scan_time_bars_and_table(scan):
    assert len(plot_scan_time(scan).axes) == 1
    t = scan_table(scan, title="layer", shaped="ZPETC", note="n")
    assert t.columns[0] == "category" and t.columns[-1] == "dynamics-aware, ZPETC [s]"
    assert [r[0] for r in t.rows] == [*CATEGORIES, "total"]
    total = scan["unshaped"].naive.total_s
    assert t.rows[-1][1] == f"{total:.5g} (100.0 %)"
    assert t.note == "n"


def test_step_comparison_and_build():
    t = np.linspace(0, 1e-3, 50)
    fig = plot_step_comparison({"seed": [("zv", t, np.clip(t / 5e-4, 0, 1))]})
    assert len(fig.axes) == 1 and len(fig.axes[0].lines) == 1
    fig = plot_build(np.array([0.03, 0.06]), {"naive_s": np.array([1.0, 2.0])}, {"naive": 3.0})
    assert len(fig.axes) == 2
