"""Figures of a galvo ILC run: tracking, error spectrum, learning curves, eq. (5)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from microfab.machines.galvo.ilc import run_msl_ilc
from microfab.report import canvas
from microfab.report.canvas import render_png, save_figure
from microfab.report.galvo_ilc import fig_eq5, fig_learning, fig_psd, fig_time, fig_xy

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def result():
    return run_msl_ilc(400, 4)


def test_fig_xy_paths_in_mm(result):
    fig = fig_xy(result)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert len(ax.lines) == 4  # FB, ILC output, ILC input, desired (drawn last, on top)
    assert ax.get_aspect() == 1.0
    desired = ax.lines[-1].get_xydata()
    assert "desired" in ax.lines[-1].get_label()
    assert ax.lines[-1].get_linewidth() < ax.lines[1].get_linewidth()  # thinner
    scale = np.asarray(result.scale_mm_per_v)
    np.testing.assert_allclose(desired[:-1], result.reference * scale)
    np.testing.assert_allclose(desired[-1], desired[0])  # drawn closed
    assert "mm" in ax.get_xlabel() and "mm" in ax.get_ylabel()
    labels = [line.get_label() for line in ax.lines]
    assert any("u_{4}" in lab for lab in labels)


def test_fig_time_two_stacked_axes(result):
    fig = fig_time(result)
    assert len(fig.axes) == 2
    for a, ax in enumerate(fig.axes):
        assert len(ax.lines) == 4
        t = ax.lines[0].get_xdata()
        assert t[0] == 0.0
        assert t[-1] == pytest.approx(result.period_s * 1e3, rel=1e-3)
        np.testing.assert_allclose(ax.lines[3].get_ydata(), result.ilc_input[:, a])
        assert result.axes[a] in ax.get_ylabel()
    assert "ms" in fig.axes[-1].get_xlabel()


def test_fig_psd_lines_floor_and_cutoff(result):
    fig = fig_psd(result)
    assert len(fig.axes) == 2
    for a, ax in enumerate(fig.axes):
        assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
        assert len(ax.lines) == 4  # FB and ILC at the harmonics, floor, cutoff
        assert ax.lines[0].get_linestyle() == "None"  # markers only, no zig-zag
        assert ax.lines[1].get_linestyle() == "None"
        floor = 2 * result.noise_rms_v[a] ** 2 * result.dt
        ys = [line.get_ydata() for line in ax.lines]
        assert any(np.allclose(y, floor) for y in ys)
        xs = [line.get_xdata() for line in ax.lines]
        assert any(np.allclose(x, 8e3) for x in xs)
        # harmonic markers sit on multiples of the scan rate
        fh = np.asarray(ax.lines[0].get_xdata())
        np.testing.assert_allclose(fh / result.features_per_s, np.round(fh / result.features_per_s))
        assert "V²/Hz" in ax.get_ylabel()


def test_fig_learning_single_and_mapping(result):
    fig = fig_learning(result)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert len(ax.lines) == 2
    assert ax.get_yscale() == "log"
    np.testing.assert_allclose(ax.lines[0].get_ydata(), result.rms_history[:, 0] * 1e3)
    assert to_rgba(ax.lines[0].get_color()) == to_rgba("tab:red")  # x red
    assert to_rgba(ax.lines[1].get_color()) == to_rgba("tab:blue")  # y blue

    fig2 = fig_learning({400.0: result, 200.0: result})
    assert len(fig2.axes) == 2
    assert [ax.get_title() for ax in fig2.axes] == ["200 features/s", "400 features/s"]
    assert all(len(ax.lines) == 2 for ax in fig2.axes)
    with pytest.raises(ValueError):
        fig_learning({})


def test_save_figure_writes_png(result, tmp_path):
    target = tmp_path / "sub" / "xy.png"
    out = save_figure(fig_xy(result), target)
    assert out == target
    data = target.read_bytes()
    assert data.startswith(PNG_SIGNATURE)
    assert len(data) > 5000
    assert os.listdir(target.parent) == ["xy.png"]  # no temporary file left


def test_save_figure_failure_leaves_target_untouched(result, tmp_path, monkeypatch):
    target = tmp_path / "xy.png"
    target.write_bytes(b"old")
    fig = fig_xy(result)

    def boom(*args, **kwargs):
        raise RuntimeError("simulated render failure")

    monkeypatch.setattr(fig, "savefig", boom)
    with pytest.raises(RuntimeError):
        save_figure(fig, target)
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["xy.png"]


def test_render_png_bytes(result):
    data = render_png(fig_time(result), dpi=60)
    assert data.startswith(PNG_SIGNATURE)
    assert canvas.DPI == 120


def test_eq5_is_within_the_bound_on_the_twin(result) -> None:
    assert [v.shape for v in result.eq5] == [h.shape for h in result.harmonics]
    for v in result.eq5:
        assert np.all(v <= 1.0)  # seed 000 eq. 5 holds at every learned harmonic
        np.testing.assert_allclose(v, 0.6, atol=0.1)  # rho = 0.4 and P P^-1 ~ 1
    fig = fig_eq5(result)
    ax = fig.axes[0]
    assert len(ax.lines) == 3  # x, y, the bound
    f1 = result.features_per_s
    np.testing.assert_allclose(ax.lines[0].get_xdata(), result.harmonics[0] * f1 / 1e3)
