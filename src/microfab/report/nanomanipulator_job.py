"""Figures of a nanomanipulator job on the twin: what only a run of the controllers has.

The ``nanomanipulator-msl`` job's report (`microfab run`) draws a
`microfab.machines.nanomanipulator.job.JobRun` with the trace figures of
`microfab.report.circle_tracking` (seed 001 Figs. 12-13, as for a measured trace) and
these: ‖Ŵ‖ and ``s`` of the RBF controllers against time (`fig_learning`), the control
effort (`fig_effort`) and the cured-line maps of one circle with and without warm-up
compensation (`fig_cure`, seed 001 Figs. 14-15, of a
`microfab.machines.nanomanipulator.cure.CircleCure`). Each returns a
:class:`matplotlib.figure.Figure` on an Agg canvas (`microfab.report.canvas.new_figure`)
and writes nothing.
"""

from __future__ import annotations

from matplotlib.figure import Figure as MplFigure

from microfab.machines.nanomanipulator.cure import PRINTS, CircleCure
from microfab.machines.nanomanipulator.job import JobRun
from microfab.report.canvas import new_figure

__all__ = ["fig_cure", "fig_effort", "fig_learning"]

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
