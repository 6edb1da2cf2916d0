"""Figures of seed 002 part 1: Figs. 6, 8 and 9 redrawn, models against the twin, training.

Physics lives in `study`; this module only draws (matplotlib,
`microfab.report.canvas.new_figure`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.core.limits import MachineLimits
from microfab.identify.stage_data import AXES, RunErrors
from microfab.report.canvas import new_figure

__all__ = [
    "plot_bode",
    "plot_excitation",
    "plot_fig9",
    "plot_histograms",
    "plot_losses",
    "plot_prediction",
    "plot_singular_values",
]


def plot_excitation(commands: Sequence[tuple[str, np.ndarray]]) -> MplFigure:
    """Seed 002 Fig. 6: a few training commands in the workspace (yellow), mm."""
    (x0, x1), (y0, y1) = MachineLimits.seed002_stage().workspace
    fig = new_figure(6.0, 6.0)
    ax = fig.subplots()
    ax.fill_between(
        [x0 * 1e3, x1 * 1e3], y0 * 1e3, y1 * 1e3, color="#fff3b0", zorder=0, label="workspace"
    )
    for name, u in commands:
        ax.plot(u[:, 0] * 1e3, u[:, 1] * 1e3, lw=0.7, label=name)
    ax.set_aspect("equal")
    ax.set_xlabel("x, mm")
    ax.set_ylabel("y, mm")
    ax.legend(loc="upper right", fontsize=6)
    ax.set_title("Training commands: random runs and a shape (seed 002 Fig. 6)")
    return fig


def plot_histograms(panels: Mapping[str, RunErrors]) -> MplFigure:
    """Seed 002 Fig. 8: histograms of the network's error per axis, one panel per data set."""
    fig = new_figure(9.0, 3.2)
    axes = np.atleast_1d(fig.subplots(1, max(len(panels), 1), sharey=False))
    for ax, (title, err) in zip(axes, panels.items(), strict=False):
        if err.samples is None:
            continue
        e = err.samples * 1e6
        lim = max(float(np.percentile(np.abs(e), 99.5)), 1e-3)
        bins = np.linspace(-lim, lim, 81)
        for j, a in enumerate(err.axes):
            ax.hist(
                e[:, j],
                bins=bins,
                histtype="step",
                density=True,
                label=f"{a}: μ {err.mean[j] * 1e6:.1f}, σ {err.std[j] * 1e6:.1f} µm",
            )
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("error, µm")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("density, 1/µm")
    fig.suptitle("Network prediction error (seed 002 Fig. 8)", fontsize=10)
    return fig


def plot_fig9(
    a_max: Sequence[float],
    sigma: Mapping[str, np.ndarray],
    training_a_max: float,
) -> MplFigure:
    """Seed 002 Fig. 9: σ per axis against a_max; ``sigma[label]`` shape (len(a_max), 2), m."""
    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    for label, s in sigma.items():
        arr = np.asarray(s, dtype=float) * 1e6
        for j, a in enumerate(AXES):
            ax.plot(a_max, arr[:, j], "o-" if j == 0 else "s--", ms=4, label=f"{label}, {a}")
    ax.axvline(training_a_max, color="0.5", lw=0.8, ls=":", label="training data reach")
    ax.set_yscale("log")
    ax.set_xlabel("a_max, m/s²")
    ax.set_ylabel("σ of the prediction error, µm")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Prediction error against a_max (seed 002 Fig. 9)")
    return fig


def plot_prediction(
    t: np.ndarray, measured: np.ndarray, predictions: Mapping[str, tuple[np.ndarray, np.ndarray]]
) -> MplFigure:
    """A validation run: measured position and each model's error along time, µm.

    ``predictions[label] = (t_model, y_model)``, ``y_model`` (n, 2), m; the error drawn is
    measured minus predicted, at the model's own samples.
    """
    fig = new_figure(8.0, 5.5)
    top, *rows = fig.subplots(3, 1, sharex=True)
    for j, a in enumerate(AXES):
        top.plot(t, measured[:, j] * 1e3, lw=0.8, label=f"measured {a}")
    top.set_ylabel("position, mm")
    top.legend(fontsize=7)
    for j, (ax, a) in enumerate(zip(rows, AXES, strict=True)):
        for label, (tm, ym) in predictions.items():
            k = np.clip(np.round(tm / (t[1] - t[0])).astype(int), 0, t.size - 1)
            ax.plot(tm, (measured[k, j] - ym[:, j]) * 1e6, lw=0.7, label=label)
        ax.set_ylabel(f"{a} error, µm")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    rows[-1].set_xlabel("time, s")
    top.set_title("A validation run: measured, and measured minus each model")
    return fig


def plot_losses(histories: Mapping[str, Sequence[Sequence[float]]]) -> MplFigure:
    """Training and validation loss (scaled MSE) per epoch; ``histories[label]`` rows."""
    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    for label, h in histories.items():
        arr = np.asarray(h, dtype=float).reshape(-1, 2)
        ep = np.arange(1, arr.shape[0] + 1)
        line = ax.semilogy(ep, arr[:, 0], lw=0.8, label=f"{label} train")[0]
        ax.semilogy(ep, arr[:, 1], "--", lw=0.8, color=line.get_color(), label=f"{label} val")
    ax.set_xlabel("epoch")
    ax.set_ylabel("loss (scaled MSE)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Network training")
    return fig


def plot_singular_values(sv: np.ndarray, order: int) -> MplFigure:
    """Singular values of the subspace projection (the order check), relative to the first."""
    fig = new_figure(6.0, 3.5)
    ax = fig.subplots()
    s = np.asarray(sv, dtype=float)
    n = np.arange(1, s.size + 1)
    ax.semilogy(n, s / s[0], "o-", ms=4)
    ax.axvline(order + 0.5, color="0.5", ls=":", lw=0.8, label=f"order {order}")
    ax.set_xlabel("index")
    ax.set_ylabel("singular value / first")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Subspace identification: singular values")
    return fig


def plot_bode(f_hz: np.ndarray, responses: Mapping[str, np.ndarray]) -> MplFigure:
    """Diagonal channels (x→x, y→y) of each response (len(f), 2, 2): magnitude and phase."""
    fig = new_figure(7.5, 5.5)
    mag, ph = fig.subplots(2, 1, sharex=True)
    for label, h in responses.items():
        for j, a in enumerate(AXES):
            g = h[:, j, j]
            style = "-" if j == 0 else "--"
            mag.semilogx(f_hz, 20 * np.log10(np.abs(g)), style, lw=0.9, label=f"{label} {a}")
            ph.semilogx(f_hz, np.rad2deg(np.unwrap(np.angle(g))), style, lw=0.9)
    mag.set_ylabel("magnitude, dB")
    ph.set_ylabel("phase, deg")
    ph.set_xlabel("frequency, Hz")
    for ax in (mag, ph):
        ax.grid(True, which="both", alpha=0.3)
    mag.legend(fontsize=7)
    mag.set_title("Set-point to position: the 4-state model and the twin's linear part")
    return fig
