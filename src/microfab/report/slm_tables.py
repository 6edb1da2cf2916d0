"""Tables of SLM galvo-scanner results (seed 003 part 2): scan times, a build, shapers.

Each function reads a finished result and formats it as a `microfab.report.tables.Table`
(printed by the CLI, written into a report); none computes physics. `scan_table` reads
the scan-time estimates of one layer without and with a shaper
(`microfab.process.slm.estimate.estimate_with_shaper`: ``microfab slm scan-time``, the
``slm-shaping`` job); `build_table` a `microfab.process.slm.build.BuildResult`
(``microfab slm build``, the job); `comparison_table` a
`microfab.machines.slm_galvo.shapers.ShaperComparison` (``microfab shaper compare``, the
job).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from microfab.machines.slm_galvo.shapers import ShaperComparison
from microfab.process.slm.build import ESTIMATES, LABELS, BuildResult
from microfab.process.slm.estimate import (
    SEED_JUMP_DELAY_SHAPED_S,
    SEED_JUMP_DELAY_UNSHAPED_S,
    SEED_TOTAL_SHAPED_S,
    SEED_TOTAL_UNSHAPED_S,
    ScanTimeComparison,
    ScanTimeEstimate,
)
from microfab.process.slm.timing import CATEGORIES
from microfab.report.tables import DASH, Table

__all__ = ["build_table", "comparison_table", "scan_table"]


def scan_table(
    runs: Mapping[str, ScanTimeComparison], *, title: str, shaped: str = "shaped", note: str = ""
) -> Table:
    """A layer's naive, fixed-delay and dynamics-aware scan times by category, s and share.

    Parameters
    ----------
    runs : mapping of str to ScanTimeComparison
        ``"unshaped"`` and, if estimated, ``"shaped"`` (`estimate_with_shaper`).
    title : str
        The table's title (names the layer).
    shaped : str
        Tag of the shaped columns (``"naive, shaped [s]"``).
    note : str
        A line under the table.

    Returns
    -------
    Table
        One row per category of `microfab.process.slm.timing.CATEGORIES` and the total;
        per estimate its time, s, and its share of the estimate's total.
    """
    cols = ["category"]
    ests = []
    for name, c in runs.items():
        tag = "" if name == "unshaped" else f", {shaped}"
        for e in (c.naive, c.fixed, c.dynamics):
            cols.append(f"{e.method}{tag} [s]")
            ests.append(e)

    def cell(e: ScanTimeEstimate, cat: str) -> str:
        sec = e.total_s if cat == "total" else e.breakdown_s[cat]
        share = 1.0 if cat == "total" else e.share(cat)
        return f"{sec:.5g} ({100 * share:.1f} %)"

    rows = [[cat, *(cell(e, cat) for e in ests)] for cat in (*CATEGORIES, "total")]
    return Table(title=title, columns=cols, rows=rows, note=note)


def build_table(result: BuildResult) -> Table:
    """Build time per category and estimate, the total and its spread over layers.

    Parameters
    ----------
    result : BuildResult
        A whole build (`microfab.process.slm.build.run_build`).

    Returns
    -------
    Table
        One row per category of `microfab.process.slm.timing.CATEGORIES`, the total and
        (when a layer finished) the per-layer mean and range, s; one column per estimate of
        `ESTIMATES`; the note gives the derived jump delays and the cuts beside the seed's
        (seed 003 part 2 §4: 750 -> 250 µs, 4686 -> 4219 s).
    """
    cats = {e: result.breakdown(e) for e in ESTIMATES}
    tot = result.totals()
    rows = [[c.replace("_", " "), *(f"{cats[e][c]:.2f}" for e in ESTIMATES)]
            for c in CATEGORIES]  # fmt: skip
    rows.append(["total", *(f"{tot[f'{e}_s']:.2f}" for e in ESTIMATES)])
    per = {e: result.per_layer(f"{e}_s") for e in ESTIMATES}
    if result.layers:
        rows.append(["per layer, mean", *(f"{per[e].mean():.3f}" for e in ESTIMATES)])
        spread = (f"{per[e].min():.3f} – {per[e].max():.3f}" for e in ESTIMATES)
        rows.append(["per layer, min – max", *spread])
    jd = result.jump_delay_s
    done = len(result.layers)
    note = (
        f"{done} of {result.settings.n_layers} layers; shaper {result.settings.shaper}; jump "
        f"delays derived for one cell: {jd.get('unshaped', math.nan) * 1e6:.0f} µs "
        f"unshaped, {jd.get('shaped', math.nan) * 1e6:.0f} µs shaped (seed: "
        f"{SEED_JUMP_DELAY_UNSHAPED_S * 1e6:.0f} -> {SEED_JUMP_DELAY_SHAPED_S * 1e6:.0f} "
        f"µs); cut {100 * tot['cut_fraction']:.1f} % dynamics-aware, "
        f"{100 * tot['cut_fraction_fixed']:.1f} % fixed delays (seed: "
        f"{100 * (1 - SEED_TOTAL_SHAPED_S / SEED_TOTAL_UNSHAPED_S):.2f} % on its bunny)"
    )
    if result.failed:
        note += f"; {len(result.failed)} layer(s) failed"
    return Table(
        title=f"Whole build, {done} lattice layers: scan time [s]",
        columns=("category", *(LABELS[e] for e in ESTIMATES)),
        rows=rows,
        note=note,
    )


def _us(x: float) -> str:
    return DASH if not math.isfinite(x) else f"{x * 1e6:.1f}"


def comparison_table(comparison: ShaperComparison) -> Table:
    """One line per shaper of a comparison on one twin, units in the headers.

    Parameters
    ----------
    comparison : ShaperComparison
        `microfab.machines.slm_galvo.shapers.compare_shapers`'s rows on one twin.

    Returns
    -------
    Table
        Per shaper: design mode, residual vibration over 0.8-1.2 f (%), added delay,
        command peak, settling and ramp lag (µs) and the field check.
    """
    rows = []
    for r in comparison.rows:
        design = (
            DASH if not math.isfinite(r.design_hz) else f"{r.design_hz:.1f}, {r.design_damping:.4f}"
        )
        rows.append(
            (
                r.name,
                design,
                DASH if not math.isfinite(r.vibration) else f"{100 * r.vibration:.2f}",
                _us(r.delay_s),
                DASH if not math.isfinite(r.command_peak) else f"{r.command_peak:.2f}",
                _us(r.settling_s),
                _us(r.lag_s),
                "emitted" if r.refused is None else f"refused: {r.refused}",
            )
        )
    s = comparison.settings
    return Table(
        title=(
            f"Shapers on the {comparison.twin} twin: mode {comparison.mode_hz:.1f} Hz, ζ "
            f"{comparison.damping:.4g}; jump {s.jump_bit:g} bit from {s.start_bit:g} bit"
        ),
        columns=(
            "shaper",
            "design f [Hz], ζ",
            "V over 0.8-1.2 f [%]",
            "added delay [µs]",
            "command peak [× jump]",
            f"settling {100 * s.band:g} % [µs]",
            "ramp lag [µs]",
            "field check",
        ),
        rows=rows,
        note=(
            f"10 µs samples, no noise; inverse: {s.inverse.upper()}; classic shapers "
            + ("at the mode fitted to the twin's chirp FRF" if s.frf_noise else "at the true mode")
        ),
    )
