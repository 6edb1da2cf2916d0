"""Report of a ``stage-reference-opt`` job: seed 002 Figs. 11-17 redrawn, Table III.

With the networks' generations (seed 002 Fig. 7) the page also shows Table III per
generation and the networks against the twin per generation
(`microfab.experiments.seed002_reference.tables.comparison_tables`), and notes where
each generation's models are; it reads the study and computes nothing.

What the optimisation reached (issue 43) is a table of every point
(`microfab.experiments.seed002_reference.tables.reached_table`: each stage's status, the
broken constraint, its residual and sample), and the notes carry the warnings the points
recorded: the networks' training range, their recorded validation σ above μ, and how many
points ended infeasible or with the networks and the linear model apart by more than μ.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from microfab.experiments.seed002_reference import figures as f
from microfab.experiments.seed002_reference.study import ReferenceStudy
from microfab.experiments.seed002_reference.tables import (
    NOTES,
    comparison_tables,
    study_warnings,
)
from microfab.machines.xy_stage.cases import case_paths

__all__ = ["write_report"]

#: The points the seed draws in detail: letter r at 1 m/s² (Figs. 11-12), the airfoil at
#: 2 m/s² (Figs. 13-15).
_DETAIL = (("r", 1.0, "11", "12"), ("airfoil", 2.0, "13", "15"))


def _outputs(out: Path | None, case: str, a: float) -> dict[str, np.ndarray] | None:
    if out is None:
        return None
    p = out / "points" / f"{case}_a{a:g}.npz"
    if not p.is_file():
        return None
    with np.load(p) as z:
        return {k[4:]: z[k] for k in z.files if k.startswith("out_")}


def _figures(study: ReferenceStudy, out: Path) -> list[tuple[str, Any, str]]:
    figs: list[tuple[str, Any, str]] = []
    paths = case_paths(study.sizes, study.settings.cases)
    for case, a, fig_xy, fig_s in _DETAIL:
        if case not in paths:
            continue
        o = _outputs(out, case, a)
        if o is None:
            continue
        xy = f.plot_point_xy(paths[case], o, f"{case} at a_max {a:g} m/s²")
        cap = (
            f"Redraws Fig. {fig_xy}: target, optimised input, twin outputs of the optimised "
            "and the eq. (15) inputs; right: the baseline's worst corner."
        )
        figs.append((f"{case}_a{a:g}_xy.png", xy, cap))
        along = f.plot_point_along_s(paths[case], o, 1 / 400.0, study.settings.tolerance_m)
        cap = f"Redraws Fig. {fig_s}: deviation along s and the projected speed."
        figs.append((f"{case}_a{a:g}_along_s.png", along, cap))
    for name, fig_no in (("letters", "16"), ("airfoil", "17")):
        rows = study.tradeoff.get(name)
        if rows:
            cap = f"Redraws Fig. {fig_no}: L2 against time and time against a_max."
            figs.append((f"tradeoff_{name}.png", f.plot_tradeoff(rows, name), cap))
    if study.generations is not None:
        gens = [{"generation": g.index, "linf_m": g.twin.get("linf_m", np.nan),
                 "sigma_um": {a: e["sigma_um"] for a, e in g.network_error.items()}}
                for g in study.generations.generations]  # fmt: skip
        cap = (
            "Per generation (seed 002 Fig. 7): the networks' σ against the twin on the "
            "shapes that generation optimised, and the twin's L∞ of those references."
        )
        figs.append(("generations.png", f.plot_generations(gens), cap))
    rows = [p for _, p in sorted(study.points.items()) if "error" not in p]
    if rows:
        figs.append(("timings.png", f.plot_timings(
            [{"case": p["case"], "a_max": p["a_max"],
              "wall_s": {"stage1": p["stage1"]["wall_s"],
                         "stage2": (p.get("stage2") or {}).get("wall_s", np.nan)}}
             for p in rows]), "Wall time of the stages per point."))  # fmt: skip
    return figs


def _generation_notes(study: ReferenceStudy) -> list[str]:
    """Where each generation's models are, and whether generation 1 saw the same data."""
    if study.generations is None:
        return []
    gens = study.generations.generations
    notes = [
        f"Generations (seed 002 §III-C.2, Fig. 7): {len(gens)}; the tables above the "
        "per-generation ones use the last generation's networks. Models: "
        + "; ".join(f"{g.index}: {g.models_dir}" for g in gens)
        + ". The linear model is not refitted (§III-C.2)."
    ]
    second = gens[1].training if len(gens) > 1 else None
    if second is not None and not second.get("start_data_matches", True):
        notes.append(
            "Generation 1's networks were not trained on the data the retrainings start "
            "from (another data digest): the retrainings add their runs to other data."
        )
    return notes


def write_report(study: ReferenceStudy, out: Path, title: str) -> Path:
    """Render the figures and write ``report.html`` into ``out``."""
    from microfab.report.canvas import render_png
    from microfab.report.page import Figure, page_html, write_page

    figs = [Figure(name=n, png=render_png(fig), caption=cap) for n, fig, cap in
            _figures(study, out)]  # fmt: skip
    s = study.settings
    notes = [
        *NOTES,
        *(f"Warning: {w}." for w in study_warnings(study)),
        f"Models: {s.models_dir}. Sizes: letter height "
        f"{study.sizes.letter_height_m * 1e3:.2f} mm, airfoil chord "
        f"{study.sizes.airfoil_chord_m * 1e3:.1f} mm.",
    ]
    notes += _generation_notes(study)
    text = page_html(
        title,
        intro="Seed 002 part 2 on the XY stage twin: the two-stage reference optimisation "
        "against the constant-progress baseline.",
        notes=notes,
        figures=figs,
        tables=comparison_tables(study),
    )
    return write_page(out, text, figs)
