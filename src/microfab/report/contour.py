"""Figures and the page of a contouring run: axis errors, ballbar, contour error in time.

What ``microfab laser analyze`` writes for a measured trace (`write_analysis`, from
`microfab.measure.contour_trace`), and the figures the seed 004 reproduction redraws on
its twin runs (Figs. 3, 4 and 7). Only draws (matplotlib, through
`microfab.report.canvas.new_figure`): the figures of merit come from
`microfab.measure.contour`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path as FilePath

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.geometry.path import Path
from microfab.geometry.project import project_points
from microfab.measure.contour import AxisErrors, ContourErrors
from microfab.measure.contour_trace import TraceAnalysis
from microfab.report.canvas import new_figure
from microfab.report.tables import Table

__all__ = [
    "AXIS_COLOURS",
    "analysis_table",
    "lap_span",
    "plot_axis_errors",
    "plot_ballbar",
    "plot_contour_time",
    "write_analysis",
]

#: Axis names and their colours in every figure.
AXIS_COLOURS = (("x", "tab:red"), ("y", "tab:blue"))


def lap_span(ax: object, span: tuple[float, float] | None) -> None:
    """Shade the full-speed laps (``span``: start and end time, s) on a time axis."""
    if span is not None:
        ax.axvspan(*span, color="0.94", zorder=0)  # type: ignore[attr-defined]


def plot_axis_errors(
    time: np.ndarray,
    reference: np.ndarray,
    measured: np.ndarray,
    axis: AxisErrors,
    span: tuple[float, float] | None = None,
) -> MplFigure:
    """Seed 004 Fig. 3: x and y tracking errors against time, with the ±0.5 µm band.

    ``time`` (s, (n,)), ``reference`` and ``measured`` (m, (n, 2)); ``axis`` the errors'
    figures (`microfab.measure.contour.axis_errors`); ``span`` the laps' time span to shade.
    """
    fig = new_figure(7.0, 4.2)
    axes = fig.subplots(2, 1, sharex=True)
    e = (np.asarray(reference) - np.asarray(measured)) * 1e6
    band = axis.band_m * 1e6
    for k, (ax, (name, col)) in enumerate(zip(axes, AXIS_COLOURS, strict=True)):
        lap_span(ax, span)
        ax.plot(time, e[:, k], lw=0.6, color=col)
        for s in (-band, band):
            ax.axhline(s, color="k", lw=0.6, ls="--")
        frac = axis.fraction_below[k] * 100
        ax.set_ylabel(f"e_{name} [µm]")
        ax.set_title(
            f"{name}: {frac:.1f} % of lap samples within ±{band:g} µm, peak "
            f"{axis.peak_m[k] * 1e6:.2f} µm (seed: < 0.5, peaks 0.8 µm)",
            fontsize=8,
        )
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]" + (" (shaded: full-speed laps)" if span else ""))
    return fig


def plot_ballbar(path: Path, measured: np.ndarray, magnify: float | None = None) -> MplFigure:
    """Seed 004 Fig. 4, ballbar style: the contour and the trace, radial error magnified.

    Each measured point (m, (n, 2)) is drawn at its foot point on the contour plus
    ``magnify`` times its contour error along the normal (default: the error's largest
    value shown as 15 % of the contour's size).
    """
    pr = project_points(path, measured)
    bb = path.bbox
    size = max(bb[2] - bb[0], bb[3] - bb[1])
    worst = float(np.max(np.abs(pr.distance))) or 1.0
    m = magnify if magnify is not None else 0.15 * size / worst
    shown = pr.foot + m * pr.distance[:, None] * pr.normal
    fig = new_figure(5.2, 5.2)
    ax = fig.subplots()
    pts = path.flatten(size * 1e-4)
    ax.plot(pts[:, 0] * 1e6, pts[:, 1] * 1e6, color="k", lw=0.8, label="drawing")
    ax.plot(shown[:, 0] * 1e6, shown[:, 1] * 1e6, color="tab:green", lw=0.6,
            label=f"measured, error x{m:.3g}")  # fmt: skip
    ax.set_aspect("equal")
    ax.set_xlabel("x [µm]")
    ax.set_ylabel("y [µm]")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(f"Contour error magnified {m:.3g}x (largest {worst * 1e9:.0f} nm)", fontsize=8)
    return fig


def plot_contour_time(
    series: Mapping[str, tuple[np.ndarray, ContourErrors]],
    span: tuple[float, float] | None = None,
) -> MplFigure:
    """Contour error against time: ``label -> (time s (n,), ContourErrors)``."""
    fig = new_figure(7.0, 3.2)
    ax = fig.subplots()
    lap_span(ax, span)
    for label, (t, ce) in series.items():
        ax.plot(t, ce.error_m * 1e9, lw=0.7,
                label=f"{label}: {ce.steady_label} {ce.steady_max() * 1e9:.0f} nm")  # fmt: skip
    ax.set_xlabel("time [s]" + (" (shaded: full-speed laps)" if span else ""))
    ax.set_ylabel("contour error [nm]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def analysis_table(a: TraceAnalysis) -> Table:
    """The figures of merit beside the seed's."""
    rows = [
        ("samples / full laps", f"{a.time.size} / {len(a.laps)}"),
        ("reference off the drawing, max [nm]", f"{a.reference_deviation_m * 1e9:.3g}"),
        ("within ±0.5 µm, x / y [%]",
         " / ".join(f"{v * 100:.1f}" for v in a.axis.fraction_below) + "  (seed: 'generally')"),
        ("peak |e|, x / y [µm]",
         " / ".join(f"{v * 1e6:.3f}" for v in a.axis.peak_m) + "  (seed: 0.8)"),
        ("contour error per lap, max [nm]",
         ", ".join(f"{v * 1e9:.1f}" for v in a.contour.lap_max_m)),
    ]  # fmt: skip
    return Table(title="Measured trace against the drawing", columns=("figure", "value"),
                 rows=rows)  # fmt: skip


def write_analysis(a: TraceAnalysis, out: str | FilePath, title: str) -> FilePath:
    """Write ``report.html`` with the figures of a measured trace into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.page import Figure, page_html, write_page

    figs = [
        Figure(name="axis_errors.png",
               png=render_png(plot_axis_errors(a.time, a.reference, a.measured, a.axis)),
               caption="As seed 004 Fig. 3: x and y tracking error with the ±0.5 µm band."),
        Figure(name="ballbar.png", png=render_png(plot_ballbar(a.path, a.measured)),
               caption="As seed 004 Fig. 4, ballbar style: the measured path, its contour "
               "error magnified."),
        Figure(name="contour_time.png",
               png=render_png(plot_contour_time({"measured": (a.time, a.contour)})),
               caption="Contour error of the encoder against the exact drawing."),
    ]  # fmt: skip
    text = page_html(
        title,
        intro=f"{a.time.size} samples, {len(a.laps)} full lap(s) of the drawing's contour.",
        notes=[
            "Contour error: signed distance of the encoder position to the exact drawing "
            "(foot point); laps counted along the reference.",
        ],
        figures=figs,
        tables=(analysis_table(a),),
    )
    return write_page(FilePath(out), text, figs)
