"""Bode and coherence axes shared by `FRF.plot` and `FitResult.plot` (matplotlib, no pyplot).

matplotlib is imported when a figure is made, not with the package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from microfab.identify.frf import FRF

__all__ = ["MIN_COHERENCE", "bode_axes", "draw_coherence", "draw_response"]

MIN_COHERENCE = 0.8  # issue 16 §8: "coherence < 0.8 over a named range" is refused


def bode_axes(title: str | None) -> tuple[Figure, list[Any]]:
    """A figure with magnitude, phase and coherence axes on a shared log frequency axis."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 7.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = list(fig.subplots(3, 1, sharex=True, height_ratios=(3, 3, 1.5)))
    axes[0].set_ylabel("magnitude, dB")
    axes[1].set_ylabel("phase, deg")
    axes[2].set_ylabel("coherence")
    axes[2].set_xlabel("frequency, Hz")
    for ax in axes:
        ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig, axes


def draw_response(axes: list[Any], f: np.ndarray, h: np.ndarray, *, label: str, style: str) -> None:
    """Magnitude (dB) and unwrapped phase (deg) of ``h`` on the first two axes."""
    kw = {"ms": 2} if style == "." else {"lw": 1.5}
    axes[0].plot(f, 20 * np.log10(np.abs(h)), style, label=label, **kw)
    axes[1].plot(f, np.rad2deg(np.unwrap(np.angle(h))), style, label=label, **kw)


def draw_coherence(ax: Any, frf: FRF, threshold: float = MIN_COHERENCE) -> None:
    """The coherence (or a note that it is unknown) and the refusal threshold."""
    if np.all(np.isnan(frf.coherence)):
        ax.text(0.5, 0.5, "coherence unknown (one average)", transform=ax.transAxes, ha="center")
    else:
        ax.plot(frf.freq_hz, frf.coherence, ".", ms=2)
    ax.axhline(threshold, color="C3", lw=0.8, ls="--")
    ax.set_ylim(0.0, 1.05)
