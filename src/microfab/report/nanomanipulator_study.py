"""Figure of the seed 001 RBF learning study: error and ‖Ŵ‖ per period, per variant.

Draws the results of `microfab.experiments.seed001_nanomanipulator.study` (passed as
arrays: this layer knows no experiment); computes nothing.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.report.canvas import new_figure

__all__ = ["fig_learning_study"]


def fig_learning_study(
    rms_nm: Mapping[str, np.ndarray], weight_norm: Mapping[str, np.ndarray]
) -> MplFigure:
    """RMS error (nm, log scale) and ‖Ŵ‖ (mV) per period, one line per variant.

    Parameters
    ----------
    rms_nm : mapping of str to numpy.ndarray
        Per variant, RMS error per period, nm, shape (periods,).
    weight_norm : mapping of str to numpy.ndarray
        Per variant, mean ‖Ŵ‖ per period, V, shape (periods,); all-NaN entries (no
        weights) are not drawn.
    """
    fig = new_figure(7.0, 4.6)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    for i, (name, r) in enumerate(rms_nm.items()):
        k = np.arange(1, len(r) + 1)
        colour = f"C{i % 10}"  # the same variant in the same colour on both panels
        a1.semilogy(k, r, "o-", ms=3, color=colour, label=name)
        w = np.asarray(weight_norm.get(name, np.full(len(r), np.nan)), dtype=float)
        if np.any(np.isfinite(w)):
            a2.plot(k, w * 1e3, "o-", ms=3, color=colour, label=name)
    a1.set_ylabel("RMS error [nm]")
    a2.set_ylabel("‖Ŵ‖ [mV]")
    a2.set_xlabel("period")
    for ax in (a1, a2):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    a1.set_title("RBF per period: adapting, weights frozen at hand-over, eq. 6 oracle", fontsize=9)
    return fig
