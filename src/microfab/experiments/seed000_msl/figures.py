"""Figures of seed 000 (galvo MSL with frequency-domain ILC), redrawn from a run result.

Every function takes a :class:`~microfab.experiments.seed000_msl.run.MSLRunResult` and returns a
:class:`matplotlib.figure.Figure` attached to an Agg canvas; no pyplot (global) state is
used, so the functions are safe in scripts, tests and threads. :func:`save_figure` writes
a figure to PNG atomically.

Line styles follow the seed: ILC output black solid, feedback (FB) blue dash-dot, ILC
input orange dotted, x axis red and y axis blue in the learning transient.

References
----------
Seed 000 §4: Fig. 4a (xy plane), Fig. 4b (time axis), Fig. 5 (error PSD), Fig. 6
(learning transient), Fig. 7 (beam velocity), Fig. 8 (printed line).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from microfab.experiments.seed000_msl.run import MSLRunResult
from microfab.measure.metrics import error_psd
from microfab.process.exposure import (
    ENVISIONTEC_R11_ASSUMED,
    SEED000_BEAM,
    BeamParams,
    ResinParams,
    line_profile,
)
from microfab.process.velocity import beam_velocity
from microfab.report.canvas import DPI, new_figure, render_png, save_figure

__all__ = [
    "DPI",
    "fig_learning",
    "fig_line_width",
    "fig_psd",
    "fig_time",
    "fig_velocity",
    "fig_xy",
    "render_png",
    "save_figure",
]

#: Resolution of saved PNGs, dots per inch.

# Seed 000 §4.1 styles (Fig. 4 and 5 text).
_DESIRED = {"color": "0.55", "linestyle": "--", "linewidth": 1.0}
_FB = {"color": "tab:blue", "linestyle": "-.", "linewidth": 1.2}
_ILC = {"color": "black", "linestyle": "-", "linewidth": 1.2}
_INPUT = {"color": "tab:orange", "linestyle": ":", "linewidth": 1.4}
_AXIS_COLOURS = ("tab:red", "tab:blue", "tab:green", "tab:purple")  # seed Fig. 6: x red, y blue
_RATE_MARKERS = ("o", "s", "^", "D", "v", "P")

# Slowest speed passed to the exposure model, m/s: keeps the quasi-steady model finite
# if the beam ever stops (it then overestimates the width anyway, see exposure.py).
_MIN_SPEED_M_S = 1e-6


def _rate_label(features_per_s: float) -> str:
    return f"{features_per_s:g} features/s"


def _to_mm(result: MSLRunResult, signal: np.ndarray) -> np.ndarray:
    """Encoder volts (N, n_axes) to beam position in mm, per-axis scale."""
    return np.asarray(signal, dtype=float) * np.asarray(result.scale_mm_per_v)[np.newaxis, :]


def _closed(points: np.ndarray) -> np.ndarray:
    """Append the first sample so that a one-period path is drawn closed."""
    return np.concatenate([points, points[:1]], axis=0)


def _n_trials(result: MSLRunResult) -> int:
    return int(result.rms_history.shape[0])


def fig_xy(result: MSLRunResult) -> Figure:
    """Beam path on the xy plane: desired, FB, ILC output and ILC input (seed Fig. 4a).

    Parameters
    ----------
    result : MSLRunResult
        Run with at least two axes; the first two are drawn as x and y.

    Returns
    -------
    matplotlib.figure.Figure
        One axes with four lines (desired, FB, ILC output, ILC input ``u_N``), in mm,
        equal aspect.
    """
    if len(result.axes) < 2:
        raise ValueError(f"fig_xy needs two axes, the result has {result.axes}")
    n = _n_trials(result)
    fig = new_figure(5.6, 5.2)
    ax = fig.add_subplot()
    # the desired path last and thinner, so the ILC output under it cannot hide it
    curves = (
        (result.fb_output, "FB only ($y_1$)", _FB),
        (result.ilc_output, f"ILC output ($y_{{{n}}}$)", _ILC),
        (result.ilc_input, f"ILC input ($u_{{{n}}}$)", _INPUT),
        (result.reference, "desired $y_d$", {**_DESIRED, "linewidth": 0.7, "color": "tab:red"}),
    )
    for signal, label, style in curves:
        p = _closed(_to_mm(result, signal))
        ax.plot(p[:, 0], p[:, 1], label=label, **style)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{result.axes[0]} position (mm)")
    ax.set_ylabel(f"{result.axes[1]} position (mm)")
    ax.set_title(f"Beam path at {_rate_label(result.features_per_s)}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="center", fontsize="small", framealpha=0.9)
    return fig


def fig_time(result: MSLRunResult) -> Figure:
    """Each axis against time over one period (seed Fig. 4b).

    Parameters
    ----------
    result : MSLRunResult
        Run to draw.

    Returns
    -------
    matplotlib.figure.Figure
        One axes per scan axis (stacked, shared time axis in ms), each with four lines:
        desired, FB, ILC output and ILC input ``u_N``, in encoder volts.
    """
    n = _n_trials(result)
    t_ms = np.arange(result.reference.shape[0]) * result.dt * 1e3
    n_axes = len(result.axes)
    fig = new_figure(7.0, 2.4 * n_axes + 0.6)
    axs = fig.subplots(n_axes, 1, sharex=True, squeeze=False)[:, 0]
    for a, (ax, name) in enumerate(zip(axs, result.axes, strict=True)):
        ax.plot(t_ms, result.reference[:, a], label="desired $y_d$", **_DESIRED)
        ax.plot(t_ms, result.fb_output[:, a], label="FB only ($y_1$)", **_FB)
        ax.plot(t_ms, result.ilc_output[:, a], label=f"ILC output ($y_{{{n}}}$)", **_ILC)
        ax.plot(t_ms, result.ilc_input[:, a], label=f"ILC input ($u_{{{n}}}$)", **_INPUT)
        ax.set_ylabel(f"{name} encoder (V)")
        ax.grid(True, alpha=0.3)
    axs[0].set_title(f"One period at {_rate_label(result.features_per_s)}")
    fig.legend(
        *axs[0].get_legend_handles_labels(),
        loc="outside lower center",
        ncols=4,
        fontsize="small",
    )
    axs[-1].set_xlabel("time (ms)")
    axs[-1].set_xlim(t_ms[0], t_ms[-1])
    return fig


def fig_psd(
    result: MSLRunResult, *, cutoff_hz: float = 8e3, f_max_hz: float | None = 20e3
) -> Figure:
    """Power spectral density of the FB and ILC errors at the harmonics (seed Fig. 5).

    The one-period error is analysed with :func:`microfab.measure.metrics.error_psd` and
    ``period_s``, so every harmonic of the scan rate falls on a bin.

    Parameters
    ----------
    result : MSLRunResult
        Run to draw.
    cutoff_hz : float, optional
        Highest learned harmonic frequency, drawn as a vertical line (seed 000 §4: 8 kHz).
    f_max_hz : float or None, optional
        Upper end of the frequency axis in Hz; Nyquist when None.

    Returns
    -------
    matplotlib.figure.Figure
        One log-log axes per scan axis with four lines: FB and ILC error at the
        harmonics (markers only), the encoder white-noise floor ``2·σ²·dt`` (one-sided,
        V²/Hz) and the cutoff.
    """
    fb = error_psd(result.fb_error, result.dt, result.period_s)
    ilc = error_psd(result.ilc_error, result.dt, result.period_s)
    f_top = fb.freq_hz[-1] if f_max_hz is None else min(f_max_hz, fb.freq_hz[-1])
    band = (fb.freq_hz > 0) & (fb.freq_hz <= f_top)
    harm = fb.harmonic_freq_hz <= f_top
    n_axes = len(result.axes)
    fig = new_figure(7.0, 2.7 * n_axes + 0.6)
    axs = fig.subplots(n_axes, 1, sharex=True, squeeze=False)[:, 0]
    for a, (ax, name) in enumerate(zip(axs, result.axes, strict=True)):
        for spec, tag, style, marker in ((fb, "FB", _FB, "D"), (ilc, "ILC", _ILC, "o")):
            # markers only: a one-period spectrum has power at the harmonics, noise between
            ax.loglog(
                spec.harmonic_freq_hz[harm],
                spec.harmonic_psd[harm, a],
                linestyle="none",
                marker=marker,
                markersize=4,
                markerfacecolor="none",
                color=style["color"],
                label=f"{tag} error at the harmonics",
            )
        sigma = result.noise_rms_v[a]
        floor = 2.0 * sigma**2 * result.dt
        ax.axhline(
            floor,
            color="tab:red",
            linestyle=":",
            linewidth=1.4,
            label="encoder noise floor 2σ²·dt",
        )
        ax.text(
            0.99,
            0.97,
            f"{name}: encoder noise σ = {sigma * 1e3:.2f} mV",
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize="small",
            color="tab:red",
        )
        ax.axvline(
            cutoff_hz,
            color="0.4",
            linestyle="--",
            linewidth=1.0,
            label=f"ILC cutoff {cutoff_hz / 1e3:g} kHz",
        )
        ax.set_ylabel(f"{name} error PSD (V²/Hz)")
        ax.grid(True, which="both", alpha=0.25)
    axs[0].set_title(
        f"Error PSD at {_rate_label(result.features_per_s)} "
        f"(harmonics of {1 / result.period_s:g} Hz)"
    )
    fig.legend(
        *axs[0].get_legend_handles_labels(),
        loc="outside lower center",
        ncols=3,
        fontsize="small",
    )
    axs[-1].set_xlabel("frequency (Hz)")
    axs[-1].set_xlim(fb.freq_hz[band][0] * 0.8, f_top * 1.05)
    return fig


def fig_learning(results: Mapping[float, MSLRunResult] | MSLRunResult) -> Figure:
    """RMS error against iteration, one panel per scan rate (seed Fig. 6).

    Parameters
    ----------
    results : MSLRunResult or mapping of float to MSLRunResult
        One run, or runs by rate (features/s); panels are sorted by rate.

    Returns
    -------
    matplotlib.figure.Figure
        One axes per rate (shared log y axis, mV), each with one line per scan axis
        (x red, y blue as in the seed).
    """
    runs = {results.features_per_s: results} if isinstance(results, MSLRunResult) else dict(results)
    if not runs:
        raise ValueError("fig_learning needs at least one run")
    rates = sorted(runs)
    fig = new_figure(3.4 * len(rates) + 0.6, 3.6)
    axs = fig.subplots(1, len(rates), sharey=True, squeeze=False)[0, :]
    for i, (ax, rate) in enumerate(zip(axs, rates, strict=True)):
        r = runs[rate]
        it = np.arange(1, _n_trials(r) + 1)
        for a, name in enumerate(r.axes):
            ax.semilogy(
                it,
                r.rms_history[:, a] * 1e3,
                color=_AXIS_COLOURS[a % len(_AXIS_COLOURS)],
                marker=_RATE_MARKERS[i % len(_RATE_MARKERS)],
                markersize=3.5,
                linewidth=1.2,
                label=f"{name} axis",
            )
        ax.set_title(_rate_label(rate))
        ax.set_xlabel("iteration")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize="small")
    axs[0].set_ylabel("RMS error (mV)")
    axs[0].yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axs[0].yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axs[0].yaxis.set_minor_formatter(NullFormatter())
    return fig


def _speed_path(result: MSLRunResult, signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed path in mm and beam speed (mm/s) per segment."""
    bv = beam_velocity(signal, result.dt, result.velocity_params(), periodic=True)
    p = _closed(_to_mm(result, signal))
    seg_speed = 0.5 * (bv.speed_mm_s + np.roll(bv.speed_mm_s, -1))
    return p, seg_speed


