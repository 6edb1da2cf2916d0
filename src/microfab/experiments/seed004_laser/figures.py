"""Figures of seed 004: Figs. 3, 4, 6 and 7 redrawn, speed sweep, force, disturbance.

Physics lives in `run` and `microfab.measure.contour`; this module only draws (matplotlib,
through `microfab.report.canvas.new_figure`). The plots of any contouring run (axis errors,
ballbar, contour error in time) are `microfab.report.contour`'s; here they are applied to
the twin runs, beside the reproduction's own figures.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.experiments.seed004_laser import paper
from microfab.experiments.seed004_laser.run import ContourRun
from microfab.report.canvas import new_figure
from microfab.report.contour import (
    AXIS_COLOURS,
    plot_axis_errors,
    plot_ballbar,
    plot_contour_time,
)

__all__ = [
    "fig_axis_errors",
    "fig_ballbar",
    "fig_contour_time",
    "fig_disturbance",
    "fig_force",
    "fig_speed",
    "plot_disturbance",
    "plot_focus",
]


def _run_span(run: ContourRun) -> tuple[float, float]:
    ref = run.reference
    return ref.lap_starts[0] * run.dt, (ref.lap_starts[-1] + ref.lap_samples) * run.dt


def fig_axis_errors(run: ContourRun) -> MplFigure:
    """`plot_axis_errors` of a twin run."""
    return plot_axis_errors(
        run.time, run.reference.trajectory.position, run.measured, run.axis, _run_span(run)
    )


def fig_ballbar(run: ContourRun, magnify: float | None = None) -> MplFigure:
    """`plot_ballbar` of a twin run's full-speed laps."""
    ref = run.reference
    sl = slice(int(ref.lap_starts[0]), int(ref.lap_starts[-1]) + ref.lap_samples)
    return plot_ballbar(ref.path, run.measured[sl], magnify)


def fig_contour_time(runs: Mapping[str, ContourRun]) -> MplFigure:
    """Seed 004 Fig. 7 as a time plot: contour error of each run (label → run)."""
    first = next(iter(runs.values()))
    series = {k: (r.time, r.contour) for k, r in runs.items()}
    return plot_contour_time(series, _run_span(first))


def fig_speed(rows: Sequence[Mapping[str, float | str]]) -> MplFigure:
    """Largest contour error after lap 1 against speed, one line per law.

    ``rows``: dicts with ``law``, ``speed_mm_s`` and ``contour_max_nm``.
    """
    fig = new_figure(5.6, 3.6)
    ax = fig.subplots()
    for law in sorted({str(r["law"]) for r in rows}):
        pts = sorted(
            (float(r["speed_mm_s"]), float(r["contour_max_nm"])) for r in rows if r["law"] == law
        )
        ax.loglog(*zip(*pts, strict=True), "o-", label=law)
    ax.set_xlabel("tangential speed [mm/s]")
    ax.set_ylabel("max contour error after lap 1 [nm]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def fig_force(run: ContourRun) -> MplFigure:
    """Motor force of both axes against the 12 N peak; RMS against the 3 N continuous."""
    fig = new_figure(7.0, 3.0)
    ax = fig.subplots()
    rms = np.sqrt(np.mean(run.force**2, axis=0))
    for k, (name, col) in enumerate(AXIS_COLOURS):
        ax.plot(run.time, run.force[:, k], lw=0.6, color=col,
                label=f"{name} (RMS {rms[k]:.3g} N / {paper.CONTINUOUS_FORCE_N:g} N)")  # fmt: skip
    top = max(float(np.abs(run.force).max()) * 1.2, 1e-3)
    if top > 0.5 * paper.PEAK_FORCE_N:
        for s in (-paper.PEAK_FORCE_N, paper.PEAK_FORCE_N):
            ax.axhline(s, color="k", lw=0.6, ls="--")
    ax.set_title(f"Motor force (Table I: {paper.PEAK_FORCE_N:g} N peak)", fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_disturbance(time: np.ndarray, true: np.ndarray, estimate: np.ndarray) -> MplFigure:
    """The DOB's estimate of the load force beside the twin's true ``F_l``, per axis.

    ``time`` (s, (n,)), ``true`` and ``estimate`` (N, (n, 2)).
    """
    fig = new_figure(7.0, 4.2)
    axes = fig.subplots(2, 1, sharex=True)
    for k, (name, col) in enumerate(AXIS_COLOURS):
        ax = axes[k]
        ax.plot(time, true[:, k], lw=0.8, color="0.3", label="true F_l (twin)")
        ax.plot(time, estimate[:, k], lw=0.6, color=col, label="DOB estimate K_fn î_d")
        gap = float(np.sqrt(np.mean((estimate[:, k] - true[:, k]) ** 2)))
        ax.set_ylabel(f"{name} force [N]")
        ax.set_title(f"{name}: RMS of estimate − true {gap:.3g} N", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    return fig


def fig_disturbance(run: ContourRun, estimate: np.ndarray) -> MplFigure:
    """`plot_disturbance` of a run and its DOB estimate (``ContourRun.dob``)."""
    return plot_disturbance(run.time, run.disturbance, estimate)


def plot_focus(
    runs: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    depth_of_focus_m: float,
) -> MplFigure:
    """Seed 004 Fig. 6: detector output (a) and z against time (b), with the ±DOF/2 band.

    ``runs``: label -> ``(time s, detector V, z m, focus m)``, each (n,).
    """
    fig = new_figure(7.0, 4.6)
    ax_y, ax_z = fig.subplots(2, 1, sharex=True)
    for label, (t, y, z, _f) in runs.items():
        ax_y.plot(t, y, lw=0.7, label=label)
        ax_z.plot(t, z * 1e6, lw=0.7, label=label)
    t, _, _, f = next(iter(runs.values()))
    half = 0.5 * depth_of_focus_m * 1e6
    ax_z.fill_between(t, f * 1e6 - half, f * 1e6 + half, color="0.9", zorder=0,
                      label=f"focus ± DOF/2 ({half:.1f} µm)")  # fmt: skip
    ax_y.set_ylabel("detector [V]")
    ax_y.set_title("(a) detector output (minimal at focus)", fontsize=8)
    ax_z.set_ylabel("z [µm]")
    ax_z.set_title("(b) z encoder", fontsize=8)
    ax_z.set_xlabel("time [s]")
    for ax in (ax_y, ax_z):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    return fig
