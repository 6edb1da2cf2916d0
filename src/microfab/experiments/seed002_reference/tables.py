"""Tables and JSON of the seed 002 part 2 study: Table III ours beside the seed's, and more.

With the networks' generations (seed 002 §III-C.2, Fig. 7; `ReferenceStudy.generations`)
Table III is shown once per generation (`table_iii` with each generation's study, the last
generation's first) and `generations_table` gives, per generation, the networks' error
against the twin on the references that generation optimised and the twin's contour
error of those references.
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from microfab.core.provenance import Shows, quantity
from microfab.experiments.seed002_reference import paper
from microfab.experiments.seed002_reference.study import ReferenceStudy
from microfab.machines.xy_stage.cases import table_iii_quantity
from microfab.report.provenance import OURS, labelled
from microfab.report.tables import DASH, Table, versus

__all__ = [
    "NOTES",
    "comparison_tables",
    "generations_table",
    "point_reached",
    "points_table",
    "reached_table",
    "stages_table",
    "study_summary",
    "study_warnings",
    "table_iii",
    "table_iii_agreement",
    "times_table",
    "tradeoff_reduction",
    "tradeoff_table",
]

NOTES = (
    "Twin: our stand-in for the ETEL DXL-LM325 (microfab/data/xy_stage_twin.toml), the "
    "models those of a stage-identify job on it; 'experimental' is the twin, 'simulated' "
    "the networks, as in the seed.",
    "Sizes: the letter height and the airfoil chord are set so that stage 1 gives 'r' "
    "0.807 s and the airfoil 1.322 s at 1 m/s² (Table III); every other time is a check. "
    "DejaVu Sans stands in for the ETH logo's letters; the airfoil has no spar notch.",
    "a_max bounds the output (eqs. 12j, 14f), as the equations read; §V-B says input.",
    "Deviations (eqs. 16-18) at the 400 Hz instants t_1…t_M of eq. (13), by exact "
    "foot-point projection; the 500 ms after T (input held) are reported apart.",
    "Stage 1's input term (12a) is weighted 1e-3 of the seed's SI weight: at the seed's "
    "weight it is comparable to T and keeps the letters at 3 m/s² near their 1 m/s² times.",
)

_NORMS = ("l1", "l2", "linf")

#: Band of `table_iii_agreement`, percentage points: issue 46 counts Table III's cells whose
#: improvement lies within 15 points of the seed's.
AGREEMENT_BAND_POINTS = 15.0


def _ok(p: dict[str, Any] | None) -> bool:
    return p is not None and "error" not in p


def table_iii(study: ReferenceStudy, output: str = "twin", prefix: str = "") -> Table:
    """Table III: time and improvement in L1, L2, L∞ per case and a_max, ours / seed.

    ``prefix`` starts the title (the generation, when there are several).
    """
    rows = []
    shows = []
    for case in study.settings.cases:
        for a in study.settings.a_max:
            p = study.points.get((case, a))
            seed = paper.TABLE_III.get(case, {}).get(a)
            shows.append(
                OURS
                if seed is None or not _ok(p)
                else Shows(tuple(table_iii_quantity(case, a, k) for k in ("T", *_NORMS)))
            )
            if not _ok(p):
                rows.append([case, f"{a:g}", "failed", DASH, DASH, DASH])
                continue
            imp = p["improvement"][output]
            rows.append([
                case, f"{a:g}",
                versus(p["duration_s"], None if seed is None else seed.time_s, "{:.3f}".format),
                *(versus(imp[k], None if seed is None else getattr(seed, k), "{:.1f}".format)
                  for k in _NORMS),
            ])  # fmt: skip
    label = "twin (experimental)" if output == "twin" else "networks (simulated)"
    table = Table(
        title=f"{prefix}Table III: improvement over the eq. (15) baseline at the same time, "
        f"{label} [%], ours / seed",
        columns=("shape", "a_max [m/s²]", "time [s]", "L1", "L2", "L∞"),
        rows=rows,
        note="improvement = 100 (baseline - optimised) / baseline; seed: experimental"
        + _agreement_note(table_iii_agreement(study, output)),
    )
    return labelled(table, shows)


def _agreement_note(agree: dict[str, float | None]) -> str:
    if not agree["cells"]:
        return ""
    return (
        f"; {agree['within']} of {agree['cells']} cells within ±{agree['band_points']:g} "
        f"points of the seed's, mean |difference| {agree['mean_abs_diff_points'] or 0.0:.1f} "
        "points"
    )


def table_iii_agreement(study: ReferenceStudy, output: str = "twin") -> dict[str, float | None]:
    """How close Table III's improvements come to the seed's, over the cells both have.

    Parameters
    ----------
    study : ReferenceStudy
        The study (its points at Table III's cases and a_max).
    output : str
        ``"twin"`` (the seed's "experimental") or ``"ann"`` (its "simulated").

    Returns
    -------
    dict
        ``cells``: improvement cells (L1, L2, L∞ of each point that ran and that Table III
        lists); ``within``: those within `AGREEMENT_BAND_POINTS` of the seed's;
        ``mean_abs_diff_points``: their mean |ours - seed|, percentage points (None
        without cells: the summary is strict JSON); ``band_points``: the band.
    """
    diffs = []
    for (case, a), p in sorted(study.points.items()):
        seed = paper.TABLE_III.get(case, {}).get(a)
        if seed is None or not _ok(p) or a not in study.settings.a_max:
            continue
        imp = p["improvement"][output]
        diffs += [abs(float(imp[k]) - float(getattr(seed, k))) for k in _NORMS]
    d = np.asarray(diffs, dtype=float)
    return {
        "cells": int(d.size),
        "within": int(np.sum(d <= AGREEMENT_BAND_POINTS)),
        "mean_abs_diff_points": float(d.mean()) if d.size else None,
        "band_points": AGREEMENT_BAND_POINTS,
    }


def times_table(study: ReferenceStudy) -> Table:
    """Optimised times per case and a_max against Table III and §V-A; T(3)/T(1)."""
    a_all = sorted({a for (_, a) in study.points})
    rows = []
    shows = []
    for case in study.settings.cases:
        cells = [case]
        t = {}
        compared: list[str] = []
        for a in a_all:
            p = study.points.get((case, a))
            seed = paper.TABLE_III.get(case, {}).get(a)
            seed_t = seed.time_s if seed is not None else None
            if case == "airfoil" and a in paper.AIRFOIL_TIMES_S:
                seed_t = paper.AIRFOIL_TIMES_S[a]
            t[a] = p["duration_s"] if _ok(p) else None
            if seed_t is not None and t[a] is not None:
                compared.append(table_iii_quantity(case, a, "T"))
            cells.append(versus(t[a], seed_t, "{:.3f}".format) if (case, a) in study.points
                         else DASH)  # fmt: skip
        r = t.get(3.0), t.get(1.0)
        cells.append(f"{r[0] / r[1]:.3f}" if r[0] and r[1] else DASH)
        rows.append(cells)
        shows.append(Shows(tuple(compared)))
    table = Table(
        title="Optimised time T [s], ours / seed (Table III, §V-A)",
        columns=("shape", *(f"a_max {a:g}" for a in a_all), "T(3)/T(1) (seed 0.59)"),
        rows=rows,
    )
    return labelled(table, shows)


def stages_table(study: ReferenceStudy) -> Table:
    """Per point: stage-1 N, iterations and time; stage-2 iterations, cost and time."""
    rows = []
    for (case, a), p in sorted(study.points.items()):
        if not _ok(p):
            rows.append([case, f"{a:g}", p.get("error", "failed")[:60], DASH, DASH, DASH, DASH])
            continue
        s1, s2 = p["stage1"], p.get("stage2") or {}
        cost = DASH
        if s2.get("cost_start") is not None:
            cost = f"{s2['cost_start']:.3g} → {s2['cost_end']:.3g}"
        rows.append([
            case, f"{a:g}", f"{s1['n']} / {s1['iterations']} / {s1['wall_s']:.1f}",
            f"{s2.get('iterations', DASH)} / {s2.get('wall_s', float('nan')):.1f}", cost,
            str(p["limited"].get("baseline", DASH)), f"{p['m']}",
        ])  # fmt: skip
    return labelled(
        Table(
            title="Stages: stage 1 N / iterations / s; stage 2 iterations / s; predicted cost; "
            "baseline samples limited by the set-point guard; M",
            columns=("shape", "a_max", "stage 1", "stage 2", "cost [µm² sum]", "limited", "M"),
            rows=rows,
            note="seed §IV-C: stage 1 about 1 min (N ≈ 10³), stage 2 1-4 h (M 200-1000)",
        ),
        OURS,
    )


def point_reached(p: dict[str, Any]) -> dict[str, Any]:
    """What one point's optimisation reached, read from its summary (nothing computed).

    Keys: ``case``, ``a_max``, ``stage1`` ("converged", "failed" or None when not
    recorded), ``stage2`` (`microfab.optimize.stage2.Stage2Result.status`, "failed", or
    None), ``stop`` (why stage 2's iterations ended, `Stage2Result.stop`; None when not
    recorded), and for a broken constraint (stage 2's worst, or stage 1's when it failed)
    ``constraint``, ``equation``, ``excess``, ``unit``, ``sample``, ``time_s``,
    ``rows_over``, ``rows``; ``rms_m`` and ``rms_over_tolerance`` of the prediction check,
    ``warning`` (its text); ``error``.
    """
    s1, s2 = p.get("stage1") or {}, p.get("stage2") or {}
    out: dict[str, Any] = {"case": p.get("case"), "a_max": p.get("a_max"), "error": p.get("error")}
    if "converged" in s1:
        out["stage1"] = "converged" if s1["converged"] else "failed"
    else:
        out["stage1"] = "failed" if "error" in p else None
    out["stage2"] = s2.get("status") or ("failed" if "error" in p else None)
    out["stop"] = s2.get("stop") or None
    worst = (s2.get("feasibility") or {}).get("worst")
    if worst is None and out["stage1"] == "failed":
        worst = (s1.get("feasibility") or {}).get("worst")
    for k in ("constraint", "equation", "excess", "unit", "sample", "time_s", "rows_over",
              "rows"):  # fmt: skip
        out[k] = None if worst is None else worst.get(k)
    pred = p.get("prediction") or {}
    out["rms_m"] = pred.get("rms_m")
    out["rms_over_tolerance"] = pred.get("rms_over_tolerance")
    out["warning"] = pred.get("warning")
    return out


def reached_table(study: ReferenceStudy) -> Table:
    """Per point: what each stage reached, measured on its answer (issue 43).

    Stage 1's and stage 2's status, the broken constraint of the largest relative excess
    (seed 002 eq.), by how much, where (the 400 Hz sample ``i`` of ``φ_i`` and ``t_i``; a
    knot for stage 1) and the share of rows beyond; and the RMS difference between the
    networks' and the linear model's outputs on stage 1's input, marked when above μ.
    """
    rows = []
    for _, p in sorted(study.points.items()):
        r = point_reached(p)
        if r["constraint"] is None:
            broken = where = rows_cell = DASH
        else:
            broken = f"{r['constraint']} ({r['equation']}): +{r['excess']:.3g} {r['unit']}"
            where = f"{r['sample']} (t = {r['time_s']:.3f} s)"
            rows_cell = f"{r['rows_over']} / {r['rows']}"
        rms = r["rms_m"]
        rms_cell = DASH if not rms else " / ".join(f"{rms[a] * 1e6:.1f}" for a in ("x", "y"))
        if r["rms_over_tolerance"]:
            rms_cell += " > μ"
        status = (r["stage1"] or DASH, r["stage2"] or "not recorded")
        rows.append([str(r["case"]), f"{r['a_max']:g}", *status, broken, where, rows_cell,
                     rms_cell])  # fmt: skip
    mu = study.settings.tolerance_m * 1e6
    return labelled(
        Table(
            title="What the optimisation reached, measured on its answer: stage 2's hard "
            "constraints (eqs. 14c-14f) on the networks' prediction",
            columns=("shape", "a_max", "stage 1", "stage 2", "worst broken constraint",
                     "sample (time)", "rows beyond", "networks - linear RMS x / y [µm]"),
            rows=rows,
            note=f"converged: every hard constraint holds within 1e-3 of its bound (μ = "
            f"{mu:g} µm); infeasible: the least violating iterate is returned; sample i of "
            "φ_i at 400 Hz (stage 1: knot k); RMS on stage 1's input",
        ),
        OURS,
    )  # fmt: skip


def study_warnings(study: ReferenceStudy) -> list[str]:
    """The points' recorded warnings, read from their summaries.

    Those shared by points once; the rest counted (stage 2 infeasible; the networks and
    the linear model apart by more than μ).
    """
    pts = [p for _, p in sorted(study.points.items())]
    shared = {p.get("training_warning") for p in pts}
    shared |= {(p.get("prediction") or {}).get("sigma_warning") for p in pts}
    if not any("format" in p for p in pts):  # points saved before issue 43
        shared |= {p.get("warning") for p in pts}
    out = sorted(w for w in shared if w)
    reached = [point_reached(p) for p in pts]
    bad = [f"{r['case']} at {r['a_max']:g} m/s²" for r in reached if r["stage2"] == "infeasible"]
    if bad:
        out.append(
            f"stage 2 ended infeasible on {len(bad)} of {len(pts)} points ({', '.join(bad)}): "
            "a hard constraint of eqs. 14c-14f is broken on the networks' prediction, and the "
            "least violating iterate was played (table 'What the optimisation reached')"
        )
    apart = [f"{r['case']} at {r['a_max']:g} m/s²" for r in reached if r["rms_over_tolerance"]]
    if apart:
        out.append(
            f"on {len(apart)} of {len(pts)} points the networks and the linear model differ by "
            f"more than μ RMS on stage 1's input ({', '.join(apart)}): the prediction stage 2 "
            "optimises is not good to the tolerance there"
        )
    return out


def points_table(study: ReferenceStudy) -> Table:
    """Every point's L2 and L∞ for every input and output, µm."""
    rows = []
    keys = ("optimised_twin", "baseline_twin", "stretched_twin", "optimised_ann",
            "baseline_ann")  # fmt: skip
    for (case, a), p in sorted(study.points.items()):
        if not _ok(p):
            continue
        sc = p["scores"]
        rows.append([case, f"{a:g}", *(
            f"{sc[k]['l2'] * 1e6:.1f} / {sc[k]['linf'] * 1e6:.1f}" if k in sc else DASH
            for k in keys), f"{sc['optimised_twin']['tail_linf'] * 1e6:.1f}"])  # fmt: skip
    return labelled(
        Table(
            title="Deviation L2 / L∞ [µm] per input and output",
            columns=("shape", "a_max", *keys, "tail L∞ (opt., twin)"),
            rows=rows,
            note="stretched: the time-optimal command under Table I stretched to the same T",
        ),
        OURS,
    )


def _time_at(curve: list[tuple[float, float]], l2: float) -> float | None:
    """Time at which a (time, L2) curve reaches ``l2`` (log-linear interpolation)."""
    pts = sorted(curve)
    for (t0, e0), (t1, e1) in itertools.pairwise(pts):
        if (e0 - l2) * (e1 - l2) <= 0 and e0 != e1:
            w = (math.log(l2) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return t0 + w * (t1 - t0)
    return None


def tradeoff_reduction(study: ReferenceStudy, name: str, l2: float) -> dict[str, float | None]:
    """Times of the optimised and the baseline curves at ``l2`` (twin) and the reduction."""
    rows = study.tradeoff.get(name, [])
    opt = [(r["time_s"], r["optimised_twin_l2"]) for r in rows]
    base = [(r["time_s"], r["baseline_twin_l2"]) for r in rows]
    base += [(r["time_s"], r["baseline_twin_l2"]) for r in study.baseline_curve.get(name, [])]
    t_opt, t_base = _time_at(opt, l2), _time_at(base, l2)
    red = None if t_opt is None or t_base is None else 100.0 * (1 - t_opt / t_base)
    return {"l2_m": l2, "optimised_s": t_opt, "baseline_s": t_base, "reduction_pct": red}


def tradeoff_table(study: ReferenceStudy) -> Table:
    """§V-B: the time each input needs for the seed's L2, and the optimised share."""
    rows = []
    shows = []
    for name, seed in paper.TRADEOFF.items():
        if name not in study.tradeoff:
            continue
        shows.append(
            Shows(
                tuple(
                    quantity("002", "§V-B", name, k)
                    for k in ("optimised time", "baseline time", "reduction")
                )
            )
        )
        r = tradeoff_reduction(study, name, seed.l2_m)
        beats = all(x["optimised_twin_l2"] < x["baseline_twin_l2"] for x in study.tradeoff[name])
        rows.append([
            name, f"{seed.l2_m * 1e6:g}",
            versus(r["optimised_s"], None if math.isnan(seed.optimised_s) else seed.optimised_s,
                   "{:.2f}".format),
            versus(r["baseline_s"], None if math.isnan(seed.baseline_s) else seed.baseline_s,
                   "{:.2f}".format),
            versus(r["reduction_pct"], seed.reduction_pct, "{:.0f}".format),
            "yes" if beats else "no",
        ])  # fmt: skip
    return labelled(Table(
        title="Trade-off (§V-B): time at the same L2 on the twin [s], ours / seed",
        columns=("case", "L2 [µm]", "optimised", "baseline", "reduction [%]",
                 "optimised better at every a_max"),
        rows=rows,
    ), shows)  # fmt: skip


def _axes_cell(err: dict[str, dict[str, float]], key: str) -> str:
    """``x / y`` of one statistic (µm) of a per-axis error, or a dash."""
    if not err:
        return DASH
    return " / ".join(f"{err[a][key]:.1f}" for a in ("x", "y") if a in err)


def generations_table(study: ReferenceStudy) -> Table:
    """Per generation: networks against the twin on its optimised references, and more.

    Columns: σ and μ of ``predicted - measured`` per axis (µm, pooled over the
    generation's optimised runs at 10 kHz: what seed 002 Table II columns 2-3 measure on
    the letters), the twin's pooled L2 and largest L∞ of those references (µm), the points
    that optimised, the retraining's validation σ (µm) and its epochs / best epoch.
    """
    assert study.generations is not None
    rows = []
    for g in study.generations.generations:
        ok = [p for p in g.points if "error" not in p]
        tr = g.training
        rows.append([
            str(g.index), _axes_cell(g.network_error, "sigma_um"),
            _axes_cell(g.network_error, "mu_um"),
            f"{g.twin['l2_m'] * 1e6:.1f}" if g.twin else DASH,
            f"{g.twin['linf_m'] * 1e6:.1f}" if g.twin else DASH,
            f"{len(ok)} / {len(g.points)}",
            DASH if tr is None else _axes_cell(tr["validation"], "sigma_um"),
            DASH if tr is None else " / ".join(
                f"{tr['epochs'][a]}, {tr['best_epoch'][a]}" for a in sorted(tr["epochs"])),
        ])  # fmt: skip
    gs = study.generations.settings
    shapes = ", ".join(gs.shapes)
    a_max = ", ".join(f"{a:g}" for a in gs.a_max)
    return labelled(
        Table(
            title="Networks against the twin per generation (seed 002 §III-C.2, Fig. 7): "
            "the regular shapes optimised with each generation's models [µm]",
            columns=("generation", "σ x / y", "μ x / y", "twin L2", "twin L∞", "points",
                     "retraining: validation σ x / y", "epochs, best (x / y)"),
            rows=rows,
            note=f"shapes {shapes} of {gs.size_m * 1e3:g} mm at a_max {a_max} m/s²; "
            "networks - twin on the optimised inputs (hold included). Seed 002 Table II, "
            "third generation, letters after optimisation: σ 8.2 / 13.4 µm at 1 m/s², "
            "11.1 / 18.7 µm at 3 m/s² (other drawings than these shapes); best epoch -1: "
            "no epoch beat the previous generation's weights",
        ),
        OURS,
    )  # fmt: skip


def study_summary(study: ReferenceStudy) -> dict[str, Any]:
    """JSON-ready: sizes, every point, the trade-off and Table III's means."""
    means = _means(study)
    gens = None
    if study.generations is not None:
        gens = [{"generation": g.index, "models_dir": g.models_dir, "points": g.points,
                 "network_error_um": g.network_error, "twin_m": g.twin, "split": g.split,
                 "training": g.training, "table_iii_means": _means(sub)}
                for g, (_, sub) in zip(study.generations.generations, study.by_generation(),
                                       strict=True)]  # fmt: skip
    return {
        "generations": gens,
        "sizes": {"letter_height_m": study.sizes.letter_height_m,
                  "airfoil_chord_m": study.sizes.airfoil_chord_m},
        "sizing_steps": study.sizing_steps,
        "points": [p for _, p in sorted(study.points.items())],
        "reached": [point_reached(p) for _, p in sorted(study.points.items())],
        "warnings": study_warnings(study),
        "table_iii_means": means,
        "table_iii_agreement": {o: table_iii_agreement(study, o) for o in ("twin", "ann")},
        "table_iii_means_seed": {k: float(np.mean([getattr(r, k) for rows in
                                                   paper.TABLE_III.values()
                                                   for r in rows.values()]))
                                 for k in _NORMS},
        "tradeoff": study.tradeoff,
        "baseline_curve": study.baseline_curve,
        "tradeoff_reduction": {n: tradeoff_reduction(study, n, s.l2_m)
                               for n, s in paper.TRADEOFF.items() if n in study.tradeoff},
    }  # fmt: skip


def _means(study: ReferenceStudy) -> dict[str, dict[str, float]]:
    """Table III's mean improvement per output and norm, %."""
    means: dict[str, dict[str, float]] = {}
    for out in ("twin", "ann"):
        vals = {k: [p["improvement"][out][k] for (c, a), p in study.points.items()
                    if _ok(p) and a in study.settings.a_max] for k in _NORMS}  # fmt: skip
        means[out] = {k: float(np.mean(v)) if v else float("nan") for k, v in vals.items()}
    return means


def comparison_tables(study: ReferenceStudy) -> tuple[Table, ...]:
    """Every comparison table of a study, ours beside the seed's (terminal and report).

    With generations: Table III of the last generation first, then of each earlier one,
    then `generations_table`.
    """
    steps = study.by_generation()
    n = len(steps)
    last = f"Generation {n} of {n}: " if n > 1 else ""
    out = [table_iii(study, prefix=last), table_iii(study, "ann", prefix=last)]
    out += [table_iii(sub, prefix=f"Generation {g} of {n}: ") for g, sub in steps[:-1]]
    if study.generations is not None:
        out.append(generations_table(study))
    out.append(times_table(study))
    if study.tradeoff:
        out.append(tradeoff_table(study))
    out += [reached_table(study), stages_table(study), points_table(study)]
    return tuple(out)
