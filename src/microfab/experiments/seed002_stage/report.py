"""Report of a ``stage-identify`` job: seed 002 part 1 Figs. 6, 8, 9 redrawn, Table II."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from microfab.experiments.seed002_stage import figures as f
from microfab.experiments.seed002_stage.study import IdentifyStudy
from microfab.experiments.seed002_stage.tables import NOTES, comparison_tables
from microfab.identify.stage_data import AXES

__all__ = ["write_report"]


def _figures(study: IdentifyStudy) -> list[tuple[str, object, str]]:
    """``(file name, matplotlib figure, caption)`` of every figure the study allows."""
    s = study.settings
    out: list[tuple[str, object, str]] = [
        (
            "excitation.png",
            f.plot_excitation(study.example_runs),
            "Redraws seed 002 Fig. 6: training commands (random runs and a shape) in the "
            "workspace.",
        ),
    ]
    if study.singular_values.size:
        out.append(
            (
                "singular_values.png",
                f.plot_singular_values(study.singular_values, study.linear.model.order),
                "Singular values of the weighted projection (order check).",
            )
        )
    out.append(
        (
            "bode.png",
            _bode(study),
            "The identified 4-state model (1 kHz) against the twin's linear part (10 kHz, "
            "nonlinear parts off): set-point to position, x and y.",
        )
    )
    a_sweep = s.cases.sweep_a_max
    sig: dict[str, np.ndarray] = {}
    for model, label in (("ann", "ANN"), ("linear", "linear")):
        let = [study.letters(a, model) for a in a_sweep]
        air = [study.case("airfoil", a).errors.get(model) for a in a_sweep]
        if all(e is not None for e in let):
            sig[f"{label} letters"] = np.array([e.std for e in let])  # type: ignore[union-attr]
            sig[f"{label} airfoil"] = np.array([e.std for e in air])  # type: ignore[union-attr]
    out.append(
        (
            "fig9.png",
            f.plot_fig9(a_sweep, sig, s.linear.a_max),
            "Redraws Fig. 9: σ against a_max on the letters (pooled) and the airfoil.",
        )
    )
    if study.ann is not None and study.ann_validation is not None:
        panels = {"validation runs": study.ann_validation}
        for a in s.cases.table_a_max[:2]:
            e = study.letters(a, "ann")
            if e is not None:
                panels[f"letters, a_max {a:g} m/s²"] = e
        out.append(
            (
                "fig8_histograms.png",
                f.plot_histograms(panels),
                "Redraws Fig. 8: the network's error on its validation runs and on the letters.",
            )
        )
        hist = {}
        for name, st in (
            ("per-axis", study.ann),
            ("both axes", study.coupled),
            ("PRBS/chirp", study.classic),
        ):
            if st is not None:
                for a, info in st.model.info.get("axes", {}).items():
                    hist[f"{name} {a}"] = info.get("history", [])
        out.append(("losses.png", f.plot_losses(hist), "Training and validation loss."))
        if study.curves is not None and study.curves.time_s is not None:
            out.append(
                (
                    "prediction.png",
                    _prediction(study),
                    "A validation run: measured position and measured minus each model.",
                )
            )
    return out


def _bode(study: IdentifyStudy) -> object:
    c = study.curves
    assert c is not None
    return f.plot_bode(c.freq_hz, c.response)


def _prediction(study: IdentifyStudy) -> object:
    c = study.curves
    assert c is not None and c.time_s is not None and c.measured is not None
    return f.plot_prediction(c.time_s, c.measured, c.predictions)


def write_report(study: IdentifyStudy, out: Path, title: str) -> Path:
    """Render the figures and write ``report.html`` into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.page import Figure, page_html, write_page

    figs = [
        Figure(name=name, png=render_png(fig), caption=cap)  # type: ignore[arg-type]
        for name, fig, cap in _figures(study)
    ]
    s = study.settings
    notes = [
        *NOTES,
        f"Linear data {s.linear.total_s:g} s of random runs up to {s.linear.a_max:g} m/s², "
        f"order {s.linear.order}, decimated by {s.linear.decimate}; noise "
        f"{'on' if s.twin.noise else 'off'}, seed {s.twin.seed}.",
        "Wall time: " + ", ".join(f"{k} {v:.0f} s" for k, v in study.seconds.items()) + ".",
        "linear_model.json and ann/model next to this page are the models (`microfab identify "
        "validate MODEL RUN...`).",
    ]
    text = page_html(
        title,
        intro="Seed 002 part 1 on the XY stage twin: the black box's linear and network "
        f"models ({', '.join(AXES)}).",
        notes=notes,
        figures=figs,
        tables=comparison_tables(study),
    )
    return write_page(out, text, figs)
