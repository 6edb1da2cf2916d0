"""Self-contained HTML report of seed 000 runs: figures, Tables 1 and 2, seed comparison.

`write_report` draws the figures (`microfab.report.galvo_ilc`, `microfab.report.loops`
and `.figures`) of the main rate (the learning transient of every rate), writes them as
PNGs next to ``report.html``, and writes the HTML with tables of our numbers and, when
given, our numbers beside the seed's. All figures are rendered in memory before anything
is written, and every file is written atomically, so a failure while drawing leaves the
directory as it was (no partial or new ``report.html``).

References
----------
Seed 000 §4: Figs. 4-8, Table 1 (RMS and PP errors, mV), Table 2 (beam speed, mm/s),
§3.1 (gain and phase margins).
"""

from __future__ import annotations

import html
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from microfab.experiments.seed000_msl import figures
from microfab.experiments.seed000_msl import paper as seed000
from microfab.machines.galvo.ilc import BeamExposure, MSLRunResult
from microfab.plants.lti import DiscreteLTI
from microfab.report import galvo_ilc, loops
from microfab.report.canvas import render_png, render_svg
from microfab.report.page import Figure, page_html, write_page

__all__ = ["FIGURE_FILES", "fmt_mm_s", "fmt_mv", "write_report"]

#: PNG files written by :func:`write_report`, in report order.
FIGURE_FILES = (
    "xy.png",
    "time.png",
    "psd.png",
    "learning.png",
    "velocity.png",
    "line_width.png",
    "bode.png",
    "eq5.png",
)

_BODE_TITLE = "Open loop of each axis (seed 000 eq. 1 controller, twin plant)"
_T2_STATS = ("mean", "std", "min", "max")
_DASH = "&mdash;"


def fmt_mv(value: float) -> str:
    """Format an error in mV as shown in the report (two decimals)."""
    return f"{value:.2f}"


def fmt_mm_s(value: float) -> str:
    """Format a speed in mm/s as shown in the report (one decimal)."""
    return f"{value:.1f}"


def _fmt1(value: float) -> str:
    return f"{value:.1f}"


def _fmt_ratio(ours: float | None, seed: float | None) -> str:
    if ours is None or seed is None or seed == 0:
        return _DASH
    return f"{ours / seed:.2f}"


def _rate_str(rate: float) -> str:
    return f"{float(rate):g}"


def _seed_rate(rate: Any) -> int | None:
    """Seed table key (int features/s) for a rate given as number or string."""
    try:
        r = float(rate)
    except (TypeError, ValueError):
        return None
    return int(r) if r.is_integer() and int(r) in seed000.RATES else None


def _td(value: float | None, fmt: Callable[[float], str]) -> str:
    text = _DASH if value is None else html.escape(fmt(float(value)))
    return f'<td class="num">{text}</td>'


def _th(text: str, **attrs: int) -> str:
    extra = "".join(f' {k}="{v}"' for k, v in attrs.items())
    return f"<th{extra}>{html.escape(text)}</th>"


def _render_figures(
    runs: Mapping[float, MSLRunResult],
    main: MSLRunResult,
    exposure: BeamExposure,
    open_loops: Mapping[str, DiscreteLTI],
) -> list[tuple[str, bytes, bytes]]:
    """Draw and render every figure to PNG and SVG bytes (nothing is written here)."""
    # Looked up on the module at call time so that tests can substitute a function.
    makers: list[tuple[str, Callable[[], Any]]] = [
        ("xy.png", lambda: galvo_ilc.fig_xy(main)),
        ("time.png", lambda: galvo_ilc.fig_time(main)),
        ("psd.png", lambda: galvo_ilc.fig_psd(main)),
        ("learning.png", lambda: galvo_ilc.fig_learning(runs)),
        ("velocity.png", lambda: figures.fig_velocity(main, exposure)),
        ("line_width.png", lambda: figures.fig_line_width(main, exposure)),
        ("bode.png", lambda: loops.fig_bode(dict(open_loops), title=_BODE_TITLE)),
        ("eq5.png", lambda: galvo_ilc.fig_eq5(main)),
    ]  # fmt: skip
    out = []
    for name, make in makers:
        fig = make()
        out.append((name, render_png(fig), render_svg(fig)))
    return out


