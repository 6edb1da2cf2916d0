"""Report of a ``laser-micromachining`` job: seed 004 Figs. 3, 4 and 7 redrawn on the twin."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from microfab.report.contour import (
    fig_axis_errors,
    fig_ballbar,
    fig_contour_time,
    fig_disturbance,
    fig_focus,
    fig_force,
    fig_speed,
)

if TYPE_CHECKING:
    from microfab.experiments.seed004_laser.results import LaserResult

__all__ = ["write_report"]


def _notes(result: LaserResult) -> list[str]:
    job = result.main.job
    tw = job.twin
    return [
        "Twin: seed 004 eq. 2 per axis with Table I limits; masses, force constants (10 % "
        "off the controller's nominal), amplifier, LuGre friction, cogging, cable and "
        "encoder noise assumed, each with its reason in microfab/data/lmw_stage.toml"
        + ("" if tw.nonlinear else " (nonlinear parts off in this job)")
        + ("" if tw.noise else " (noise off)")
        + ".",
        f"Reference: the drawing's contour through a time-based spline (seed eq. 1) at "
        f"{job.motion.speed_m_s * 1e3:g} mm/s for {job.motion.laps} lap(s), ramps and "
        "knots as documented in microfab/trajectory/contour_laps.py; checked against "
        "Table I (speed, acceleration, 12 N peak, 3 N RMS force) before running.",
        f"Controller: {job.control.law} (axis loop {job.control.bandwidth_hz:g} Hz, DOB "
        f"{job.control.dob_bandwidth_hz:g} Hz, K_a = {job.control.k_a:g}, contour loop "
        f"{job.control.contour_bandwidth_hz:g} Hz; all assumed, the seed gives no gains)"
        + (
            "; friction feedforward from the twin's LuGre law (not in the seed)."
            if job.control.friction_ff
            else "."
        ),
        "Contour error: distance of the true (or measured) position to the exact drawing "
        "(foot point), signed; 'after lap 1' leaves out the first full-speed lap.",
    ]


def write_report(result: LaserResult, out: Path, title: str) -> Path:
    """Render the figures and write ``report.html`` into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.page import Figure, page_html, write_page

    m = result.main
    fig3 = result.fig3_run()
    runs = {f"{m.job.control.law}": m}
    if result.baseline is not None:
        runs["preview-dob (no correction)"] = result.baseline
    figs = [
        Figure(name="axis_errors.png", png=render_png(fig_axis_errors(fig3 or m, fig3 is not None)),
               caption=(f"Redraws seed 004 Fig. 3 ({fig3.job.control.law} run)"
                        if fig3 is not None else "Axis tracking (not the seed's Fig. 3 set-up)")
               + ": x and y tracking error with the ±0.5 µm band."),
        Figure(name="ballbar.png", png=render_png(fig_ballbar(m)),
               caption="Redraws seed 004 Fig. 4, ballbar style: the measured path with its "
               "contour error magnified."),
        Figure(name="contour_time.png", png=render_png(fig_contour_time(runs)),
               caption="Seed 004 Fig. 7 as a time plot: contour error with and without the "
               "correction."),
        Figure(name="force.png", png=render_png(fig_force(m)),
               caption="Motor force against Table I's 12 N peak and 3 N continuous force."),
    ]  # fmt: skip
    dob_run = m if m.dob is not None else result.baseline
    if dob_run is not None and dob_run.dob is not None:
        figs.append(
            Figure(
                name="disturbance.png",
                png=render_png(fig_disturbance(dob_run, dob_run.dob)),
                caption="The DOB's estimate of the load force (eq. 4) beside the twin's true "
                "F_l (friction, cogging, cable, and the 10 % mass and force-constant "
                "errors it also absorbs), preview-dob run.",
            )
        )
    if result.focus is not None:
        figs.append(
            Figure(
                name="focus.png",
                png=render_png(fig_focus(result.focus)),
                caption="Redraws seed 004 Fig. 6: detector output and z encoder of the focus "
                "search from 500 µm off focus, both laws, band ±DOF/2 about the (fixed) focus.",
            )
        )
    if result.sweep:
        figs.append(
            Figure(
                name="speed.png",
                png=render_png(fig_speed(result.sweep)),
                caption="Largest contour error after lap 1 against speed.",
            )
        )
    text = page_html(
        title,
        intro=f"Contour {m.job.contour} of {m.job.drawing!r} on the seed 004 stage twin.",
        notes=_notes(result) + [f"Failure: {f}" for f in result.failures()],
        figures=figs,
        tables=result.comparison(),
    )
    return write_page(out, text, figs)
