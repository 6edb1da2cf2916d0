"""Figures of an optimised reference (seed 002 §IV): the contour and the deviation along it.

What ``microfab optimize`` draws for a user's drawing: `plot_contour` (target, stage 1's
output, the optimised input, the networks' predicted output) and `plot_deviation` (signed
deviation along ``s`` with ±μ). `signed_deviation` is the foot-point ``s`` and signed
deviation they plot (`microfab.geometry.project.project_points`); the seed 002 reference
reproduction's figures plot it too. Only draws (matplotlib,
`microfab.report.canvas.new_figure`); the result drawn is an
`microfab.optimize.pipeline.ReferenceResult`. Lengths in mm, deviations in µm.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.geometry.path import Path
from microfab.geometry.project import project_points
from microfab.report.canvas import new_figure

__all__ = ["plot_contour", "plot_deviation", "signed_deviation"]

_MM, _UM = 1e3, 1e6


def signed_deviation(path: Path, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot-point ``s`` (m) and signed deviation (m, port positive) of each point."""
    proj = project_points(path, pts)
    d = np.sum((pts - proj.foot) * proj.normal, axis=1)
    return np.asarray(proj.s), d


def plot_contour(res: Any) -> MplFigure:
    """The contour, stage 1's output, the optimised input and the predicted output (mm)."""
    fig = new_figure(6.5, 6.0)
    ax = fig.subplots()
    xy = res.problem.path.flatten(1e-7)
    ax.plot(xy[:, 0] * _MM, xy[:, 1] * _MM, "k-", lw=1.2, label="target Ξ")
    ax.plot(res.stage1.gamma[:, 0] * _MM, res.stage1.gamma[:, 1] * _MM, lw=0.8,
            label="stage 1: linear model γ")  # fmt: skip
    ax.plot(res.r[:, 0] * _MM, res.r[:, 1] * _MM, lw=0.8, label="input r (400 Hz)")
    if res.predicted is not None:
        ax.plot(res.predicted[:, 0] * _MM, res.predicted[:, 1] * _MM, lw=0.8,
                label="networks φ")  # fmt: skip
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_title(f"T = {res.duration:.3f} s at a_max = {res.problem.a_max:g} m/s²")
    ax.legend(fontsize=7)
    return fig


def plot_deviation(res: Any) -> MplFigure:
    """Signed deviation along ``s`` of the input and the predicted output, with ±μ (µm)."""
    fig = new_figure(7.0, 3.6)
    ax = fig.subplots()
    path = res.problem.path
    mu = res.problem.tolerance_m * _UM
    ax.axhspan(-mu, mu, color="#e0f0e0", label="±μ")
    ax.plot(res.stage1.s * _MM, res.stage1.deviation * _UM, lw=0.8, label="stage 1 γ (linear)")
    s, d = signed_deviation(path, res.r)
    ax.plot(s * _MM, d * _UM, ".", ms=2, label="input r")
    if res.predicted is not None:
        s, d = signed_deviation(path, res.predicted)
        ax.plot(s * _MM, d * _UM, ".", ms=2, label="networks φ")
    ax.set_xlabel("s [mm]")
    ax.set_ylabel("deviation [µm]")
    ax.legend(fontsize=7, ncol=2)
    return fig
