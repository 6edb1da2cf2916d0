"""Pictures of drawings and trajectories: contours with start and direction, profiles.

:func:`fig_layer` draws a layer's contours (outer boundaries, holes, open paths) with a
dot at each start and arrows along the direction of travel; :func:`fig_profile` draws a
trajectory's path speed, per-axis acceleration and jerk against the path progress ``s``
with the machine limits, where a reader checks at a glance what limits the motion.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection, PathCollection
from matplotlib.figure import Figure
from matplotlib.path import Path as MplPath
from matplotlib.transforms import IdentityTransform

from microfab.core.limits import MachineLimits
from microfab.geometry.layer import Layer
from microfab.report.canvas import new_figure
from microfab.trajectory.base import Trajectory

__all__ = ["FULL_DOTS", "MAX_ARROWS", "fig_layer", "fig_profile"]

_DEPTH_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple")
#: Most direction arrows in one picture: beyond it each contour gets fewer (at least one).
MAX_ARROWS = 600
#: Most contours drawn with full-size start dots and arrow heads.
FULL_DOTS = 100


def fig_layer(layer: Layer, *, title: str | None = None, arrows_per_contour: int = 6) -> Figure:
    """Contours in mm, start points as dots, direction arrows; holes in another colour.

    Closed contours are drawn solid in their depth's colour (outer, hole, island, …), open
    ones dashed grey, each from its :meth:`~microfab.geometry.path.Path.flatten` polyline.
    Everything is drawn as a few collections (lines, dots, arrow shafts and heads), not
    artists per contour, so that a drawing of thousands of contours draws in under a
    second. Arrows sit evenly along each polyline, pointing along it, 4 % of the
    contour's size long, with ``->`` heads of 4 points; with more than ``MAX_ARROWS /
    arrows_per_contour`` contours each gets fewer arrows (at least one), and beyond
    `FULL_DOTS` contours the dots and heads shrink (as ``1/√n``, down to a fifth).
    """
    fig = new_figure(6.0, 5.4)
    ax = fig.add_subplot()
    n = len(layer)
    if n:
        _draw_contours(ax, layer, arrows_per_contour)
        _frame(ax, [c.flatten() * 1e3 for c in layer.contours])
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


def _frame(ax: Axes, flats: list[np.ndarray]) -> None:
    """Axis limits around the contours (mm), neither span under 1 % of the other.

    A drawing flat along one axis (a Lissajous curve of height 1e-30 m) would give
    matplotlib a singular transform; 5 % margins as matplotlib's own.
    """
    pts = np.concatenate(flats)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    half = np.maximum(half, max(float(half.max()) * 0.01, 1e-9)) * 1.05
    ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
    ax.set_ylim(centre[1] - half[1], centre[1] + half[1])


def _draw_contours(ax: Axes, layer: Layer, arrows_per_contour: int) -> None:
    """The contours, dots and arrows of `fig_layer` on ``ax``, as a few collections."""
    n = len(layer)
    flats = [c.flatten() * 1e3 for c in layer.contours]
    depth = np.array(layer.depth)
    colours = np.array(["0.4" if d < 0 else _DEPTH_COLOURS[d % len(_DEPTH_COLOURS)] for d in depth])
    for dashed in (False, True):
        idx = np.flatnonzero((depth < 0) == dashed)
        if idx.size:
            lines = LineCollection(
                [flats[i] for i in idx],
                colors=colours[idx],
                linewidths=1.2,
                linestyles="--" if dashed else "-",
            )
            ax.add_collection(lines)
    scale = min(1.0, max(0.2, np.sqrt(FULL_DOTS / n)))
    starts = np.array([f[0] for f in flats])
    for colour in dict.fromkeys(colours.tolist()):
        at = starts[colours == colour]
        ax.plot(at[:, 0], at[:, 1], "o", color=colour, ms=5.0 * scale)
    per = max(1, min(arrows_per_contour, MAX_ARROWS // n))
    tail, tangent, size = _arrows(flats, per)
    tip = tail + tangent * size[:, None]
    arrow_colours = np.repeat(colours, per)
    shafts = LineCollection(np.stack([tail, tip], axis=1), colors=arrow_colours, linewidths=1.2)
    ax.add_collection(shafts)
    # heads in points, as annotate's "->": barbs 4 pt back and 2 pt aside, turned to the
    # tangent
    bx, by = np.array([[-4.0, 0.0, -4.0]]) * scale, np.array([[2.0, 0.0, -2.0]]) * scale
    cos, sin = tangent[:, :1], tangent[:, 1:]
    head = np.stack([cos * bx - sin * by, sin * bx + cos * by], axis=-1)
    heads = PathCollection(
        [MplPath(h) for h in head],
        sizes=[1.0],  # the paths in points, placed at the tips
        transform=IdentityTransform(),
        offsets=tip,
        offset_transform=ax.transData,
        facecolors="none",
        edgecolors=arrow_colours,
        linewidths=1.2,
    )
    ax.add_collection(heads, autolim=False)
    ax.autoscale_view()


def _arrows(flats: list[np.ndarray], per: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where ``per`` arrows go evenly along each polyline, vectorised over all of them.

    Parameters
    ----------
    flats : list of numpy.ndarray
        Polylines, each shape (m, 2) with m >= 1, mm.
    per : int
        Arrows per polyline, at ``(k + 1/2) / per`` of its length, k = 0 … per − 1.

    Returns
    -------
    tail : numpy.ndarray
        Arrow starts on the polylines, shape (n * per, 2), mm; polyline by polyline.
    tangent : numpy.ndarray
        Unit directions of the polyline there, shape (n * per, 2); ``(1, 0)`` on a
        polyline of no length.
    size : numpy.ndarray
        Arrow lengths, shape (n * per,), mm: 4 % of the polyline's larger extent (at
        least 1e-9 mm).
    """
    verts = np.concatenate(flats)
    sizes = np.array([f.shape[0] for f in flats])
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    last = first + sizes - 1
    span = np.maximum.reduceat(verts, first, axis=0) - np.minimum.reduceat(verts, first, axis=0)
    size = 0.04 * np.maximum(span.max(axis=1), 1e-9)
    # arc length along all polylines, not counting the jumps from one to the next
    step = np.hypot(*np.diff(verts, axis=0).T) if verts.shape[0] > 1 else np.zeros(0)
    step[last[:-1]] = 0.0
    cum = np.concatenate([[0.0], np.cumsum(step)])
    owner = np.repeat(np.arange(len(flats)), per)
    frac = np.tile((np.arange(per) + 0.5) / per, len(flats))
    target = cum[first[owner]] + frac * (cum[last[owner]] - cum[first[owner]])
    # the chord holding each target, kept inside its own polyline
    k = np.searchsorted(cum, target, side="right") - 1
    k = np.clip(k, first[owner], np.maximum(last[owner] - 1, first[owner]))
    nxt = np.minimum(k + 1, last[owner])
    chord = verts[nxt] - verts[k]
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = length > 0
    tangent = np.tile([1.0, 0.0], (k.size, 1))
    tangent[ok] = chord[ok] / length[ok, None]
    along = np.zeros(k.size)
    along[ok] = np.clip((target[ok] - cum[k[ok]]) / length[ok], 0.0, 1.0)
    tail = verts[k] + along[:, None] * chord
    return tail, tangent, size[owner]


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
