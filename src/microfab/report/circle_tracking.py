"""Seed 001 §4.2 tracking drawn: Figs. 12-13, the RC's convergence, the table, the page.

The figures draw a trace and its `~microfab.measure.circle_tracking.TrackingMetrics`
(a twin run of the nanomanipulator job, or a measured trace); `tracking_table` sets the
metrics beside the seed's; `write_analysis` writes the page of
``microfab nanomanipulator analyze`` (`microfab.measure.circle_trace.Analysis`).

Every function returns a :class:`matplotlib.figure.Figure` on an Agg canvas
(`microfab.report.canvas.new_figure`, no pyplot) and writes nothing; the report renders
them (`microfab.report.canvas.render_png`). Positions are in mm, errors in nm, the same
samples for a twin run and a measured trace.

References
----------
Seed 001 §4.2: Fig. 12 (tracking result in the plane), Fig. 13a (x and y tracking errors
against time), Fig. 13b (contour error against phase, averaged over the four circles).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from microfab.core.provenance import Shows, quantity
from microfab.measure.circle_trace import Analysis
from microfab.measure.circle_tracking import (
    NM_PER_MM,
    SEED_AXIAL_RMS_NM,
    SEED_CONTOUR_RMS_NM,
    SEED_GATE_PERIODS,
    TrackingMetrics,
)
from microfab.report.canvas import new_figure, render_png
from microfab.report.page import Figure as PageFigure
from microfab.report.page import page_html, write_page
from microfab.report.provenance import OURS, labelled
from microfab.report.tables import DASH, Table, ratio, versus

__all__ = [
    "analysis_figures",
    "analysis_page",
    "fig_contour_phase",
    "fig_error_time",
    "fig_period_rms",
    "fig_xy",
    "tracking_table",
    "write_analysis",
]

_REF = {"color": "0.45", "linestyle": "--", "linewidth": 0.9}
_OUT = {"color": "tab:blue", "linestyle": "-", "linewidth": 0.8}
_ON = {"color": "tab:red", "linestyle": "-", "linewidth": 1.6}
_AXIS_COLOURS = ("tab:red", "tab:blue")  # x, y
_SEED = {"color": "black", "linestyle": ":", "linewidth": 1.2}
#: Default gate threshold drawn on the period RMS, nm (`GateConfig`'s 1 µm, our reading
#: of seed 001 §4.2 "reaches submicrons").
THRESHOLD_NM = 1000.0


def _check(reference: np.ndarray, output: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(reference, dtype=float)
    y = np.asarray(output, dtype=float)
    if r.ndim != 2 or r.shape[1] != 2 or y.shape != r.shape:
        raise ValueError(
            f"reference and output must both be shaped (n, 2), got {r.shape} and {y.shape}"
        )
    return r, y


def _runs(metrics: TrackingMetrics) -> list[tuple[int, int]]:
    span = metrics.periods * metrics.period_samples
    return [(s, s + span) for s in metrics.starts]


def fig_xy(reference: np.ndarray, output: np.ndarray, laser: np.ndarray) -> Figure:
    """Reference and output in the plane, the laser-on part highlighted (seed Fig. 12).

    Parameters
    ----------
    reference, output : numpy.ndarray
        Reference and measured output, mm, shape (n, 2).
    laser : numpy.ndarray
        Laser on per sample, bool, shape (n,).

    Returns
    -------
    matplotlib.figure.Figure
        One axes, equal aspect: output (thin blue), output with the laser on (thick
        red; gaps between exposures left open) and the reference (thin dashed, on top).
    """
    r, y = _check(reference, output)
    on = np.asarray(laser, dtype=bool)
    if on.shape != (r.shape[0],):
        raise ValueError(f"laser must be shaped ({r.shape[0]},), got {on.shape}")
    fig = new_figure(5.6, 5.8)
    ax = fig.add_subplot()
    ax.plot(y[:, 0], y[:, 1], label="output", **_OUT)
    lit = np.where(on[:, None], y, np.nan)  # NaN breaks the line where the laser is off
    if on.any():
        ax.plot(lit[:, 0], lit[:, 1], label="output, laser on", **_ON)
    # the reference last and thin, so the output under it cannot hide it
    ax.plot(r[:, 0], r[:, 1], label="reference", **{**_REF, "color": "black", "linewidth": 0.6})
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("Tracking in the plane (seed 001 Fig. 12)")
    ax.grid(True, alpha=0.3)
    fig.legend(
        *ax.get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize="small"
    )
    return fig


def fig_error_time(
    time: np.ndarray, reference: np.ndarray, output: np.ndarray, metrics: TrackingMetrics
) -> Figure:
    """Tracking error ``r − y`` of x and y against time with the gate instants (seed Fig. 13a).

    Parameters
    ----------
    time : numpy.ndarray
        Sample times, s, shape (n,).
    reference, output : numpy.ndarray
        Reference and measured output, mm, shape (n, 2).
    metrics : TrackingMetrics
        The job's metrics (circle runs, gate samples, axial RMS).

    Returns
    -------
    matplotlib.figure.Figure
        Two stacked axes (x, y), error in nm; circle runs shaded, laser switch-on
        instants as vertical lines. The error range is set by the circle runs: the moves
        between circles may leave it.
    """
    r, y = _check(reference, output)
    t = np.asarray(time, dtype=float)
    if t.shape != (r.shape[0],):
        raise ValueError(f"time must be shaped ({r.shape[0]},), got {t.shape}")
    e = (r - y) * NM_PER_MM
    runs = _runs(metrics)
    in_runs = np.concatenate([e[a:b] for a, b in runs])
    lim = 1.15 * float(np.max(np.abs(in_runs))) if in_runs.size else 1.0
    fig = new_figure(7.5, 5.0)
    axs = fig.subplots(2, 1, sharex=True)
    for i, (ax, name) in enumerate(zip(axs, "xy", strict=True)):
        ax.plot(t, e[:, i], color=_AXIS_COLOURS[i], linewidth=0.6, label=f"{name} error")
        for c, (a, b) in enumerate(runs):
            ax.axvspan(
                t[a], t[b - 1], color="0.92", zorder=0, label="circle runs" if not c else None
            )
        gates = [k for k in metrics.gate_sample if k is not None]
        for j, k in enumerate(gates):
            ax.axvline(
                t[k],
                color="black",
                linestyle="--",
                linewidth=1.0,
                label="laser on" if j == 0 else None,
            )
        seed = SEED_AXIAL_RMS_NM[name]
        ax.set_ylim(-max(lim, 1.2 * seed), max(lim, 1.2 * seed))
        ax.set_ylabel(f"{name} error (nm)")
        ax.set_title(
            f"{name}: RMS {metrics.axial_rms_nm[i]:.1f} nm over the runs (seed {seed:g} nm)",
            fontsize="medium",
        )
        ax.grid(True, alpha=0.3)
    axs[-1].set_xlabel("time (s)")
    axs[-1].set_xlim(t[0], t[-1])
    fig.suptitle("Tracking errors (seed 001 Fig. 13a)")
    fig.legend(
        *axs[0].get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize="small"
    )
    return fig


def fig_contour_phase(metrics: TrackingMetrics) -> Figure:
    """Contour error against phase, mean over the circles (seed Fig. 13b).

    Parameters
    ----------
    metrics : TrackingMetrics
        The job's metrics.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: the binned mean contour error (nm) over the unwrapped phase of the
        circle runs (in turns, 0 at each run's start), our RMS and the seed's 769.5 nm as
        ± lines.
    """
    turns = metrics.phase_rad / (2.0 * np.pi)
    fig = new_figure(7.5, 3.8)
    ax = fig.add_subplot()
    ax.plot(
        turns,
        metrics.contour_vs_phase_nm,
        color="tab:blue",
        linewidth=0.9,
        label=f"mean of {metrics.n_circles} circle(s)",
    )
    ours = metrics.contour_rms_nm
    for sign in (1.0, -1.0):
        ax.axhline(
            sign * ours,
            color="tab:blue",
            linestyle="--",
            linewidth=1.0,
            label=f"± our RMS {ours:.1f} nm" if sign > 0 else None,
        )
        ax.axhline(
            sign * SEED_CONTOUR_RMS_NM,
            **_SEED,
            label=f"± seed RMS {SEED_CONTOUR_RMS_NM:g} nm" if sign > 0 else None,
        )
    ax.set_xlabel("phase from the run's start (turns)")
    ax.set_ylabel("contour error ‖y − c‖ − R (nm)")
    ax.set_xlim(0.0, metrics.periods)
    ax.set_title("Contour error vs phase (seed 001 Fig. 13b)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize="small", framealpha=0.9)
    return fig


def fig_period_rms(metrics: TrackingMetrics, *, threshold_nm: float = THRESHOLD_NM) -> Figure:
    """RMS error norm per period, one line per circle: the RC's convergence and the gate.

    Parameters
    ----------
    metrics : TrackingMetrics
        The job's metrics.
    threshold_nm : float
        Gate threshold drawn as a line, nm (default 1000 nm).

    Returns
    -------
    matplotlib.figure.Figure
        One axes, log y (nm) against the 1-based period; the threshold, the seed's
        3-4 periods (shaded) and each circle's gate period (marker) drawn.
    """
    if not (np.isfinite(threshold_nm) and threshold_nm > 0):
        raise ValueError(f"threshold_nm must be positive, got {threshold_nm}")
    k = np.arange(1, metrics.periods + 1)
    fig = new_figure(6.4, 4.0)
    ax = fig.add_subplot()
    lo, hi = SEED_GATE_PERIODS
    ax.axvspan(lo - 0.5, hi + 0.5, color="0.9", zorder=0, label=f"seed: gate in {lo}-{hi} periods")
    for i in range(metrics.n_circles):
        line = ax.semilogy(
            k,
            metrics.period_rms_nm[i],
            marker="o",
            markersize=3,
            linewidth=1.0,
            label=f"circle {i + 1}",
        )
        g = metrics.gate_period[i]
        if g is not None and 1 <= g <= metrics.periods:
            ax.plot(
                [g],
                [metrics.period_rms_nm[i, g - 1]],
                marker="*",
                markersize=11,
                color=line[0].get_color(),
                linestyle="none",
            )
    ax.axhline(
        threshold_nm,
        color="black",
        linestyle="--",
        linewidth=1.0,
        label=f"gate threshold {threshold_nm:g} nm",
    )
    ax.set_xlabel("period")
    ax.set_ylabel("RMS of ‖r − y‖ per period (nm)")
    ax.set_xticks(k)
    ax.set_title("Convergence per period (★: laser switched on)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(loc="upper right", fontsize="small", framealpha=0.9)
    return fig


def _opt(v: float | None, fmt: str = "{:.1f}") -> str:
    return DASH if v is None else fmt.format(v)


def tracking_table(metrics: TrackingMetrics, *, seed: bool = True) -> Table:
    """Ours beside seed 001 §4.2 (axial and contour RMS, gate periods, exposed RMS).

    With ``seed=False`` (a set-up other than the seed's §4.2 pattern and twin) ours alone:
    no seed number is set beside a run of another set-up.
    """
    f0 = "{:.1f}".format
    if not seed:
        rows = [(f"axial RMS {a} [nm]", f0(metrics.axial_rms_nm[i])) for i, a in enumerate("xy")]
        rows.append(("contour RMS [nm]", f0(metrics.contour_rms_nm)))
        for i in range(metrics.n_circles):
            rows.append((f"circle {i + 1}: gate period", _opt(metrics.gate_period[i], "{}")))
            rows.append((f"circle {i + 1}: exposed RMS [nm]", _opt(metrics.exposed_rms_nm[i])))
        return labelled(
            Table(
                title="Tracking (not the seed's set-up: ours alone)",
                columns=("quantity", "ours"),
                rows=rows,
                note="Error r − y as the sensor shows it, over every period of every circle "
                "(moves and pauses left out). The seed's §4.2 numbers are for four 0.15 mm "
                "circles in a 0.5 mm field on the calibrated twin; this run differs, so they "
                "are not set beside it.",
            ),
            OURS,
        )
    rows = [
        (
            f"axial RMS {a} [nm]",
            versus(metrics.axial_rms_nm[i], SEED_AXIAL_RMS_NM[a], f0),
            ratio(metrics.axial_rms_nm[i], SEED_AXIAL_RMS_NM[a]),
        )
        for i, a in enumerate("xy")
    ]
    rows.append(
        (
            "contour RMS [nm]",
            versus(metrics.contour_rms_nm, SEED_CONTOUR_RMS_NM, f0),
            ratio(metrics.contour_rms_nm, SEED_CONTOUR_RMS_NM),
        )
    )
    from microfab.machines.nanomanipulator.calibration import axial_quantity

    shows = [Shows((axial_quantity(a),)) for a in "xy"]
    shows.append(Shows((quantity("001", "§4.2", "contour RMS"),)))
    lo, hi = SEED_GATE_PERIODS
    for i in range(metrics.n_circles):
        shows += [Shows((quantity("001", "§4.2", "gate period"),)), OURS]
        g = metrics.gate_period[i]
        rows.append((f"circle {i + 1}: gate period", f"{_opt(g, '{}')} / {lo}-{hi}", DASH))
        rows.append(
            (f"circle {i + 1}: exposed RMS [nm]", f"{_opt(metrics.exposed_rms_nm[i])}", DASH)
        )
    return labelled(
        Table(
            title="Seed 001 §4.2 tracking, ours / seed",
            columns=("quantity", "ours / seed", "ratio"),
            rows=rows,
            note="Error r − y as the sensor shows it, over every period of every circle "
            "(moves and pauses left out); seed 001 §4.2, Fig. 13: axial 485.8 / 885.8 nm, "
            "contour 769.5 nm RMS, laser on after 3-4 periods.",
        ),
        shows,
    )


def analysis_figures(analysis: Analysis) -> list[PageFigure]:
    """The report's figures, rendered to PNG (nothing is written)."""
    tr, m = analysis.trace, analysis.metrics
    drawn = (
        (
            "xy.png",
            fig_xy(tr.reference, tr.output, analysis.laser),
            "Reference and output in the plane, laser-on part in red (seed 001 Fig. 12).",
        ),
        (
            "error_time.png",
            fig_error_time(tr.time, tr.reference, tr.output, m),
            "x and y tracking error r − y against time; grey: circle runs, dashed: laser "
            "switched on (seed 001 Fig. 13a). The error range is set by the circle runs.",
        ),
        (
            "contour_phase.png",
            fig_contour_phase(m),
            "Contour error against the phase from each run's start, mean over the circles, "
            "with our RMS and the seed's 769.5 nm (seed 001 Fig. 13b).",
        ),
        (
            "period_rms.png",
            fig_period_rms(m),
            "RMS error norm per period and circle (RC convergence), the 1 µm gate "
            "threshold and the seed's 3-4 periods.",
        ),
    )
    return [PageFigure(name=n, png=render_png(f), caption=c) for n, f, c in drawn]


def _period_table(m: TrackingMetrics) -> Table:
    rows = [
        (f"circle {i + 1}", *(f"{v:.1f}" for v in m.period_rms_nm[i])) for i in range(m.n_circles)
    ]
    return Table(
        title="RMS of ‖r − y‖ per period [nm]",
        columns=("circle", *(str(k + 1) for k in range(m.periods))),
        rows=rows,
    )


def analysis_page(analysis: Analysis, figures: list[PageFigure]) -> str:
    """The report's HTML text."""
    tr, cfg = analysis.trace, analysis.config
    notes = [
        f"Trace {tr.path}: {tr.n_samples} samples at {1.0 / tr.dt:g} Hz; columns time, "
        "ref_x, ref_y, x, y (mm), laser (0/1).",
        f"Pattern: {cfg.n_circles} circle(s) of {cfg.diameter_mm:g} mm in a "
        f"{cfg.field_mm:g} mm field, {cfg.periods} periods of {cfg.period_s:g} s each, "
        f"pause {cfg.pause_s:g} s, move {cfg.move_s:g} s, spin-up/down {cfg.ramp_s:g} s.",
        "Error r − y as the sensor shows it; axial and contour RMS over every period of "
        "every circle, moves and pauses left out (definitions: "
        "microfab.measure.circle_tracking).",
        "Contour error ‖y − c‖ − R; Fig. 13b bins it on the reference's phase from each "
        "run's start and averages over the circles (seed 001 §4.2).",
    ]
    return page_html(
        "Seed 001 nanomanipulator: measured trace",
        intro="Tracking metrics and figures of seed 001 §4.2 from a measured trace, "
        "ours beside the seed's.",
        notes=notes,
        figures=figures,
        tables=[tracking_table(analysis.metrics), _period_table(analysis.metrics)],
    )


def write_analysis(analysis: Analysis, out_dir: str | Path) -> Path:
    """Render every figure, then write them and ``report.html`` into ``out_dir``.

    Returns
    -------
    Path
        The path of ``report.html``.
    """
    figures = analysis_figures(analysis)  # drawn before anything is written
    return write_page(out_dir, analysis_page(analysis, figures), figures)
