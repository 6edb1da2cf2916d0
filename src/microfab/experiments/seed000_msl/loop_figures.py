"""Figures of the feedback loops and of the learning's convergence condition (seed 000).

:func:`fig_bode` draws the open loop ``L = C G`` of each axis (seed 000 eq. 1 controller,
the calibrated twin's plant) with its gain and phase margins; :func:`fig_eq5` draws the
convergence condition of the learning, ``|1 - rho P P^-1|`` at every learned harmonic
(seed 000 eq. 5 asks for at most 1), from a run's result.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from microfab.control.margins import loop_margins
from microfab.experiments.seed000_msl.run import MSLRunResult
from microfab.machines.galvo import open_loop
from microfab.plants.galvo import GalvoAxis
from microfab.report.canvas import new_figure

__all__ = ["fig_bode", "fig_eq5"]


def fig_bode(axes: Mapping[str, GalvoAxis], *, f_min_hz: float = 10.0) -> Figure:
    """Bode plot of each axis's open loop with its margins marked.

    Parameters
    ----------
    axes : mapping of str to GalvoAxis
        The axes (their discrete open loops, `microfab.machines.galvo.open_loop`).
    f_min_hz : float, optional
        Lowest frequency drawn, Hz (the top is 0.999 of Nyquist).

    Returns
    -------
    matplotlib.figure.Figure
        Magnitude (dB) and phase (deg) panels, one line per axis, the gain crossover and
        the phase crossover of each marked and labelled with its margin.
    """
    fig = new_figure(7.0, 5.6)
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    for i, (name, axis) in enumerate(axes.items()):
        loop = open_loop(axis)
        f = np.geomspace(f_min_hz, 0.999 / (2 * loop.dt), 3000)
        resp = loop.frequency_response(f)[:, 0, 0]
        color = f"C{i}"
        ax_m.semilogx(f, 20 * np.log10(np.abs(resp)), color=color, label=f"{name}: L = C G")
        ax_p.semilogx(f, np.rad2deg(np.unwrap(np.angle(resp))), color=color)
        m = loop_margins(loop, f_min_hz=f_min_hz, n_points=20_000)
        ax_m.plot(m.pm_freq_hz, 0.0, "o", color=color, mfc="none")
        ax_p.annotate(
            f"{name}: PM {m.pm_deg:.1f}° at {m.pm_freq_hz / 1e3:.2f} kHz",
            (m.pm_freq_hz, m.pm_deg - 180.0),
            textcoords="offset points",
            xytext=(6, -14 - 12 * i),
            fontsize="small",
            color=color,
        )
        ax_p.plot(m.pm_freq_hz, m.pm_deg - 180.0, "o", color=color, mfc="none")
        if np.isfinite(m.gm_db):
            ax_m.plot(m.gm_freq_hz, -m.gm_db, "s", color=color, mfc="none")
            ax_m.annotate(
                f"{name}: GM {m.gm_db:.1f} dB at {m.gm_freq_hz / 1e3:.1f} kHz",
                (m.gm_freq_hz, -m.gm_db),
                textcoords="offset points",
                xytext=(6, 6 + 12 * i),
                fontsize="small",
                color=color,
            )
    ax_m.axhline(0.0, color="0.5", linewidth=0.8)
    ax_p.axhline(-180.0, color="0.5", linewidth=0.8)
    ax_m.set_ylabel("magnitude (dB)")
    ax_p.set_ylabel("phase (deg)")
    ax_p.set_xlabel("frequency (Hz)")
    ax_m.set_title("Open loop of each axis (seed 000 eq. 1 controller, twin plant)")
    ax_m.legend(fontsize="small")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.25)
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
