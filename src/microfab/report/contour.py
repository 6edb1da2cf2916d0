"""Figures and the page of a contouring run: axis errors, ballbar, contour error in time.

What ``microfab laser analyze`` writes for a measured trace (`write_analysis`, from
`microfab.measure.contour_trace`), and the figures of a ``laser-micromachining`` job on
the seed 004 twin (Figs. 3, 4, 6 and 7 redrawn; `fig_axis_errors` ... `fig_focus` of a
`microfab.machines.laser_stage.contour.ContourRun` or a
`microfab.machines.laser_stage.focus.FocusStudy`), with the speed sweep, the motor force,
the DOB's load-force estimate, and the tables of the runs' contour errors, of the speed
sweep and of the axis loops' margins. Only draws
(matplotlib, through `microfab.report.canvas.new_figure`) and formats: the figures of
merit come from `microfab.measure.contour` and the machine modules.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.geometry.path import Path
from microfab.geometry.project import project_points
from microfab.measure.contour import AxisErrors, ContourErrors
from microfab.measure.contour_trace import TraceAnalysis
from microfab.report.canvas import new_figure
from microfab.report.tables import Table
from microfab.trajectory.force_check import CONTINUOUS_FORCE_N, PEAK_FORCE_N

if TYPE_CHECKING:
    from microfab.control.margins import AxisMargins
    from microfab.machines.laser_stage.contour import ContourRun
    from microfab.machines.laser_stage.focus import FocusStudy

__all__ = [
    "AXIS_COLOURS",
    "acceleration_table",
    "analysis_table",
    "contour_table",
    "corner_label",
    "fig_axis_errors",
    "fig_ballbar",
    "fig_contour_time",
    "fig_disturbance",
    "fig_focus",
    "fig_force",
    "fig_speed",
    "lap_span",
    "margins_table",
    "plot_axis_errors",
    "plot_ballbar",
    "plot_contour_time",
    "plot_disturbance",
    "plot_focus",
    "speed_table",
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
    seed: bool = True,
) -> MplFigure:
    """Seed 004 Fig. 3: x and y tracking errors against time, with the ±0.5 µm band.

    ``time`` (s, (n,)), ``reference`` and ``measured`` (m, (n, 2)); ``axis`` the errors'
    figures (`microfab.measure.contour.axis_errors`); ``span`` the laps' time span to shade;
    ``seed`` also names the seed's figures in the titles (only for the seed's set-up).
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
            f"{axis.peak_m[k] * 1e6:.2f} µm" + (" (seed: < 0.5, peaks 0.8 µm)" if seed else ""),
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


# ---------------------------------------------------------------------------- twin runs
def fig_axis_errors(run: ContourRun, seed: bool = True) -> MplFigure:
    """`plot_axis_errors` of a twin run (``seed``: name the seed's figures)."""
    return plot_axis_errors(
        run.time, run.reference.trajectory.position, run.measured, run.axis, run.span, seed
    )


def fig_ballbar(run: ContourRun, magnify: float | None = None) -> MplFigure:
    """`plot_ballbar` of a twin run's full-speed laps."""
    ref = run.reference
    sl = ref.laps
    return plot_ballbar(ref.path, run.measured[sl], magnify)


def fig_contour_time(runs: Mapping[str, ContourRun]) -> MplFigure:
    """Seed 004 Fig. 7 as a time plot: contour error of each run (label → run)."""
    first = next(iter(runs.values()))
    return plot_contour_time({k: (r.time, r.contour) for k, r in runs.items()}, first.span)


