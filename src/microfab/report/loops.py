"""Figures of feedback loops: the Bode plot of open loops with their margins marked.

`fig_bode` draws any SISO discrete open loops (`microfab.plants.lti.DiscreteLTI`) with the
gain and phase margins of `microfab.control.margins.loop_margins`: the ``msl-ilc`` job
draws the galvo's (`microfab.machines.galvo.open_loop`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from microfab.control.margins import loop_margins
from microfab.plants.lti import DiscreteLTI
from microfab.report.canvas import new_figure

__all__ = ["fig_bode"]


def fig_bode(
    loops: Mapping[str, DiscreteLTI],
    *,
    f_min_hz: float = 10.0,
    title: str = "Open loop of each axis",
) -> Figure:
    """Bode plot of each axis's discrete SISO open loop ``L = C G`` with its margins marked.

    Parameters
    ----------
    loops : mapping of str to DiscreteLTI
        Open loop per axis name (e.g. `microfab.machines.galvo.open_loop` of each axis).
    f_min_hz : float, optional
        Lowest frequency drawn, Hz (the top is 0.999 of Nyquist).
    title : str, optional
        Title of the magnitude panel.

    Returns
    -------
    matplotlib.figure.Figure
        Magnitude (dB) and phase (deg) panels, one line per axis, the gain crossover and
        the phase crossover of each marked and labelled with its margin.
    """
    fig = new_figure(7.0, 5.6)
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    for i, (name, loop) in enumerate(loops.items()):
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
    ax_m.set_title(title)
    ax_m.legend(fontsize="small")
    for ax in (ax_m, ax_p):
        ax.grid(True, which="both", alpha=0.25)
    return fig
