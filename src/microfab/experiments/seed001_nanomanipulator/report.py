"""Report of a ``nanomanipulator-msl`` job: seed 001 Figs. 12-15 redrawn on the twin.

The trace figures (Fig. 12 XY, Fig. 13a errors with the gate, Fig. 13b contour error
against phase, RMS per period) are those of a measured trace
(`microfab.report.circle_tracking`), so a twin run and `microfab nanomanipulator analyze`
look alike; this module adds what only a run of the controllers has: ‖Ŵ‖ and ``s``
against time, the control effort, and the cured-line maps with and without warm-up
compensation.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure as MplFigure

from microfab.machines.nanomanipulator_cure import PRINTS, CircleCure
from microfab.machines.nanomanipulator_job import JobRun
from microfab.report.canvas import new_figure

if TYPE_CHECKING:
    from microfab.experiments.seed001_nanomanipulator.results import NanomanipulatorResult

__all__ = ["fig_cure", "fig_effort", "fig_learning", "write_report"]

_AXES = (("x", "tab:red"), ("y", "tab:blue"))


def _circle_spans(ax: object, run: JobRun) -> None:
    """Shade each circle's periods on a time axis."""
    n, dt = run.reference.period_samples * run.reference.periods, run.dt
    for s in run.reference.starts:
        ax.axvspan(s * dt, (s + n) * dt, color="0.93", zorder=0)  # type: ignore[attr-defined]


def fig_learning(run: JobRun) -> MplFigure:
    """‖Ŵ‖ and ``s`` of both axes against time (logged every ``log_every`` samples)."""
    fig = new_figure(7.0, 4.6)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    t = run.log_index * run.dt
    for a, (name, col) in enumerate(_AXES):
        a1.plot(t, run.weight_norm[:, a] * 1e3, ".", ms=2, color=col, label=name)
        a2.plot(t, run.s[:, a], ".", ms=2, color=col, label=name)
    for ax in (a1, a2):
        _circle_spans(ax, run)
        ax.grid(True, alpha=0.3)
    a1.set_ylabel("‖Ŵ‖ [mV]")
    a2.set_ylabel("s = λe + ė [mm/s]")
    a2.set_xlabel("time [s]")
    a1.legend(loc="upper left", fontsize=8)
    a1.set_title("RBF weights and error function (shaded: circle periods)", fontsize=9)
    return fig


