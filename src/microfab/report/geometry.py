"""Pictures of drawings and trajectories: contours with start and direction, profiles.

:func:`fig_layer` draws a layer's contours (outer boundaries, holes, open paths) with a
dot at each start and arrows along the direction of travel; :func:`fig_profile` draws a
trajectory's path speed, per-axis acceleration and jerk against the path progress ``s``
with the machine limits, where a reader checks at a glance what limits the motion.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from microfab.core.limits import MachineLimits
from microfab.geometry.layer import Layer
from microfab.report.canvas import new_figure
from microfab.trajectory.base import Trajectory

__all__ = ["fig_layer", "fig_profile"]

_DEPTH_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple")


def fig_layer(layer: Layer, *, title: str | None = None, arrows_per_contour: int = 6) -> Figure:
    """Contours in mm, start points as dots, direction arrows; holes in another colour."""
    fig = new_figure(6.0, 5.4)
    ax = fig.add_subplot()
    for c, depth in zip(layer.contours, layer.depth, strict=True):
        pts = c.flatten() * 1e3
        colour = "0.4" if depth < 0 else _DEPTH_COLOURS[depth % len(_DEPTH_COLOURS)]
        ax.plot(pts[:, 0], pts[:, 1], color=colour, lw=1.2, ls="--" if depth < 0 else "-")
        ax.plot(*(c.start * 1e3), "o", color=colour, ms=5)
        s = (np.arange(arrows_per_contour) + 0.5) / arrows_per_contour * c.length
        p, t = c.evaluate(s, 1)[:2]
        size = 0.04 * max(np.ptp(pts[:, 0]), np.ptp(pts[:, 1]), 1e-9)
        for (x, y), (tx, ty) in zip(p * 1e3, t, strict=True):
            ax.annotate(
                "",
                xy=(x + tx * size, y + ty * size),
                xytext=(x, y),
                arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.2},
            )
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    n_open = len(layer.open)
    ax.set_title(
        title
        or f"{layer.source or 'drawing'}: {len(layer)} contours"
        + (f" ({n_open} open)" if n_open else "")
    )
    ax.grid(True, lw=0.3)
    return fig


def fig_profile(
    traj: Trajectory,
    limits: MachineLimits,
    *,
    title: str = "",
    knots: tuple[np.ndarray, np.ndarray] | None = None,
) -> Figure:
    """Path speed, per-axis acceleration and jerk against ``s`` (or t), limits dashed.

    ``knots = (s, sdot)`` (m, m/s) adds a planner's grid speeds as dots, e.g.
    ``(result.s, result.sdot)`` of :func:`~microfab.trajectory.optimal.time_optimal`.
    """
    x = traj.s * 1e3 if traj.s is not None else traj.time
    xlabel = "path progress s (mm)" if traj.s is not None else "time (s)"
    dt = traj.dt
    vel = traj.velocity if traj.velocity is not None else np.gradient(traj.position, dt, axis=0)
    acc = traj.acceleration if traj.acceleration is not None else np.gradient(vel, dt, axis=0)
    jerk = traj.jerk if traj.jerk is not None else np.gradient(acc, dt, axis=0)
    has_jerk = any(np.isfinite(j) for j in limits.jerk)  # type: ignore[union-attr]
    rows = 3 if has_jerk else 2
    fig = new_figure(7.5, 2.2 * rows + 0.5)
    axs = fig.subplots(rows, 1, sharex=True)
    colours = ("tab:red", "tab:blue", "tab:green")
    axs[0].plot(x, np.linalg.norm(vel, axis=1), color="black", lw=1.2, label="path speed")
    if knots is not None and traj.s is not None:
        axs[0].plot(np.asarray(knots[0]) * 1e3, knots[1], ".", color="0.5", ms=2, label="grid ṡ")
    for k, ax_name in enumerate(traj.axes):
        axs[0].plot(x, np.abs(vel[:, k]), color=colours[k % 3], lw=0.8, label=f"|v_{ax_name}|")
        axs[0].axhline(limits.velocity[k], color=colours[k % 3], ls="--", lw=0.8)
        axs[1].plot(x, acc[:, k], color=colours[k % 3], lw=0.9, label=f"a_{ax_name}")
        for sign in (-1, 1):
            axs[1].axhline(sign * limits.acceleration[k], color=colours[k % 3], ls="--", lw=0.8)
        if has_jerk:
            axs[2].plot(x, jerk[:, k], color=colours[k % 3], lw=0.9, label=f"j_{ax_name}")
            for sign in (-1, 1):
                axs[2].axhline(sign * limits.jerk[k], color=colours[k % 3], ls="--", lw=0.8)  # type: ignore[index]
    axs[0].set_ylabel("speed (m/s)")
    axs[1].set_ylabel("acceleration (m/s²)")
    if has_jerk:
        axs[2].set_ylabel("jerk (m/s³)")
    for a in axs:
        a.grid(True, lw=0.3)
        a.legend(loc="upper right", fontsize=7, ncol=3)
    axs[-1].set_xlabel(xlabel)
    axs[0].set_title(title or f"reference: {traj.duration:.4g} s; dashed lines are the limits")
    return fig