def fig_speed(rows: Sequence[Mapping[str, float | str]]) -> MplFigure:
    """Largest contour error after lap 1 against speed, one line per law.

    ``rows``: dicts with ``law``, ``speed_mm_s`` and ``contour_max_nm``
    (`microfab.machines.laser_stage.contour.speed_point`).
    """
    fig = new_figure(5.6, 3.6)
    ax = fig.subplots()
    for law in sorted({str(r["law"]) for r in rows}):
        pts = sorted(
            (float(r["speed_mm_s"]), float(r["contour_max_nm"])) for r in rows if r["law"] == law
        )
        ax.loglog(*zip(*pts, strict=True), "o-", label=law)
    ax.set_xlabel("tangential speed [mm/s]")
    ax.set_ylabel("max contour error after lap 1 [nm]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def fig_force(run: ContourRun) -> MplFigure:
    """Motor force of both axes against the 12 N peak; RMS against the 3 N continuous."""
    fig = new_figure(7.0, 3.0)
    ax = fig.subplots()
    rms = np.sqrt(np.mean(run.force**2, axis=0))
    for k, (name, col) in enumerate(AXIS_COLOURS):
        ax.plot(run.time, run.force[:, k], lw=0.6, color=col,
                label=f"{name} (RMS {rms[k]:.3g} N / {CONTINUOUS_FORCE_N:g} N)")  # fmt: skip
    top = max(float(np.abs(run.force).max()) * 1.2, 1e-3)
    if top > 0.5 * PEAK_FORCE_N:
        for s in (-PEAK_FORCE_N, PEAK_FORCE_N):
            ax.axhline(s, color="k", lw=0.6, ls="--")
    ax.set_title(f"Motor force (Table I: {PEAK_FORCE_N:g} N peak)", fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("force [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def plot_disturbance(time: np.ndarray, true: np.ndarray, estimate: np.ndarray) -> MplFigure:
    """The DOB's estimate of the load force beside the twin's true ``F_l``, per axis.

    ``time`` (s, (n,)), ``true`` and ``estimate`` (N, (n, 2)).
    """
    fig = new_figure(7.0, 4.2)
    axes = fig.subplots(2, 1, sharex=True)
    for k, (name, col) in enumerate(AXIS_COLOURS):
        ax = axes[k]
        ax.plot(time, true[:, k], lw=0.8, color="0.3", label="true F_l (twin)")
        ax.plot(time, estimate[:, k], lw=0.6, color=col, label="DOB estimate K_fn î_d")
        gap = float(np.sqrt(np.mean((estimate[:, k] - true[:, k]) ** 2)))
        ax.set_ylabel(f"{name} force [N]")
        ax.set_title(f"{name}: RMS of estimate − true {gap:.3g} N", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    return fig


def fig_disturbance(run: ContourRun, estimate: np.ndarray) -> MplFigure:
    """`plot_disturbance` of a run and its DOB estimate (``ContourRun.dob``)."""
    return plot_disturbance(run.time, run.disturbance, estimate)


def plot_focus(
    runs: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    depth_of_focus_m: float,
) -> MplFigure:
    """Seed 004 Fig. 6: detector output (a) and z against time (b), with the ±DOF/2 band.

    ``runs``: label -> ``(time s, detector V, z m, focus m)``, each (n,).
    """
    fig = new_figure(7.0, 4.6)
    ax_y, ax_z = fig.subplots(2, 1, sharex=True)
    for label, (t, y, z, _f) in runs.items():
        ax_y.plot(t, y, lw=0.7, label=label)
        ax_z.plot(t, z * 1e6, lw=0.7, label=label)
    t, _, _, f = next(iter(runs.values()))
    half = 0.5 * depth_of_focus_m * 1e6
    ax_z.fill_between(t, f * 1e6 - half, f * 1e6 + half, color="0.9", zorder=0,
                      label=f"focus ± DOF/2 ({half:.1f} µm)")  # fmt: skip
    ax_y.set_ylabel("detector [V]")
    ax_y.set_title("(a) detector output (minimal at focus)", fontsize=8)
    ax_z.set_ylabel("z [µm]")
    ax_z.set_title("(b) z encoder", fontsize=8)
    ax_z.set_xlabel("time [s]")
    for ax in (ax_y, ax_z):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    return fig


def fig_focus(study: FocusStudy) -> MplFigure:
    """`plot_focus` of an autofocus study: both laws, and the tilted part if it ran."""
    runs = {"continuous (eqs. 16-17)": study.continuous, "discontinuous": study.discontinuous}
    if study.tilted is not None:
        runs[f"continuous, tilted {study.tilt_rad * 1e3:g} mrad"] = study.tilted
    return plot_focus(
        {k: (r.time, r.detector, r.z, r.focus) for k, r in runs.items()},
        study.continuous.depth_of_focus_m,
    )


def margins_table(margins: Sequence[AxisMargins]) -> Table:
    """The axis loops' margins (`microfab.machines.laser_stage.axis_margins`) as a table."""
    return Table(
        title="Axis loops (preview + DOB on the twin's linear axis), broken at the current",
        columns=("axis", "crossover [Hz]", "phase margin [°]", "gain margin [dB]",
                 "at [Hz]", "max |S| [dB]", "at [Hz]"),
        rows=[
            (
                m.axis,
                f"{m.margins.pm_freq_hz:.1f}",
                f"{m.margins.pm_deg:.1f}",
                f"{m.margins.gm_db:.1f}",
                f"{m.margins.gm_freq_hz:.0f}",
                f"{m.sensitivity_peak_db:.2f}",
                f"{m.sensitivity_peak_hz:.0f}",
            )
            for m in margins
        ],
        note="The plant is the twin's true axis (mass and force constant 10 % off the "
        "controller's nominal) with its amplifier lag; friction and saturation left out.",
    )  # fmt: skip


def contour_table(runs: Mapping[str, ContourRun]) -> Table:
    """Contour error of twin runs (label → run) against the exact drawing, per run."""
    return Table(
        title="Contour error against the exact drawing (true position)",
        columns=("run", "max after lap 1 (or of the only lap) [nm]", "RMS [nm]",
                 "measured max [nm]"),
        rows=[
            (
                name,
                f"{r.contour.steady_max() * 1e9:.1f}",
                f"{r.contour.rms() * 1e9:.1f}",
                f"{r.contour_measured.lap_max_m.max() * 1e9:.1f}",
            )
            for name, r in runs.items()
        ],
    )  # fmt: skip


def corner_label(row: Mapping[str, Any]) -> str:
    """The corners one slow-down covers, in words (a row of ``slowdowns`` in `summary.json`)."""
    corners = row["corners"]
    if not corners:
        words = "no corner (a curve)"
    elif len(corners) == 1:
        words = f"corner {corners[0]}"
    else:
        words = "corners " + "+".join(str(c) for c in corners) + " (too close to get back to speed)"
    return words + (", start from rest" if row["from_rest"] else "")


def slowdown_table(rows: Sequence[Mapping[str, Any]], speed_m_s: float, n_corners: int) -> Table:
    """Where a limited profile slowed on lap 1, and at which of the drawing's corners.

    ``rows``: the ``slowdowns`` of a laser job's ``summary.json`` (``at_mm``,
    ``speed_mm_s``, ``corners``, ``corner_at_mm``, ``from_rest``; distances along the
    path from the start point, mm); ``n_corners``: the drawing's corners.
    """
    named = sorted({c for r in rows for c in r["corners"]})
    missing = [c for c in range(1, n_corners + 1) if c not in named]
    return Table(
        title=f"Slowed below 90 % of {speed_m_s * 1e3:g} mm/s on lap 1 (the v/a/j planner, "
        "seed 004 Table I)",
        columns=(
            "where",
            "corners at [mm]",
            "slowest at [mm]",
            "slowest [mm/s]",
            "of the speed [%]",
        ),
        rows=[
            (
                corner_label(r),
                ", ".join(f"{c:.4f}" for c in r["corner_at_mm"]) or "-",
                f"{r['at_mm']:.4f}",
                f"{r['speed_mm_s']:.4g}",
                f"{100 * r['speed_mm_s'] * 1e-3 / speed_m_s:.1f}",
            )
            for r in rows
        ],
        note=f"The drawing has {n_corners} corner(s), numbered from the start point (corner "
        "1 when the start point is one) along the path"
        + (f"; not slowed below 90 %: {', '.join(map(str, missing))}" if missing else "")
        + ". The requested speed is kept where the limits allow it; a sharp corner is taken "
        "from rest; corners closer than the speed allows share one slow-down.",
    )


def acceleration_table(lowered: Mapping[str, Any]) -> Table:
    """The acceleration a limited plan lowered for the continuous force (``summary.json``)."""
    return Table(
        title="Acceleration lowered for Table I's continuous force",
        columns=(
            "asked [m/s²]",
            "used [m/s²]",
            "axis",
            "RMS force asked / used [N]",
            "continuous force [N]",
        ),
        rows=[
            (
                f"{lowered['asked_m_s2']:g}",
                f"{lowered['used_m_s2']:.3g}",
                lowered["axis"],
                f"{lowered['asked_rms_force_n']:.3g} / {lowered['used_rms_force_n']:.3g}",
                f"{lowered['continuous_force_n']:g}",
            )
        ],
        note="Planned at the asked acceleration, the RMS of M a on this axis over the whole "
        "reference passed the continuous force (seed 004 Table I); the planner lowered its "
        f"acceleration limit ({lowered['plans']} plans) until it held. The lap is slower "
        "than at the asked acceleration.",
    )


def speed_table(rows: Sequence[Mapping[str, Any]]) -> Table:
    """The speed sweep's rows (`microfab.machines.laser_stage.contour.speed_point`)."""
    return Table(
        title="Contour error against speed (max after lap 1)",
        columns=("law", "speed [mm/s]", "max [nm]", "RMS [nm]", "force peak [N]"),
        rows=[
            (
                r["law"],
                f"{r['speed_mm_s']:g}",
                f"{r['contour_max_nm']:.1f}",
                f"{r['contour_rms_nm']:.1f}",
                f"{r['force_peak_n']:.3g}",
            )
            for r in rows
        ],
    )