def fig_velocity(result: MSLRunResult, *, cmap: str = "turbo", n_arrows: int = 4) -> Figure:
    """Beam path coloured by beam speed, FB left and ILC right (seed Fig. 7).

    Parameters
    ----------
    result : MSLRunResult
        Run to draw (the first two axes are x and y).
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
    stats = result.velocity_stats()
    paths = {
        "fb": ("FB only", *_speed_path(result, result.fb_output)),
        "ilc": ("ILC", *_speed_path(result, result.ilc_output)),
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
    fig.suptitle(f"Beam speed at {_rate_label(result.features_per_s)}")
    fig.colorbar(lc, ax=list(axs), label="beam speed (mm/s)", shrink=0.9)
    return fig


def fig_line_width(
    result: MSLRunResult,
    beam: BeamParams = SEED000_BEAM,
    resin: ResinParams = ENVISIONTEC_R11_ASSUMED,
) -> Figure:
    """Predicted cured line width along one period, FB against ILC (seed Fig. 8 analogue).

    The beam speed of :meth:`MSLRunResult.velocity_params` is turned into a width with the
    quasi-steady Jacobs working curve (:func:`microfab.process.exposure.line_profile`).
    The width at the constant target speed (perimeter of the desired path over one
    period) is drawn for reference.

    Parameters
    ----------
    result : MSLRunResult
        Run to draw.
    beam : BeamParams, optional
        Writing beam (seed 000 §4.3: 30 mW; assumed spot radius).
    resin : ResinParams, optional
        Resin working curve (assumed Envisiontec R11 values).

    Returns
    -------
    matplotlib.figure.Figure
        One axes with three lines (FB, ILC, width at the target speed), width in µm
        against time in ms; the legend gives mean width and uniformity ``std/mean``.
    """
    params = result.velocity_params()
    t_ms = np.arange(result.reference.shape[0]) * result.dt * 1e3
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot()
    for signal, tag, style in ((result.fb_output, "FB", _FB), (result.ilc_output, "ILC", _ILC)):
        bv = beam_velocity(signal, result.dt, params, periodic=True)
        prof = line_profile(np.maximum(bv.speed_mm_s * 1e-3, _MIN_SPEED_M_S), beam, resin)
        ax.plot(
            t_ms,
            prof.width_m * 1e6,
            label=(
                f"{tag}: mean {prof.width_mean_m * 1e6:.2f} µm, "
                f"std/mean {prof.uniformity * 100:.1f} %"
            ),
            **style,
        )
    ref_mm = _closed(_to_mm(result, result.reference))
    perimeter_mm = float(np.sum(np.hypot(*np.diff(ref_mm[:, :2], axis=0).T)))
    target_m_s = perimeter_mm * 1e-3 / result.period_s
    target = line_profile(np.array([target_m_s]), beam, resin)
    ax.axhline(
        target.width_m[0] * 1e6,
        label=f"at target speed {target_m_s * 1e3:.0f} mm/s",
        **_DESIRED,
    )
    ax.set_xlabel("time in period (ms)")
    ax.set_ylabel("cured line width (µm)")
    ax.set_xlim(t_ms[0], t_ms[-1])
    ax.set_title(
        f"Predicted line width at {_rate_label(result.features_per_s)} "
        f"({beam.power_w * 1e3:g} mW, w0 = {beam.waist_radius_m * 1e6:g} µm)",
        fontsize="medium",
    )
    ax.grid(True, alpha=0.3)
    fig.legend(
        *ax.get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize="small"
    )
    return fig