def fig_effort(run: JobRun) -> MplFigure:
    """Command of both axes against time (the control effort), V."""
    fig = new_figure(7.0, 3.0)
    ax = fig.subplots()
    t = run.time
    step = max(run.reference.n_samples // 20000, 1)
    for a, (name, col) in enumerate(_AXES):
        ax.plot(t[::step], run.command[::step, a], lw=0.6, color=col, label=name)
    _circle_spans(ax, run)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("command [V]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Control effort (PID between circles, RBF + RC on them)", fontsize=9)
    return fig


def fig_cure(cure: CircleCure) -> MplFigure:
    """Cured resin of one circle: whole loop and the closing point, per print."""
    names = [p for p in PRINTS if p in cure.prints]
    fig = new_figure(3.0 * len(names), 5.6)
    axes = fig.subplots(2, len(names), squeeze=False)
    for j, name in enumerate(names):
        pr = cure.prints[name]
        d = pr.dose
        cured = d.dose_j_m2 > cure.threshold_j_m2
        ext = [v * 1e3 for v in d.extent_m]  # m -> mm
        top, bottom = axes[0, j], axes[1, j]
        top.imshow(cured, origin="lower", extent=ext, cmap="Greys", interpolation="nearest")
        top.set_title(f"{name}", fontsize=9)
        top.set_xlabel("x [mm]", fontsize=8)
        top.set_aspect("equal")
        # closing point: where the loop starts
        p0 = pr.loop.widths.points_m[0] * 1e3
        half = 0.012  # mm shown around the closing point (assumed: 4x the 3 µm spot)
        bottom.imshow(cured, origin="lower", extent=ext, cmap="Greys", interpolation="nearest")
        bottom.set_xlim(p0[0] - half, p0[0] + half)
        bottom.set_ylim(p0[1] - half, p0[1] + half)
        bottom.set_aspect("equal")
        lp = pr.loop
        bottom.set_title(
            f"gap {lp.gap_m * 1e6:.2f} µm, width {lp.closing_width_m * 1e6:.2f} µm", fontsize=8
        )
        bottom.set_xlabel("x [mm]", fontsize=8)
    axes[0, 0].set_ylabel("y [mm]")
    axes[1, 0].set_ylabel("y [mm] (closing point)")
    fig.suptitle(f"Circle {cure.circle + 1}: cured resin (black)", fontsize=10)
    return fig


def _notes(result: NanomanipulatorResult) -> list[str]:
    run = result.run
    cfg = run.config
    noise = run.noise_rms_mm * 1e6
    return [
        "Twin: seed 001 eq. 9 per axis with the §4.1 nonlinear terms (x in mm, time in "
        "1/ω_n), a bounded disturbance d(t) and sensor noise "
        f"{noise[0]:.0f} / {noise[1]:.0f} nm rms (x / y); every value and its source in "
        "microfab/data/nanomanipulator_twin.toml.",
        "Controllers: PID between circles (assumed, the seed does not say); on each circle a "
        "fresh RBF network (seed eqs. 2-5, l = "
        f"{cfg.rbf.n_nodes} per axis, centres from one period) handed over bumplessly, inside "
        "the plug-in RC (Fig. 6-7)" + ("" if cfg.rc.enabled else " (RC off in this job)") + ".",
        f"Laser gate: opens at the next contour start after a period with RMS error norm "
        f"< {cfg.gate_threshold_mm * 1e3:g} µm (our reading of 'reaches submicrons'), "
        "exposes one loop.",
        f"Laser warm-up {cfg.laser.warmup_s * 1e3:g} ms (dead time "
        f"{cfg.laser.delay_s * 1e3:g} ms + rise {cfg.laser.rise_s * 1e3:g} ms, assumed; the "
        "seed's 'few microseconds' cannot open a visible gap at this speed).",
        "Errors are r − y as the sensor shows it; axial and contour RMS over all periods of "
        "every circle.",
        f"The run is saved per period under run/; resumed from chunk {run.resumed_from}."
        if run.resumed_from
        else "The run is saved per period under run/ (running the job again resumes).",
    ]


def write_report(result: NanomanipulatorResult, out: Path, title: str) -> Path:
    """Render the figures and write ``report.html`` into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.circle_tracking import (
        fig_contour_phase,
        fig_error_time,
        fig_period_rms,
        fig_xy,
    )
    from microfab.report.page import Figure, page_html, write_page

    run, m = result.run, result.metrics
    ref = run.reference.position
    thr_nm = run.config.gate_threshold_mm * 1e6
    figs = [
        Figure(
            name="xy.png",
            png=render_png(fig_xy(ref, run.measured, run.laser)),
            caption="Redraws seed 001 Fig. 12: reference and measured path, laser-on part "
            "highlighted.",
        ),
        Figure(
            name="error_time.png",
            png=render_png(fig_error_time(run.time, ref, run.measured, m)),
            caption="Redraws seed 001 Fig. 13a: x and y tracking error against time, with "
            "the gate instants.",
        ),
        Figure(
            name="contour_phase.png",
            png=render_png(fig_contour_phase(m)),
            caption="Redraws seed 001 Fig. 13b: contour error against phase, averaged over "
            "the circles.",
        ),
        Figure(
            name="period_rms.png",
            png=render_png(fig_period_rms(m, threshold_nm=thr_nm)),
            caption="RC convergence: RMS error norm per period and circle, gate threshold.",
        ),
        Figure(
            name="learning.png",
            png=render_png(fig_learning(run)),
            caption="‖Ŵ‖ and s of the RBF controllers against time.",
        ),
        Figure(
            name="effort.png",
            png=render_png(fig_effort(run)),
            caption="Control effort.",
        ),
    ]
    for c in result.cures:
        figs.append(
            Figure(
                name=f"cure_{c.circle + 1}.png",
                png=render_png(fig_cure(c)),
                caption=f"Redraws seed 001 Figs. 14-15 for circle {c.circle + 1}: cured "
                "resin of the gated print, the warm-up-compensated one and an ungated "
                "first loop; below, the closing point.",
            )
        )
    per = np.round(m.period_rms_nm).astype(int).tolist()
    text = page_html(
        title,
        intro=f"{len(run.circles)} circle(s) on the seed 001 twin; RMS error per period "
        f"(nm): {per}.",
        notes=_notes(result) + [f"Failure: {f}" for f in result.failures()],
        figures=figs,
        tables=result.comparison(),
    )
    return write_page(out, text, figs)
