"""Figure plumbing shared by every plot: an Agg canvas without pyplot, atomic PNG files."""

from __future__ import annotations

import io
import os
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from microfab.io.atomic import atomic_path

__all__ = ["DPI", "new_figure", "render_png", "render_svg", "save_figure"]

DPI = 120


def new_figure(width: float, height: float) -> Figure:
    """Create a figure (inches) with an Agg canvas and constrained layout (no pyplot)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: int = DPI) -> Path:
    """Write a figure to PNG atomically.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Figure to save.
    path : str or os.PathLike
        Target file; its directory is created if missing. On failure the target is
        left as it was.
    dpi : int, optional
        Resolution, dots per inch (default 120).

    Returns
    -------
    pathlib.Path
        The target path.
    """
    target = Path(path)
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return target


def render_png(fig: Figure, *, dpi: int = DPI) -> bytes:
    """Render a figure to PNG bytes in memory.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Figure to render.
    dpi : int, optional
        Resolution, dots per inch (default 120).

    Returns
    -------
    bytes
        The PNG file content.
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def render_svg(fig: Figure) -> bytes:
    """Render a figure to SVG bytes in memory (vector, for zooming and print).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Figure to render.

    Returns
    -------
    bytes
        The SVG file content (UTF-8).
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="svg")
    return buf.getvalue()