def _captions(main: MSLRunResult, runs: Mapping[float, MSLRunResult]) -> dict[str, str]:
    rate = f"{_rate_str(main.features_per_s)} features/s"
    n = main.rms_history.shape[0]
    all_rates = ", ".join(_rate_str(r) for r in sorted(runs))
    return {
        "xy.png": (
            f"Redraws seed 000 Fig. 4a: beam path on the xy plane at {rate}; desired "
            f"square, feedback only (trial 1), ILC output and ILC input u_{n} (trial {n})."
        ),
        "time.png": (
            f"Redraws seed 000 Fig. 4b: x and y encoder signals over one period at {rate}; "
            f"desired, feedback only, ILC output and the non-causal ILC input u_{n}."
        ),
        "psd.png": (
            f"Redraws seed 000 Fig. 5: power spectral density of the FB and ILC errors at "
            f"{rate}, markers at the harmonics, encoder white-noise floor 2·σ²·dt and the "
            "8 kHz learning cutoff."
        ),
        "learning.png": (
            f"Redraws seed 000 Fig. 6: learning transient, RMS error per iteration at "
            f"{all_rates} features/s (x red, y blue)."
        ),
        "velocity.png": (
            f"Redraws seed 000 Fig. 7: beam speed along the path at {rate}, feedback only "
            "(left) and ILC (right), shared colour scale in mm/s."
        ),
        "line_width.png": (
            f"Analogue of seed 000 Fig. 8: predicted cured line width along one period at "
            f"{rate} from the beam speed (Jacobs working curve; assumed spot radius and "
            "resin parameters, see microfab.process.exposure)."
        ),
        "bode.png": (
            "Open loop L = C G of each axis (seed 000 eq. 1 lead-lag, calibrated twin plant) "
            "with the gain and phase margins; seed 000 §3.1 reports the margins of the real "
            "scanners (compare the margins table)."
        ),
        "eq5.png": (
            f"Seed 000 eq. 5 at {rate}: |1 - ρ P P̂⁻¹| at every learned harmonic, the true "
            "loop of the twin against the inverse learned from trial 1; at most 1 means "
            "every learned harmonic's error shrinks from trial to trial."
        ),
    }


def _table1_ours(runs: Mapping[float, MSLRunResult]) -> str:
    rates = sorted(runs)
    axes = runs[rates[0]].axes
    head1 = (
        _th("Axis", rowspan=2)
        + _th("Controller", rowspan=2)
        + "".join(_th(f"{_rate_str(r)} features/s", colspan=2) for r in rates)
    )
    head2 = "".join(_th("RMS") + _th("PP") for _ in rates)
    rows = []
    for axis in axes:
        t1 = {r: runs[r].table1_row(axis) for r in rates}
        for ctl in ("fb", "ilc"):
            cells = "".join(
                _td(t1[r][f"{ctl}_rms"], fmt_mv) + _td(t1[r][f"{ctl}_pp"], fmt_mv) for r in rates
            )
            rows.append(f"<tr><td>{html.escape(axis)}</td><td>{ctl.upper()}</td>{cells}</tr>")
        cells = "".join(
            _td(t1[r]["fb_rms"] / t1[r]["ilc_rms"] if t1[r]["ilc_rms"] else None, fmt_mv)
            + "<td></td>"
            for r in rates
        )
        rows.append(
            f'<tr class="muted"><td>{html.escape(axis)}</td><td>FB/ILC RMS</td>{cells}</tr>'
        )
    return (
        "<table><caption>Table 1 (ours): RMS and peak-to-peak tracking errors, mV"
        "</caption>"
        f"<thead><tr>{head1}</tr><tr>{head2}</tr></thead>"
        f"<tbody>{''.join(rows)}</tbody></table>"
    )


def _table2_ours(runs: Mapping[float, MSLRunResult], table2: Mapping[str, Any]) -> str:
    head = (
        _th("Rate (features/s)")
        + _th("Controller")
        + "".join(_th(s.capitalize()) for s in _T2_STATS)
    )
    by_rate = {float(k): v for k, v in table2.items()}
    rows = []
    for r in sorted(runs):
        stats = by_rate[float(r)]
        for ctl in ("fb", "ilc"):
            cells = "".join(_td(stats[f"{ctl}_{s}"], fmt_mm_s) for s in _T2_STATS)
            rows.append(f"<tr><td>{_rate_str(r)}</td><td>{ctl.upper()}</td>{cells}</tr>")
    return (
        "<table><caption>Table 2 (ours): beam speed mean, standard deviation, minimum and "
        "maximum, mm/s</caption>"
        f"<thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"
    )


