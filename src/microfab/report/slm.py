"""Figures of the SLM galvo scanner: shaper Bode, jump responses, shapers' steps, scan times.

What the ``slm-shaping`` job's report shows (seed 003 part 2 Figs. 5-7 are the first
three of the seed's runs; Fig. 4, the FRF and its fit, is
`microfab.identify.fit.FitResult.plot`). The results are computed by
`microfab.machines.slm_galvo.shaping` (jumps), `microfab.machines.slm_galvo.shapers`
(shapers side by side), `microfab.process.slm.estimate` (scan times) and
`microfab.process.slm.build` (a whole build); this module only draws them (matplotlib,
`microfab.report.canvas.new_figure`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.control.shaping import InverseShaper
from microfab.machines.slm_galvo.shaping import JumpResponse
from microfab.process.slm.estimate import ScanTimeComparison
from microfab.process.slm.timing import CATEGORIES
from microfab.report.canvas import new_figure

__all__ = [
    "plot_build",
    "plot_jump_position",
    "plot_jump_speed",
    "plot_scan_time",
    "plot_shaper_bode",
    "plot_step_comparison",
]

_RUNS = (("unshaped", "without shaper", "tab:red"), ("shaped", "with shaper", "tab:blue"))


def plot_shaper_bode(shaper: InverseShaper, f_hz: np.ndarray | None = None) -> MplFigure:
    """Seed 003 part 2 Fig. 5: Bode of the model, its inverse and the shaper.

    ``shaper`` holds the model it inverts (``plant_num``, ``plant_den``); the sampled
    filter (its discretisation) is drawn dashed up to Nyquist.
    """
    import scipy.signal

    f = np.geomspace(1.0, 0.5 / shaper.dt, 800) if f_hz is None else np.asarray(f_hz, float)
    w = 2 * np.pi * f
    _, g = scipy.signal.freqs(shaper.plant_num, shaper.plant_den, worN=w)
    curves = {
        "model G": g,
        "inverse G(0)/G": g[0] / g,
        "shaper S (continuous)": shaper.frequency_response(f),
        f"shaper S ({shaper.config.discretization.upper()}, 10 µs)": shaper.frequency_response(
            f, discrete=True
        ),
    }
    fig = new_figure(7.0, 5.5)
    mag, ph = fig.subplots(2, 1, sharex=True)
    for (name, h), style in zip(curves.items(), ("-", "-", "-", "--"), strict=True):
        mag.semilogx(f, 20 * np.log10(np.abs(h)), style, label=name)
        ph.semilogx(f, np.rad2deg(np.unwrap(np.angle(h))), style, label=name)
    mag.set_ylabel("magnitude, dB")
    ph.set_ylabel("phase, deg")
    ph.set_xlabel("frequency, Hz")
    for ax in (mag, ph):
        ax.grid(True, which="both", alpha=0.3)
    mag.legend(loc="best", fontsize=8)
    mag.set_title("Model, inverse and input shaper (seed 003 part 2 Fig. 5)")
    return fig


def plot_jump_position(jumps: Mapping[str, JumpResponse], bit_size_m: float) -> MplFigure:
    """Seed 003 part 2 Fig. 6: the jump vector, the shaped vector and both responses, mm."""
    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    k = 1e3 * bit_size_m
    first = next(iter(jumps.values()))
    t = first.time_s * 1e6
    ax.plot(t, first.command * k, color="tab:green", label="jump vector")
    for key, label, color in _RUNS:
        r = jumps.get(key)
        if r is None:
            continue
        if r.shaped is not None:
            ax.plot(t, r.shaped * k, color=color, lw=0.8, label="shaped jump vector")
        ax.plot(t, r.position * k, ".", ms=2, color=color, label=f"position, {label}")
    peak = max(abs(first.command).max(), 1e-12) * k
    ax.set_ylim(-0.5 * peak, 1.6 * peak)
    ax.set_xlabel("time, µs")
    ax.set_ylabel("position, mm")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title("Jump from rest (seed 003 part 2 Fig. 6); shaped command clipped in view")
    return fig


def plot_jump_speed(jumps: Mapping[str, JumpResponse], jump_speed_m_s: float) -> MplFigure:
    """Seed 003 part 2 Fig. 7: speed of the mirror without and with the shaper, m/s."""
    fig = new_figure(7.0, 3.5)
    ax = fig.subplots()
    for key, label, color in _RUNS:
        r = jumps.get(key)
        if r is not None:
            ax.plot(r.time_s * 1e6, r.speed_m_s, color=color, label=label)
    ax.axhline(jump_speed_m_s, color="0.4", lw=0.8, ls="--", label="nominal jump speed")
    ax.axhline(0.95 * jump_speed_m_s, color="0.6", lw=0.6, ls=":", label="95 %")
    ax.set_xlabel("time, µs")
    ax.set_ylabel("speed, m/s")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Speed on a jump (seed 003 part 2 Fig. 7)")
    return fig


def plot_scan_time(scan: Mapping[str, ScanTimeComparison]) -> MplFigure:
    """Stacked bars: the three estimates without and with the shaper, by category, s."""
    fig = new_figure(7.0, 4.0)
    ax = fig.subplots()
    labels: list[str] = []
    stacks: list[list[float]] = []
    for key, cmp in scan.items():
        for est in (cmp.naive, cmp.fixed, cmp.dynamics):
            labels.append(f"{est.method}\n{key}")
            stacks.append([est.breakdown_s[c] for c in CATEGORIES])
    data = np.array(stacks)
    x = np.arange(len(labels))
    bottom = np.zeros(len(labels))
    for j, c in enumerate(CATEGORIES):
        if np.any(data[:, j] > 0):
            ax.bar(x, data[:, j], bottom=bottom, label=c.replace("_", " "))
            bottom += data[:, j]
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylabel("scan time, s")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Layer scan time by category")
    return fig


def plot_step_comparison(
    curves: Mapping[str, Sequence[tuple[str, np.ndarray, np.ndarray]]],
    window_s: float = 3e-3,
) -> MplFigure:
    """Step responses of each shaper, one panel per twin, the first ``window_s`` seconds.

    ``curves``: twin name -> ``(shaper name, time s, position / jump)``.
    """
    fig = new_figure(7.0, 3.2 * max(len(curves), 1))
    axes = np.atleast_1d(fig.subplots(max(len(curves), 1), 1, sharex=True))
    for ax, (twin, rows) in zip(axes, curves.items(), strict=False):
        for name, t, y in rows:
            ax.plot(t * 1e6, y, lw=1.0, label=name)
        ax.axhspan(0.98, 1.02, color="0.9", zorder=0)
        ax.set_xlim(-0.05 * window_s * 1e6, window_s * 1e6)
        ax.set_ylim(-0.1, 1.5)
        ax.set_ylabel("position / jump")
        ax.set_title(f"{twin} twin", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="lower right", fontsize=7, ncol=2)
    axes[-1].set_xlabel("time, µs")
    return fig


def plot_build(
    z_mm: np.ndarray, per_layer: Mapping[str, np.ndarray], totals: Mapping[str, float]
) -> MplFigure:
    """Per-layer scan time against height, and the build's totals, s."""
    fig = new_figure(7.0, 5.5)
    ax, bx = fig.subplots(2, 1)
    for name, v in per_layer.items():
        ax.plot(z_mm, v, lw=1.0, label=name)
    ax.set_xlabel("layer height, mm")
    ax.set_ylabel("layer time, s")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    names = list(totals)
    bx.barh(names, [totals[n] for n in names], color="tab:blue")
    bx.set_xlabel("build scan time, s")
    for i, n in enumerate(names):
        bx.text(totals[n], i, f" {totals[n]:.1f}", va="center", fontsize=8)
    return fig
