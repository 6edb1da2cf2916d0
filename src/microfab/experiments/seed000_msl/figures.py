"""Seed 000 Figs. 7 and 8 redrawn from a run: beam speed along the path, cured line width.

Both take a `microfab.machines.galvo.ilc.MSLRunResult` and return a
`matplotlib.figure.Figure` on an Agg canvas (no pyplot state). The other figures of the
report (Figs. 4a, 4b, 5, 6, the loops and eq. 5) are `microfab.report.galvo_ilc` and
`microfab.report.loops`; the line styles are theirs (seed 000 §4.1).

References
----------
Seed 000 §4.2 (Fig. 7, beam velocity) and §4.3 (Fig. 8, printed line).
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from microfab.machines.galvo.ilc import BeamExposure, MSLRunResult
from microfab.report.canvas import new_figure
from microfab.report.galvo_ilc import DESIRED_STYLE, FB_STYLE, ILC_STYLE, closed, rate_label

__all__ = ["fig_line_width", "fig_velocity"]


def _speed_path(
    result: MSLRunResult, signal: np.ndarray, speed_mm_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Closed path in mm and beam speed (mm/s) per segment (the mean of its two ends)."""
    p = closed(result.to_mm(signal))
    seg_speed = 0.5 * (speed_mm_s + np.roll(speed_mm_s, -1))
    return p, seg_speed


def fig_velocity(
    result: MSLRunResult, exposure: BeamExposure, *, cmap: str = "turbo", n_arrows: int = 4
) -> Figure:
    """Beam path coloured by beam speed, FB left and ILC right (seed Fig. 7).

    Parameters
    ----------
    result : MSLRunResult
        Run to draw (the first two axes are x and y).
    exposure : BeamExposure
        Its beam speeds (`microfab.machines.galvo.ilc.beam_exposure`).
    cmap : str, optional
        Matplotlib colour map name.
    n_arrows : int, optional
        Number of arrows showing the scan direction on each path.

    Returns
    -------
    matplotlib.figure.Figure
        Two path axes (one :class:`~matplotlib.collections.LineCollection` each, shared
        colour scale) and a colour-bar axes, speed in mm/s; each title gives the mean,
        standard deviation, minimum and maximum speed.
    """
    if len(result.axes) < 2:
        raise ValueError(f"fig_velocity needs two axes, the result has {result.axes}")
    stats = exposure.stats
    paths = {
        "fb": ("FB only", *_speed_path(result, result.fb_output, exposure.speed_mm_s["fb"])),
        "ilc": ("ILC", *_speed_path(result, result.ilc_output, exposure.speed_mm_s["ilc"])),
    }
    lo = min(float(s.min()) for _, _, s in paths.values())
    hi = max(float(s.max()) for _, _, s in paths.values())
    norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    fig = new_figure(10.0, 5.4)
    axs = fig.subplots(1, 2, sharex=True, sharey=True)
    lc = None
    for ax, (tag, (title, p, speed)) in zip(axs, paths.items(), strict=True):
        segs = np.stack([p[:-1, :2], p[1:, :2]], axis=1)
        lc = LineCollection(segs, cmap=cmap, norm=norm, linewidths=3.0, capstyle="round")
        lc.set_array(speed)
        ax.add_collection(lc)
        n = p.shape[0] - 1
        step = max(1, n // 200)
        for k in range(n_arrows):
            i = int((k + 0.5) * n / max(n_arrows, 1)) % n
            j = min(i + step, n)
            ax.annotate(
                "",
                xy=(p[j, 0], p[j, 1]),
                xytext=(p[i, 0], p[i, 1]),
                arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.2, "mutation_scale": 14},
            )
        ax.autoscale_view()
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel(f"{result.axes[0]} position (mm)")
        ax.set_title(
            f"{title}: mean {stats[f'{tag}_mean']:.0f} (std {stats[f'{tag}_std']:.0f}) mm/s\n"
            f"min {stats[f'{tag}_min']:.0f}, max {stats[f'{tag}_max']:.0f} mm/s",
            fontsize="medium",
        )
        ax.grid(True, alpha=0.3)
    axs[0].set_ylabel(f"{result.axes[1]} position (mm)")
    fig.suptitle(f"Beam speed at {rate_label(result.features_per_s)}")
    fig.colorbar(lc, ax=list(axs), label="beam speed (mm/s)", shrink=0.9)
    return fig


def fig_line_width(result: MSLRunResult, exposure: BeamExposure) -> Figure:
    """Predicted cured line width along one period, FB against ILC (seed Fig. 8 analogue).

    Draws `microfab.machines.galvo.ilc.beam_exposure`'s widths (the beam speed through the
    quasi-steady Jacobs working curve) and the width at the constant target speed
    (perimeter of the desired path over one period) for reference.

    Parameters
    ----------
    result : MSLRunResult
        Run to draw.
    exposure : BeamExposure
        Its beam speeds and cured lines.

    Returns
    -------
    matplotlib.figure.Figure
        One axes with three lines (FB, ILC, width at the target speed), width in µm
        against time in ms; the legend gives mean width and uniformity ``std/mean``.
    """
    beam = exposure.beam
    t_ms = np.arange(result.reference.shape[0]) * result.dt * 1e3
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot()
    for tag, label, style in (("fb", "FB", FB_STYLE), ("ilc", "ILC", ILC_STYLE)):
        prof = exposure.line[tag]
        ax.plot(
            t_ms,
            prof.width_m * 1e6,
            label=(
                f"{label}: mean {prof.width_mean_m * 1e6:.2f} µm, "
                f"std/mean {prof.uniformity * 100:.1f} %"
            ),
            **style,
        )
    target_m_s = exposure.target_speed_m_s
    ax.axhline(
        exposure.target_width_m * 1e6,
        label=f"at target speed {target_m_s * 1e3:.0f} mm/s",
        **DESIRED_STYLE,
    )
    ax.set_xlabel("time in period (ms)")
    ax.set_ylabel("cured line width (µm)")
    ax.set_xlim(t_ms[0], t_ms[-1])
    ax.set_title(
        f"Predicted line width at {rate_label(result.features_per_s)} "
        f"({beam.power_w * 1e3:g} mW, w0 = {beam.waist_radius_m * 1e6:g} µm)",
        fontsize="medium",
    )
    ax.grid(True, alpha=0.3)
    fig.legend(
        *ax.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize="small"
    )
    return fig
