"""Figures of a galvo ILC learning run (`microfab.machines.galvo.ilc.MSLRunResult`).

Tracking on the xy plane and against time (desired, feedback only, ILC output and input),
the error spectrum at the scan's harmonics, the learning curves of one or several rates
and the eq. (5) convergence factor at every learned harmonic: what the ``msl-ilc`` job's
report shows (seed 000 Figs. 4a, 4b, 5 and 6 are these figures of the seed's runs). Every
function returns a `matplotlib.figure.Figure` on an Agg canvas (no pyplot state); the
results are computed by the machine layer, these only draw them.

Line styles follow seed 000 §4.1: ILC output black solid, feedback (FB) blue dash-dot,
ILC input orange dotted; in the learning curves x red and y blue.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from microfab.machines.galvo.ilc import MSLRunResult
from microfab.measure.metrics import error_psd
from microfab.report.canvas import new_figure

__all__ = [
    "DESIRED_STYLE",
    "FB_STYLE",
    "ILC_STYLE",
    "INPUT_STYLE",
    "closed",
    "fig_eq5",
    "fig_learning",
    "fig_psd",
    "fig_time",
    "fig_xy",
    "n_trials",
    "rate_label",
]

# Seed 000 §4.1 styles (Fig. 4 and 5 text).
DESIRED_STYLE = {"color": "0.55", "linestyle": "--", "linewidth": 1.0}
FB_STYLE = {"color": "tab:blue", "linestyle": "-.", "linewidth": 1.2}
ILC_STYLE = {"color": "black", "linestyle": "-", "linewidth": 1.2}
INPUT_STYLE = {"color": "tab:orange", "linestyle": ":", "linewidth": 1.4}
_AXIS_COLOURS = ("tab:red", "tab:blue", "tab:green", "tab:purple")  # seed Fig. 6: x red, y blue
_RATE_MARKERS = ("o", "s", "^", "D", "v", "P")


def rate_label(features_per_s: float) -> str:
    """``"400 features/s"``."""
    return f"{features_per_s:g} features/s"


def closed(points: np.ndarray) -> np.ndarray:
    """Append the first sample so that a one-period path, shape (N, k), is drawn closed."""
    return np.concatenate([points, points[:1]], axis=0)


def n_trials(result: MSLRunResult) -> int:
    """Trials of a run."""
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
    n = n_trials(result)
    fig = new_figure(5.6, 5.2)
    ax = fig.add_subplot()
    # the desired path last and thinner, so the ILC output under it cannot hide it
    curves = (
        (result.fb_output, "FB only ($y_1$)", FB_STYLE),
        (result.ilc_output, f"ILC output ($y_{{{n}}}$)", ILC_STYLE),
        (result.ilc_input, f"ILC input ($u_{{{n}}}$)", INPUT_STYLE),
        (
            result.reference,
            "desired $y_d$",
            {**DESIRED_STYLE, "linewidth": 0.7, "color": "tab:red"},
        ),
    )
    for signal, label, style in curves:
        p = closed(result.to_mm(signal))
        ax.plot(p[:, 0], p[:, 1], label=label, **style)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{result.axes[0]} position (mm)")
    ax.set_ylabel(f"{result.axes[1]} position (mm)")
    ax.set_title(f"Beam path at {rate_label(result.features_per_s)}")
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
    n = n_trials(result)
    t_ms = np.arange(result.reference.shape[0]) * result.dt * 1e3
    n_axes = len(result.axes)
    fig = new_figure(7.0, 2.4 * n_axes + 0.6)
    axs = fig.subplots(n_axes, 1, sharex=True, squeeze=False)[:, 0]
    for a, (ax, name) in enumerate(zip(axs, result.axes, strict=True)):
        ax.plot(t_ms, result.reference[:, a], label="desired $y_d$", **DESIRED_STYLE)
        ax.plot(t_ms, result.fb_output[:, a], label="FB only ($y_1$)", **FB_STYLE)
        ax.plot(t_ms, result.ilc_output[:, a], label=f"ILC output ($y_{{{n}}}$)", **ILC_STYLE)
        ax.plot(t_ms, result.ilc_input[:, a], label=f"ILC input ($u_{{{n}}}$)", **INPUT_STYLE)
        ax.set_ylabel(f"{name} encoder (V)")
        ax.grid(True, alpha=0.3)
    axs[0].set_title(f"One period at {rate_label(result.features_per_s)}")
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

    The one-period error is analysed with `microfab.measure.metrics.error_psd` and
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
        for spec, tag, style, marker in ((fb, "FB", FB_STYLE, "D"), (ilc, "ILC", ILC_STYLE, "o")):
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
        f"Error PSD at {rate_label(result.features_per_s)} "
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
        it = np.arange(1, n_trials(r) + 1)
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
        ax.set_title(rate_label(rate))
        ax.set_xlabel("iteration")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize="small")
    axs[0].set_ylabel("RMS error (mV)")
    axs[0].yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axs[0].yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axs[0].yaxis.set_minor_formatter(NullFormatter())
    return fig


def fig_eq5(result: MSLRunResult) -> Figure:
    """``|1 - rho P P^-1|`` at each learned harmonic, per axis (seed 000 eq. 5).

    Parameters
    ----------
    result : MSLRunResult
        A run whose ``eq5`` and ``harmonics`` are filled.

    Returns
    -------
    matplotlib.figure.Figure
        Markers per axis against harmonic frequency (kHz), the bound 1 as a line.
    """
    fig = new_figure(7.0, 3.2)
    ax = fig.add_subplot()
    f1 = 1.0 / (result.reference.shape[0] * result.dt)
    for i, (name, h, val) in enumerate(
        zip(result.axes, result.harmonics, result.eq5, strict=False)
    ):
        ax.plot(h * f1 / 1e3, val, "o", mfc="none", color=f"C{i}", label=name)
    ax.axhline(1.0, color="tab:red", linestyle="--", linewidth=1.0, label="bound (eq. 5)")
    ax.set_ylim(0.0, max(1.1, max((float(v.max()) for v in result.eq5 if v.size), default=0)))
    ax.set_xlabel("harmonic frequency (kHz)")
    ax.set_ylabel("|1 - ρ P P̂⁻¹|")
    ax.set_title(
        f"Convergence condition at {result.features_per_s:g} features/s "
        "(each learned harmonic contracts by this factor per trial)"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig
