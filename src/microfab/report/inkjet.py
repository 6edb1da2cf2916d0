"""Figures of the drop-on-demand printhead (seed 003 part 1: inkjetting of sodium alginate).

They serve ``microfab droplet simulate|sweep|analyze`` and the ``droplet-sweep`` report.

Every function returns a :class:`matplotlib.figure.Figure` on an Agg canvas
(:func:`microfab.report.canvas.new_figure`, no pyplot state); save it with
:func:`microfab.report.canvas.save_figure`. The physics they draw is computed elsewhere:
the orifice flow by :mod:`microfab.plants.printhead`, the printability window by
:mod:`microfab.process.inkjet.dimensionless`, the frames by
:mod:`microfab.measure.shadowgraph`, their analysis by :mod:`microfab.measure.imaging` and
the sweep by :mod:`microfab.machines.printhead`.

References
----------
Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``): Fig. 2 (time-resolved
frames, :func:`fig_montage`), Fig. 3 (features of a forming droplet,
:func:`fig_analysis`), Fig. 4 (breakup time against concentration, :func:`fig_sweep`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from microfab.machines.printhead.machine import FIG4_VOLTAGE_V
from microfab.measure.imaging import DropletAnalysis, as_frames
from microfab.measure.shadowgraph import Camera
from microfab.plants.printhead import NozzleFlow
from microfab.process.inkjet.dimensionless import (
    CATEGORIES,
    SPLASH_LIMIT,
    WEBER_MIN,
    Z_MAX,
    Z_MIN,
    RegimeMap,
    numbers,
)
from microfab.process.inkjet.fluids import SEED_CONCENTRATIONS_PCT, naalg
from microfab.report.canvas import new_figure
from microfab.trajectory.waveform import Waveform

__all__ = [
    "CATEGORY_COLORS",
    "fig_analysis",
    "fig_montage",
    "fig_nozzle_flow",
    "fig_regime_map",
    "fig_sweep",
]

#: Colours of the printability categories (`microfab.process.inkjet.dimensionless.CATEGORIES`)
#: in `fig_regime_map`.
CATEGORY_COLORS: tuple[str, ...] = ("#8c6bb1", "#41ab5d", "#fdae61", "#bdbdbd", "#d7191c")

_DIAMETER_RULE = "nozzle diameter"


def fig_nozzle_flow(
    flow: NozzleFlow,
    waveform: Waveform,
    meniscus: tuple[np.ndarray, np.ndarray] | None = None,
) -> Figure:
    """Drive voltage, mean orifice velocity and the meniscus position against time.

    Parameters
    ----------
    flow : NozzleFlow
        Orifice velocity history.
    waveform : Waveform
        The drive waveform that produced it.
    meniscus : (numpy.ndarray, numpy.ndarray), optional
        Times in s and meniscus centre positions in m, both shape ``(n,)``
        (`microfab.process.inkjet.droplet.DropletResult.meniscus_trace`): 0 at the rim,
        negative inside the bore. Adds a third axis.

    Returns
    -------
    matplotlib.figure.Figure
        Stacked axes sharing the time axis in µs: voltage (V) on top, velocity (m/s)
        below with the peak marked, and the meniscus (µm) if given.

    Examples
    --------
    >>> from microfab.plants.printhead import Printhead, nozzle_flow
    >>> from microfab.trajectory.waveform import seed003_waveform
    >>> w = seed003_waveform()
    >>> flow = nozzle_flow(Printhead(), w, density_kg_m3=1000.0, viscosity_pa_s=1e-3,
    ...                    surface_tension_n_m=0.072, duration_s=100e-6)
    >>> len(fig_nozzle_flow(flow, w).axes)
    2
    """
    t_us = flow.t_s * 1e6
    fig = new_figure(6.4, 4.6 if meniscus is None else 6.4)
    axes = fig.subplots(2 if meniscus is None else 3, 1, sharex=True)
    ax_v, ax_u = axes[0], axes[1]
    ax_v.plot(t_us, waveform.voltage(flow.t_s), color="black")
    ax_v.set_ylabel("voltage (V)")
    ax_v.set_title(f"{waveform.kind} drive, {waveform.amplitude_v:g} V")
    ax_v.grid(True, alpha=0.3)
    ax_u.plot(t_us, flow.velocity_m_s, color="tab:blue")
    k = int(np.argmax(flow.velocity_m_s))
    ax_u.plot(t_us[k], flow.velocity_m_s[k], "o", color="tab:red")
    ax_u.annotate(
        f"peak {flow.velocity_m_s[k]:.2f} m/s",
        (t_us[k], flow.velocity_m_s[k]),
        textcoords="offset points",
        xytext=(6, -4),
        fontsize=8,
    )
    ax_u.axhline(0.0, color="gray", lw=0.8)
    ax_u.set_ylabel("orifice velocity (m/s)")
    ax_u.grid(True, alpha=0.3)
    if meniscus is not None:
        ax_m = axes[2]
        t_m, z_m = meniscus
        ax_m.plot(np.asarray(t_m) * 1e6, np.asarray(z_m) * 1e6, color="tab:green")
        ax_m.axhline(0.0, color="gray", lw=0.8)
        ax_m.set_ylabel("meniscus (µm)\n0: rim, < 0: in the bore")
        ax_m.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (µs)")
    return fig


def _nice_levels(lo: float, hi: float) -> list[float]:
    """1-3-10 levels strictly inside (lo, hi)."""
    if not (hi > 0.0 and hi > lo):
        return []
    lo = max(lo, hi * 1e-6)
    levels = []
    for e in range(math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 1):
        for m in (1.0, 3.0):
            x = m * 10.0**e
            if lo < x < hi:
                levels.append(x)
    return levels


def fig_regime_map(
    regime_map: RegimeMap,
    *,
    voltages_v: Sequence[float] | None = None,
    points: Iterable[Sequence[Any]] | None = None,
) -> Figure:
    """Two-panel printability figure for NaAlg.

    Left: the Oh-We plane (log axes) with Derby's window: Z = 1 and Z = 10 (horizontal
    lines Oh = 1 and Oh = 0.1), We = 4 and the splashing line We^1/2 Re^1/4 = 50 (i.e.
    Oh = We^2.5 / 50^4); the six seed concentrations are drawn over the map's speed range.
    Right: concentration × speed (or voltage) coloured by category, with contours of the
    intrinsic Deborah number.

    Parameters
    ----------
    regime_map : RegimeMap
        From :func:`microfab.process.inkjet.dimensionless.regime_map`.
    voltages_v : sequence of float, optional
        Drive voltage for each speed (same length as ``regime_map.speeds_m_s``); if given,
        the right panel's horizontal axis is the voltage.
    points : iterable of (concentration_pct, speed_m_s[, label]), optional
        Cases to mark on both panels (e.g. the seed's measurements or simulated runs).

    Returns
    -------
    matplotlib.figure.Figure
        Agg figure with two axes.

    Raises
    ------
    ValueError
        If ``voltages_v`` does not match the speeds.

    Examples
    --------
    >>> from microfab.process.inkjet.dimensionless import regime_map
    >>> fig = fig_regime_map(regime_map([0.15, 0.5, 1.0, 2.0], [0.5, 2.0, 5.0, 10.0]))
    >>> len(fig.axes)
    2
    """
    m = regime_map
    vs = m.speeds_m_s
    if voltages_v is not None:
        xv = np.asarray(voltages_v, dtype=float)
        if xv.shape != vs.shape:
            raise ValueError(
                f"voltages_v has {xv.size} values, the regime map has {vs.size} speeds"
            )
        x_label = "drive voltage (V)"
    else:
        xv = vs
        x_label = "jet speed (m/s)"

    pts = [tuple(p) for p in points] if points is not None else []

    fig = new_figure(11.0, 4.6)
    ax1, ax2 = fig.subplots(1, 2)

    # ---- panel 1: Oh-We plane ---------------------------------------------------------
    seed = [naalg(c, table=m.table) for c in SEED_CONCENTRATIONS_PCT]
    we_all = [m.weber[m.weber > 0]]
    oh_all = [m.ohnesorge.ravel()]
    seed_groups = []
    for f in seed:
        ds = [
            numbers(f, nozzle_radius_m=m.nozzle_radius_m, speed_m_s=float(v), length_m=m.length_m)
            for v in vs
        ]
        we = np.array([d.weber for d in ds])
        oh = np.array([d.ohnesorge for d in ds])
        seed_groups.append((f, we, oh))
        we_all.append(we[we > 0])
        oh_all.append(oh)
    we_cat = np.concatenate(we_all)
    oh_cat = np.concatenate(oh_all)
    we_lo = min(0.5, float(we_cat.min()) / 2.0) if we_cat.size else 0.5
    we_hi = max(2e3, float(we_cat.max()) * 2.0) if we_cat.size else 2e3
    oh_lo = min(3e-3, float(oh_cat.min()) / 2.0)
    oh_hi = max(3.0, float(oh_cat.max()) * 2.0)

    we_line = np.geomspace(we_lo, we_hi, 300)
    splash_oh = we_line**2.5 / SPLASH_LIMIT**4
    lower = np.maximum(1.0 / Z_MAX, splash_oh)
    ok = (we_line > WEBER_MIN) & (lower < 1.0 / Z_MIN)
    ax1.fill_between(
        we_line, lower, 1.0 / Z_MIN, where=ok, color=CATEGORY_COLORS[1], alpha=0.2, lw=0
    )
    ax1.axhline(1.0 / Z_MIN, color="k", lw=1.0, ls="--")
    ax1.axhline(1.0 / Z_MAX, color="k", lw=1.0, ls="-.")
    ax1.axvline(WEBER_MIN, color="0.3", lw=1.0, ls=":")
    ax1.plot(we_line, splash_oh, color=CATEGORY_COLORS[4], lw=1.2)
    ax1.text(we_lo * 1.2, 1.0 / Z_MIN * 1.15, "Z = 1 (too viscous above)", fontsize=7)
    ax1.text(we_lo * 1.2, 1.0 / Z_MAX * 0.7, "Z = 10 (satellites below)", fontsize=7)
    ax1.text(WEBER_MIN * 1.1, oh_lo * 1.3, "We = 4", fontsize=7, rotation=90, va="bottom")
    ax1.text(
        we_hi / 1.5,
        min(oh_hi, we_hi**2.5 / SPLASH_LIMIT**4) / 1.3,
        "splashing",
        fontsize=7,
        ha="right",
        va="top",
        color=CATEGORY_COLORS[4],
    )
    for f, we, oh in seed_groups:
        sel = we > 0
        marker = "o" if vs.size <= 15 else None
        ax1.plot(we[sel], oh[sel], marker=marker, ms=3, lw=1.2, label=f"{f.concentration_pct:g} %")
    for p in pts:
        f = naalg(float(p[0]), table=m.table)
        d = numbers(
            f, nozzle_radius_m=m.nozzle_radius_m, speed_m_s=float(p[1]), length_m=m.length_m
        )
        if d.weber > 0:
            ax1.plot(d.weber, d.ohnesorge, "k*", ms=8)
            if len(p) > 2:
                ax1.annotate(
                    str(p[2]),
                    (d.weber, d.ohnesorge),
                    fontsize=7,
                    xytext=(3, 3),
                    textcoords="offset points",
                )
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlim(we_lo, we_hi)
    ax1.set_ylim(oh_lo, oh_hi)
    length_name = (
        _DIAMETER_RULE
        if math.isclose(m.length_m, 2.0 * m.nozzle_radius_m)
        else f"L = {m.length_m * 1e6:g} µm"
    )
    ax1.set_xlabel(f"We = ρv²L/σ  (L = {length_name})")
    ax1.set_ylabel("Oh = η0/√(ρσL) = 1/Z")
    ax1.set_title("Derby printability window, NaAlg (seed concentrations)", fontsize=9)
    ax1.legend(fontsize=7, title="NaAlg w/v", title_fontsize=7, loc="lower right")

    # ---- panel 2: category map --------------------------------------------------------
    cs = m.concentrations_pct
    cmap = ListedColormap(list(CATEGORY_COLORS))
    ax2.pcolormesh(
        xv, cs, m.category, cmap=cmap, vmin=-0.5, vmax=len(CATEGORIES) - 0.5, shading="nearest"
    )
    if cs.size > 1 and xv.size > 1:
        de = m.deborah
        levels = _nice_levels(float(de.min()), float(de.max()))
        if levels:
            cset = ax2.contour(xv, cs, de, levels=levels, colors="k", linewidths=0.8)
            ax2.clabel(cset, fmt=lambda x: f"De={x:g}", fontsize=7)
    for c in SEED_CONCENTRATIONS_PCT:
        if cs.min() <= c <= cs.max():
            ax2.axhline(c, color="w", lw=0.6, ls=":")
    if pts:
        order = np.argsort(vs)
        for p in pts:
            v = float(p[1])
            x = float(np.interp(v, vs[order], xv[order])) if voltages_v is not None else v
            ax2.plot(x, float(p[0]), "k*", ms=8)
            if len(p) > 2:
                ax2.annotate(
                    str(p[2]),
                    (x, float(p[0])),
                    fontsize=7,
                    xytext=(3, 3),
                    textcoords="offset points",
                )
    if cs.min() > 0 and cs.max() / cs.min() > 4.0:
        ax2.set_yscale("log")
    ax2.set_xlabel(x_label)
    ax2.set_ylabel("NaAlg concentration (% w/v)")
    ax2.set_title(
        f"Regime (nozzle R = {m.nozzle_radius_m * 1e6:g} µm), contours: De = λ/t_c", fontsize=9
    )
    handles = [
        Patch(color=col, label=name) for name, col in zip(CATEGORIES, CATEGORY_COLORS, strict=True)
    ]
    ax2.legend(handles=handles, fontsize=7, loc="upper left", framealpha=0.8)
    return fig


def _nice_length(max_m: float) -> float:
    """Largest 1-2-5 x 10^k length not above ``max_m``."""
    exponent = math.floor(math.log10(max_m))
    for mant in (5.0, 2.0, 1.0):
        if mant * 10.0**exponent <= max_m:
            return mant * 10.0**exponent
    return 10.0 ** (exponent - 1) * 5.0


def fig_montage(frames: np.ndarray, times_s: Sequence[float], camera: Camera) -> Figure:
    """Horizontal strip of frames with time labels and a scale bar (like seed Fig. 2).

    Parameters
    ----------
    frames : numpy.ndarray
        Frames ``(n, h, w)``, float in [0, 1] (or any gray levels).
    times_s : sequence of float
        Time of each frame, s; shown in µs above the frames.
    camera : Camera
        Provides the pixel size for the scale bar (drawn on the first frame).

    Returns
    -------
    matplotlib.figure.Figure
        The montage (Agg canvas, no pyplot).

    Examples
    --------
    >>> import numpy as np
    >>> from microfab.measure.shadowgraph import Camera
    >>> cam = Camera(width_px=32, height_px=64)
    >>> fig = fig_montage(np.full((3, 64, 32), 0.8), [0.0, 1e-5, 2e-5], cam)
    >>> len(fig.axes)
    3
    """
    data = np.asarray(frames, dtype=float)
    if data.ndim == 2:
        data = data[None]
    if data.ndim != 3 or len(data) == 0:
        raise ValueError(f"frames must have shape (n, h, w) with n >= 1, got {data.shape}")
    times = np.asarray(times_s, dtype=float)
    if times.shape != (len(data),):
        raise ValueError(f"need one time per frame: {len(data)} frames, {times.size} times")
    n, h, w = data.shape
    panel_h = 4.0
    fig = new_figure(max(2.0, n * panel_h * w / h + 0.3), panel_h + 0.5)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for ax, frame, t in zip(axes, data, times, strict=True):
        ax.imshow(frame, cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
        ax.set_title(f"{t * 1e6:.4g} µs", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    bar_m = _nice_length(0.6 * w * camera.pixel_size_m)
    bar_px = bar_m / camera.pixel_size_m
    x0, y0 = 0.1 * w, 0.95 * h
    axes[0].plot([x0, x0 + bar_px], [y0, y0], color="black", linewidth=3, solid_capstyle="butt")
    axes[0].text(x0, y0 - 0.015 * h, f"{bar_m * 1e6:g} µm", fontsize=8, va="bottom")
    return fig


def fig_analysis(analysis: DropletAnalysis, frames: np.ndarray) -> Figure:
    """Head position vs time with the fit and breakup, and the breakup frame with its gap.

    Parameters
    ----------
    analysis : DropletAnalysis
        Result of :func:`microfab.measure.imaging.analyze` on ``frames``.
    frames : numpy.ndarray
        The analysed frames ``(n, h, w)``; the breakup frame (or the last one if there is
        no breakup) is shown.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels (Agg canvas, no pyplot).

    Examples
    --------
    >>> from microfab.measure.imaging import analyze  # doctest: +SKIP
    >>> from microfab.report.canvas import save_figure  # doctest: +SKIP
    >>> res = analyze(frames, pixel_size_m=2e-6, frame_interval_s=1e-5)  # doctest: +SKIP
    >>> save_figure(fig_analysis(res, frames), "analysis.png")  # doctest: +SKIP
    """
    data = as_frames(frames)
    if data.shape[0] != analysis.n_frames:
        raise ValueError(f"got {data.shape[0]} frames for an analysis of {analysis.n_frames}")
    fig = new_figure(9.0, 4.5)
    ax_t, ax_img = fig.subplots(1, 2, width_ratios=[1.6, 1.0])
    t_us = analysis.times_s * 1e6
    z_um = analysis.head_z_m * 1e6
    fit = analysis.fit_frames
    ax_t.plot(t_us[fit], z_um[fit], "o", color="C0", label="head tip (fit)")
    other = np.isfinite(z_um) & ~fit
    if other.any():
        ax_t.plot(t_us[other], z_um[other], "o", mfc="none", color="C0", label="head tip")
    if analysis.head_speed_m_s is not None and analysis.head_z0_m is not None and fit.any():
        tt = analysis.times_s[fit][[0, -1]]
        ax_t.plot(
            tt * 1e6,
            (analysis.head_z0_m + analysis.head_speed_m_s * tt) * 1e6,
            "-",
            color="C1",
            label=f"fit: {analysis.head_speed_m_s:.2f} m/s",
        )
    k = analysis.breakup_frame
    if k is not None:
        lo, hi = analysis.breakup_window_s
        if lo is not None and hi is not None:
            ax_t.axvspan(lo * 1e6, hi * 1e6, color="C3", alpha=0.15, label="breakup window")
        ax_t.axvline(t_us[k], color="C3", ls="--", label=f"breakup frame {k}")
    ax_t.set_xlabel("time (µs)")
    ax_t.set_ylabel("head position z (µm)")
    ax_t.legend(fontsize=8, loc="upper left")
    ax_t.grid(True, alpha=0.3)

    shown = k if k is not None else analysis.n_frames - 1
    img = data[shown]
    h, w = img.shape
    px_um = analysis.pixel_size_m * 1e6
    first = analysis.nozzle_row + 1
    extent = (-w / 2 * px_um, w / 2 * px_um, (h - first) * px_um, -first * px_um)
    ax_img.imshow(img, cmap="gray", extent=extent, interpolation="nearest")
    ax_img.axhline(0.0, color="C2", ls=":", lw=1, label="nozzle exit")
    title = f"frame {shown}"
    if k is not None and analysis.breakup_z_m is not None:
        ax_img.axhline(analysis.breakup_z_m * 1e6, color="C3", lw=1.5, label="breakup gap")
        mode = analysis.breakup_mode or "?"
        title += f": {mode}-pinching at {analysis.breakup_z_m * 1e6:.0f} µm"
    else:
        title += " (no breakup)"
    ax_img.set_title(title, fontsize=9)
    ax_img.set_xlabel("x (µm)")
    ax_img.set_ylabel("z (µm)")
    ax_img.legend(fontsize=7, loc="lower right")
    return fig


def fig_sweep(
    rows: Sequence[dict[str, Any]],
    *,
    seed_points: dict[float, tuple[float, str]] | None = None,
) -> Figure:
    """Breakup time against concentration (50 V) and against voltage.

    Parameters
    ----------
    rows : sequence of dict
        From `microfab.machines.printhead.droplet_sweep`.
    seed_points : dict, optional
        Concentration → (breakup time s, mode) quoted by the seed, drawn as open markers.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels; points without breakup are drawn at the top of the axis as crosses.
    """
    fig = new_figure(9.0, 3.6)
    ax_c, ax_v = fig.subplots(1, 2)
    at50 = sorted(
        (r for r in rows if r["voltage_v"] == FIG4_VOLTAGE_V), key=lambda r: r["concentration_pct"]
    )
    by_c: dict[float, list[dict[str, Any]]] = {}
    for r in rows:
        by_c.setdefault(r["concentration_pct"], []).append(r)
    series_c = max(by_c, key=lambda c: len(by_c[c])) if by_c else None
    at_c = sorted(by_c.get(series_c, []), key=lambda r: r["voltage_v"])
    for ax, data, key, label in (
        (ax_c, at50, "concentration_pct", "NaAlg concentration, % w/v"),
        (ax_v, at_c, "voltage_v", "drive voltage, V"),
    ):
        xs = [r[key] for r in data if r["breakup_time_s"] is not None]
        ys = [r["breakup_time_s"] * 1e6 for r in data if r["breakup_time_s"] is not None]
        ax.plot(xs, ys, "o-", color="C0", label="model")
        for r in data:
            if r["breakup_time_s"] is not None:
                ax.annotate(
                    str(r["breakup_mode"]),
                    (r[key], r["breakup_time_s"] * 1e6),
                    textcoords="offset points",
                    xytext=(4, 4),
                    fontsize=7,
                )
        missing = [r[key] for r in data if r["breakup_time_s"] is None]
        if missing:
            top = max(max(ys, default=0.0) * 1.1, 1.0)
            ax.plot(missing, [top] * len(missing), "x", color="C3", label="no breakup")
        ax.set_xlabel(label)
        ax.set_ylabel("first breakup time, µs")
        ax.grid(True, alpha=0.3)
    if seed_points:
        cs = sorted(seed_points)
        ax_c.plot(
            cs,
            [seed_points[c][0] * 1e6 for c in cs],
            "s",
            mfc="none",
            color="k",
            label="seed (Fig. 2)",
        )
    ax_c.set_title(f"breakup time at {FIG4_VOLTAGE_V:g} V (cf. seed Fig. 4)")
    ax_v.set_title("voltage trend" + ("" if series_c is None else f" at {series_c:g} % NaAlg"))
    ax_c.legend(fontsize=8)
    return fig
