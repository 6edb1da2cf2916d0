"""Report of an ``slm-shaping`` job: seed 003 part 2 Figs. 4-7 redrawn, shapers, scan time."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from microfab.experiments.seed003_slm.tables import NOTES
from microfab.report.slm import (
    plot_build,
    plot_jump_position,
    plot_jump_speed,
    plot_scan_time,
    plot_shaper_bode,
    plot_step_comparison,
)

if TYPE_CHECKING:
    from microfab.experiments.seed003_slm.results import ShapingResult

__all__ = ["write_report"]


def write_report(result: ShapingResult, out: Path, title: str) -> Path:
    """Render the figures and write ``report.html`` into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.page import Figure, page_html, write_page

    run = result.run
    s = run.settings
    fit = run.identification.fit
    figs = [
        Figure(name="frf_fit.png", png=render_png(fit.plot(title="Chirp FRF and fitted model")),
               caption="Redraws seed 003 part 2 Fig. 4: the twin's FRF from the chirp "
               f"({fit.frf.method}), the {fit.sampling.upper()}-aware fit and the coherence."),
        Figure(name="shaper_bode.png", png=render_png(plot_shaper_bode(run.shaper)),
               caption="Redraws Fig. 5: the fitted model, its inverse and the input shaper "
               f"({s.shaper.order} poles at {s.shaper.pole_hz:g} Hz)."),
        Figure(name="jump_position.png",
               png=render_png(plot_jump_position(run.jumps, s.rtc.bit_size_m)),
               caption=f"Redraws Fig. 6: a {s.jump_m * 1e3:.2f} mm jump at "
               f"{s.rtc.speeds.jump_m_s:g} m/s without and with the "
               f"{s.shaper.discretization.upper()} shaper, through the compiled loop."),
        Figure(name="jump_speed.png",
               png=render_png(plot_jump_speed(run.speed_jumps, s.rtc.speeds.jump_m_s)),
               caption="Redraws Fig. 7: mirror speed on a jump long enough to reach the jump "
               "speed (noise-free position)."),
        Figure(name="scan_time.png", png=render_png(plot_scan_time(run.scan)),
               caption="The layer's scan time: naive, fixed delays and dynamics-aware, without "
               "and with the shaper, by category."),
    ]  # fmt: skip
    if result.comparisons:
        curves = {
            c.twin: [
                (r.name, r.t_s, (r.position - c.settings.start_bit) / c.settings.jump_bit)
                for r in c.rows
                if r.t_s.size
            ]
            for c in result.comparisons
        }
        figs.append(
            Figure(
                name="shaper_steps.png",
                png=render_png(plot_step_comparison(curves)),
                caption="Jump responses of every shaper on both twins (band ±2 %); shapers whose "
                "command would leave the field are drawn as if the field allowed it.",
            )
        )
    if result.build is not None and result.build.layers:
        b = result.build
        z = np.array([row["z_m"] for row in b.layers]) * 1e3
        per_layer = {k: b.per_layer(k) for k in ("naive_s", "fixed_s", "dynamics_s", "shaped_s")}
        figs.append(
            Figure(
                name="build.png",
                png=render_png(plot_build(z, per_layer, b.totals())),
                caption=f"The whole build, {len(b.layers)} layers: time per layer and totals.",
            )
        )
    notes = [
        *NOTES,
        f"Identification: {s.identify.chirp.sweep} chirp {s.identify.chirp.f0_hz:g}-"
        f"{s.identify.chirp.f1_hz:g} Hz, {s.identify.chirp.amplitude:g} bit, "
        f"{s.identify.chirp.n_periods} periods of {s.identify.chirp.period_s:g} s, "
        f"{s.identify.chirp.n_dropped} dropped; noise {'on' if s.twin.noise else 'off'}, "
        f"seed {s.twin.seed}{', mirror mode on' if s.twin.mirror_mode else ''}.",
        "model.json and shaper.json next to this page are the fitted model and the shaper "
        "(`microfab shaper design`, `microfab slm scan-time --shaper`).",
        *(f"Failure: {f}" for f in result.failures()),
    ]
    text = page_html(
        title,
        intro=f"Seed 003 part 2 on the SLM galvo twin; layer {s.layer.source!r}.",
        notes=notes,
        figures=figs,
        tables=result.comparison(),
    )
    return write_page(out, text, figs)