def _get(d: Any, *keys: Any) -> float | None:
    for k in keys:
        if not isinstance(d, Mapping) or k not in d:
            return None
        d = d[k]
    try:
        return float(d)
    except (TypeError, ValueError):
        return None


def _sorted_rates(keys: Any) -> list[Any]:
    def key(k: Any) -> tuple[int, float, str]:
        try:
            return (0, float(k), "")
        except (TypeError, ValueError):
            return (1, 0.0, str(k))

    return sorted(keys, key=key)


def _compare_head(first: Sequence[str], quantities: Sequence[str]) -> str:
    head1 = "".join(_th(h, rowspan=2) for h in first) + "".join(
        _th(q, colspan=3) for q in quantities
    )
    head2 = "".join(_th("ours") + _th("seed") + _th("ours/seed") for _ in quantities)
    return f"<thead><tr>{head1}</tr><tr>{head2}</tr></thead>"


def _compare_cells(ours: float | None, seed: float | None, fmt: Callable[[float], str]) -> str:
    return _td(ours, fmt) + _td(seed, fmt) + f'<td class="num">{_fmt_ratio(ours, seed)}</td>'


def _table1_compare(t1: Mapping[str, Any]) -> str:
    rows = []
    for axis, by_rate in t1.items():
        if not isinstance(by_rate, Mapping):
            continue
        for rate in _sorted_rates(by_rate):
            sr = _seed_rate(rate)
            for ctl in ("fb", "ilc"):
                cells = ""
                for q in ("rms", "pp"):
                    key = f"{ctl}_{q}"
                    seed = _get(seed000.TABLE1_MV, axis, sr, key) if sr is not None else None
                    cells += _compare_cells(_get(by_rate, rate, key), seed, fmt_mv)
                rows.append(
                    f"<tr><td>{html.escape(str(axis))}</td>"
                    f"<td>{html.escape(str(rate))}</td><td>{ctl.upper()}</td>{cells}</tr>"
                )
    return (
        "<table><caption>Table 1 beside seed 000 Table 1: tracking errors, mV</caption>"
        + _compare_head(("Axis", "Rate (features/s)", "Controller"), ("RMS", "PP"))
        + f"<tbody>{''.join(rows)}</tbody></table>"
    )


def _table2_compare(t2: Mapping[str, Any]) -> str:
    rows = []
    for rate in _sorted_rates(t2):
        sr = _seed_rate(rate)
        for ctl in ("fb", "ilc"):
            cells = ""
            for s in _T2_STATS:
                key = f"{ctl}_{s}"
                seed = _get(seed000.TABLE2_MM_S, sr, key) if sr is not None else None
                cells += _compare_cells(_get(t2, rate, key), seed, fmt_mm_s)
            rows.append(f"<tr><td>{html.escape(str(rate))}</td><td>{ctl.upper()}</td>{cells}</tr>")
    return (
        "<table><caption>Table 2 beside seed 000 Table 2: beam speed, mm/s</caption>"
        + _compare_head(("Rate (features/s)", "Controller"), [s.capitalize() for s in _T2_STATS])
        + f"<tbody>{''.join(rows)}</tbody></table>"
    )


def _margins_compare(margins: Mapping[str, Any]) -> str:
    rows = []
    for axis in margins:
        cells = _compare_cells(
            _get(margins, axis, "gm_db"), _get(seed000.MARGINS, axis, "gm_db"), _fmt1
        ) + _compare_cells(
            _get(margins, axis, "pm_deg"), _get(seed000.MARGINS, axis, "pm_deg"), _fmt1
        )
        rows.append(f"<tr><td>{html.escape(str(axis))}</td>{cells}</tr>")
    return (
        "<table><caption>Feedback-loop margins beside seed 000 §3.1</caption>"
        + _compare_head(("Axis",), ("Gain margin (dB)", "Phase margin (deg)"))
        + f"<tbody>{''.join(rows)}</tbody></table>"
        + '<p class="muted">Why the gain margins differ: the seed measured its margins on '
        "the real scanners, whose mirror resonances its model does not give; the twin "
        "carries the seed's resonance frequencies with an assumed damping of 0.05 "
        "(microfab/data/galvo_twin.toml), so its gain margin is set by those assumed peaks. "
        "The twin's phase margins come out a few degrees below the seed's (see the Bode "
        "plot).</p>"
    )


