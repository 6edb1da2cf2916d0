"""Figures of seed 002 part 2: Figs. 11-17 redrawn, and the stage timings.

The contour and deviation figures of one optimised reference are
`microfab.report.reference`'s (``microfab optimize`` draws them too). Physics lives in
`microfab.optimize` and `run`; this module only draws (matplotlib,
`microfab.report.canvas.new_figure`). Lengths in mm, deviations in µm.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.geometry.path import Path
from microfab.optimize.metrics import projected_speed
from microfab.report.canvas import new_figure
from microfab.report.reference import signed_deviation

__all__ = [
    "plot_generations",
    "plot_point_along_s",
    "plot_point_xy",
    "plot_timings",
    "plot_tradeoff",
]

_MM, _UM = 1e3, 1e6


def plot_point_xy(path: Path, outputs: Mapping[str, np.ndarray], title: str = "") -> MplFigure:
    """Seed 002 Figs. 11 and 13: the contour, inputs and twin outputs (mm).

    The right panel is a detail around the baseline's largest deviation.
    """
    fig = new_figure(10.0, 5.0)
    ax, det = fig.subplots(1, 2)
    xy = path.flatten(1e-7)
    worst = None
    if "baseline_twin" in outputs:
        _, d = signed_deviation(path, outputs["baseline_twin"])
        worst = outputs["baseline_twin"][int(np.argmax(np.abs(d)))]
    for a in (ax, det):
        a.plot(xy[:, 0] * _MM, xy[:, 1] * _MM, "k-", lw=1.2, label="target")
        for key, style in (("optimised_input", ":"), ("optimised_twin", "-"),
                           ("baseline_twin", "--")):  # fmt: skip
            if key in outputs:
                p = outputs[key]
                a.plot(p[:, 0] * _MM, p[:, 1] * _MM, style, lw=0.9, label=key.replace("_", " "))
        a.set_aspect("equal")
        a.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(title)
    if worst is not None:
        half = 0.4  # mm, the detail's half width (assumed, like the seed's station B)
        det.set_xlim(worst[0] * _MM - half, worst[0] * _MM + half)
        det.set_ylim(worst[1] * _MM - half, worst[1] * _MM + half)
        det.set_title("detail: the baseline's largest deviation")
    ax.legend(fontsize=7)
    return fig


def plot_point_along_s(path: Path, outputs: Mapping[str, np.ndarray], dt: float,
                       tolerance_m: float) -> MplFigure:  # fmt: skip
    """Seed 002 Figs. 12 and 15: deviation along ``s`` and the projected speed.

    Top: the twin outputs and the optimised input; bottom: the speed of each output's
    projection onto the contour.
    """
    fig = new_figure(8.0, 6.0)
    top, bot = fig.subplots(2, 1, sharex=True)
    mu = tolerance_m * _UM
    top.axhspan(-mu, mu, color="#e0f0e0", label="±μ")
    for key in ("optimised_twin", "baseline_twin", "optimised_input"):
        if key not in outputs:
            continue
        s, d = signed_deviation(path, outputs[key])
        top.plot(s * _MM, d * _UM, ".", ms=2, label=key.replace("_", " "))
        if key.endswith("twin"):
            speed = projected_speed(path, outputs[key], dt)
            bot.plot(s[1:] * _MM, speed, ".", ms=2, label=key.replace("_", " "))
    top.set_ylabel("deviation [µm]")
    top.legend(fontsize=7, ncol=2)
    bot.set_ylabel("projected speed [m/s]")
    bot.set_xlabel("s [mm]")
    bot.legend(fontsize=7)
    return fig


def plot_tradeoff(rows: Sequence[Mapping[str, float]], title: str) -> MplFigure:
    """Seed 002 Figs. 16 and 17: L2 against time (top), time against a_max (bottom).

    Optimised and baseline, twin (experimental) and networks (simulated).
    """
    fig = new_figure(7.0, 7.0)
    top, bot = fig.subplots(2, 1)
    t = np.array([r["time_s"] for r in rows])
    a = np.array([r["a_max"] for r in rows])
    order = np.argsort(t)
    for key, style in (("optimised_twin", "o-"), ("baseline_twin", "s-"),
                       ("optimised_ann", "o--"), ("baseline_ann", "s--")):  # fmt: skip
        vals = np.array([r.get(f"{key}_l2", np.nan) for r in rows]) * _UM
        top.plot(t[order], vals[order], style, ms=4, label=key.replace("_", " "))
    top.set_xlabel("time [s]")
    top.set_ylabel("L2 deviation [µm]")
    top.set_yscale("log")
    top.set_title(title)
    top.legend(fontsize=7)
    bot.plot(a, t, "o-", ms=4)
    bot.set_xscale("log")
    bot.set_xlabel("a_max [m/s²]")
    bot.set_ylabel("time [s]")
    return fig


def plot_timings(rows: Sequence[Mapping[str, Any]]) -> MplFigure:
    """Wall time of stage 1 and stage 2 per point (s), beside the seed's (§IV-C)."""
    fig = new_figure(7.0, 3.6)
    ax = fig.subplots()
    names = [f"{r['case']} {r['a_max']:g}" for r in rows]
    x = np.arange(len(rows))
    s1 = [r["wall_s"].get("stage1", np.nan) for r in rows]
    s2 = [r["wall_s"].get("stage2", np.nan) for r in rows]
    ax.bar(x - 0.2, s1, 0.4, label="stage 1")
    ax.bar(x + 0.2, s2, 0.4, label="stage 2")
    ax.axhline(60.0, color="k", ls=":", lw=0.8, label="seed stage 1: ~1 min")
    ax.set_xticks(x, names, rotation=60, fontsize=7)
    ax.set_ylabel("wall time [s]")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    return fig


def plot_generations(rows: Sequence[Mapping[str, Any]]) -> MplFigure:
    """Seed 002 Fig. 7's loop per generation: the networks' σ against the twin, and L∞.

    ``rows``: per generation ``generation``, ``sigma_um`` (per axis) and ``linf_m`` (the
    twin's largest deviation of the optimised references); from the study, nothing
    computed here.
    """
    fig = new_figure(9.0, 3.5)
    ax, bx = fig.subplots(1, 2)
    g = [r["generation"] for r in rows]
    for axis, style in (("x", "o-"), ("y", "s--")):
        ax.plot(g, [r["sigma_um"].get(axis, np.nan) for r in rows], style, label=axis)
    ax.set_xlabel("generation")
    ax.set_ylabel("σ networks - twin [µm]")
    ax.set_xticks(g)
    ax.legend(fontsize=7)
    bx.plot(g, [r["linf_m"] * _UM for r in rows], "o-")
    bx.set_xlabel("generation")
    bx.set_ylabel("twin L∞ of the optimised shapes [µm]")
    bx.set_xticks(g)
    return fig
