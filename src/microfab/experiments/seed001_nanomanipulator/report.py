"""Report of a ``nanomanipulator-msl`` job: seed 001 Figs. 12-15 redrawn on the twin.

Assembles the page: the trace figures (Fig. 12 XY, Fig. 13a errors with the gate,
Fig. 13b contour error against phase, RMS per period) are those of a measured trace
(`microfab.report.circle_tracking`), so a twin run and `microfab nanomanipulator analyze`
look alike; what only a run of the controllers has (‖Ŵ‖ and ``s`` against time, the
control effort, the cured-line maps with and without warm-up compensation) is drawn by
`microfab.report.nanomanipulator_job`. The notes say what the twin and the controllers
assume, the tables set ours beside the seed's (`results.NanomanipulatorResult.comparison`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from microfab.experiments.seed001_nanomanipulator.results import NanomanipulatorResult
    from microfab.machines.nanomanipulator.job import JobConfig

__all__ = ["write_report"]


def _circle_controller(cfg: JobConfig) -> str:
    """The circle controller of job config ``cfg`` in words."""
    if cfg.controller == "seed":
        return (
            f"the seed's RBF network alone (eqs. 2-5, l = {cfg.rbf.n_nodes} per axis, centres "
            "from one period) handed over bumplessly from the PID"
        )
    return (
        f"the proposed controller: eq. 6's linear part from eq. 9 (a PD at "
        f"{cfg.pid_bandwidth_hz:g} Hz with eq. 9's inverse) plus the RBF network (eqs. 2-5) "
        "as a model of the state, centres on a grid over the circle's state box, Ŵ(0) = 0"
    )


def _notes(result: NanomanipulatorResult) -> list[str]:
    run = result.run
    cfg = run.config
    noise = run.noise_rms_mm * 1e6
    return [
        "Twin: seed 001 eq. 9 per axis with the §4.1 nonlinear terms (x in mm, time in "
        "1/ω_n), a bounded disturbance d(t) and sensor noise "
        f"{noise[0]:.0f} / {noise[1]:.0f} nm rms (x / y); every value and its source in "
        "microfab/data/nanomanipulator_twin.toml.",
        "Controllers: PID between circles (assumed, the seed does not say); on each circle "
        + _circle_controller(cfg)
        + ", inside the plug-in RC (Fig. 6-7)"
        + ("" if cfg.rc.enabled else " (RC off in this job)")
        + ".",
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
    from microfab.report.nanomanipulator_job import fig_cure, fig_effort, fig_learning
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