def _comparison(tables: Mapping[str, Any]) -> str:
    parts = []
    if isinstance(tables.get("table1"), Mapping):
        parts.append(_table1_compare(tables["table1"]))
    if isinstance(tables.get("table2"), Mapping):
        parts.append(_table2_compare(tables["table2"]))
    if isinstance(tables.get("margins"), Mapping):
        parts.append(_margins_compare(tables["margins"]))
    if not parts:
        return ""
    return (
        "<h2>Comparison with seed 000</h2>"
        '<p class="muted">Seed values from microfab.experiments.seed000_msl.paper; '
        "&ldquo;ours/seed&rdquo; is the ratio of our value to the published one "
        f"({_DASH} where the seed has no value).</p>" + "".join(parts)
    )


def write_report(
    out_dir: str | os.PathLike[str],
    runs: Mapping[float, MSLRunResult],
    *,
    main_rate: float,
    tables: dict[str, Any],
    exposure: BeamExposure,
    open_loops: Mapping[str, DiscreteLTI],
    title: str = "microfab report",
    notes: Sequence[str] = (),
) -> Path:
    """Write the figures and an HTML report of seed 000 runs.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output directory, created if missing. Receives ``xy.png``, ``time.png``,
        ``psd.png``, ``learning.png``, ``velocity.png``, ``line_width.png`` and
        ``report.html`` (which embeds the PNGs by relative path).
    runs : mapping of float to MSLRunResult
        Runs by rate, features/s. The learning figure and the tables use all of them.
    main_rate : float
        Rate whose run is drawn in the other figures; must be a key of ``runs``.
    tables : dict
        Our numbers as returned by
        `microfab.experiments.seed000_msl.job.tables_from_runs`: ``{"table1": {axis:
        {rate: {"fb_rms", "fb_pp", "ilc_rms", "ilc_pp"}}}, "table2": {rate: {...}},
        "margins": {axis: {"gm_db", "pm_deg"}}}`` with string rate keys, shown beside the
        seed's values (:mod:`microfab.experiments.seed000_msl.paper`) with the ratio
        ours/seed; Table 2 (ours) is read from it.
    exposure : BeamExposure
        The main run's beam speed and cured lines
        (`microfab.machines.galvo.ilc.beam_exposure`).
    open_loops : mapping of str to DiscreteLTI
        Each axis' open loop, for the Bode plot (`microfab.machines.galvo.open_loop`).
    title : str, optional
        Page title and heading.
    notes : sequence of str, optional
        Shown as a bulleted list.

    Returns
    -------
    pathlib.Path
        Path of ``report.html``.

    Raises
    ------
    ValueError
        If ``runs`` is empty or ``main_rate`` is not one of its keys.
    Exception
        Whatever drawing a figure raised; nothing has been written then (an existing
        report in ``out_dir`` is left untouched).
    """
    if not runs:
        raise ValueError("write_report needs at least one run")
    main = next((r for k, r in runs.items() if float(k) == float(main_rate)), None)
    if main is None:
        raise ValueError(f"main_rate {main_rate} is not among the runs' rates {sorted(runs)}")
    rendered = _render_figures(runs, main, exposure, open_loops)  # draw first
    captions = _captions(main, runs)
    figs = [
        Figure(name=name, png=png, svg=svg, caption=captions[name]) for name, png, svg in rendered
    ]
    rates = ", ".join(_rate_str(r) for r in sorted(runs))
    n_trials = ", ".join(f"{_rate_str(r)}: {runs[r].rms_history.shape[0]}" for r in sorted(runs))
    intro = (
        f"Seed 000 (galvo micro-stereolithography with frequency-domain ILC). Runs at "
        f"{rates} features/s; figures at {_rate_str(main.features_per_s)} features/s except the "
        f"learning transient. Trials per rate: {n_trials}."
    )
    sections = ["<h2>Tables</h2>", _table1_ours(runs), _table2_ours(runs, tables["table2"])]
    sections.append(_comparison(tables))
    text = page_html(title, intro=intro, notes=notes, figures=figs, sections=sections)
    return write_page(out_dir, text, figs)
