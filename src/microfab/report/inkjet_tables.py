"""Tables of a droplet sweep (seed 003 part 1): first breakups beside the seed's, by model.

`breakup_tables` formats the rows of `microfab.machines.printhead.droplet_sweep` (or
`model_sweep`, one row per point and jet model): the 50 V concentration series with the
seed's two quoted breakups beside ours, whether the breakup time rises with concentration
(`breakup_trend`, seed Fig. 4's claim), and the voltage series; with more than one jet
model, first a table that puts the models side by side. Only formats: the breakups are
the machine's.

References
----------
Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``): "Typical droplet formation
process" and Fig. 2 (the two quoted breakups, `microfab.machines.printhead.calibration`),
Fig. 4 (breakup time against concentration at 50 V), Table 1 (the voltages).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

from microfab.core.provenance import Shows, quantity
from microfab.machines.printhead.calibration import CALIBRATIONS, SEED_BREAKUP, breakup_quantity
from microfab.machines.printhead.machine import FIG4_VOLTAGE_V
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL
from microfab.report.provenance import OURS, labelled
from microfab.report.tables import DASH, Table, versus

__all__ = ["LEGACY_ROW_MODEL", "breakup_tables", "breakup_trend", "row_model"]


def _us(seconds: float | None) -> float | None:
    return None if seconds is None else seconds * 1e6


#: The jet model of sweep rows saved before rows named theirs (no ``jet_model`` key): those
#: runs were all Lagrangian. This describes old data, so it stays "lagrangian" whatever
#: `DEFAULT_JET_MODEL` (the model new runs use unless asked) is.
LEGACY_ROW_MODEL = "lagrangian"


def row_model(row: dict[str, Any]) -> str:
    """The jet model of a sweep row (``jet_model``; rows without one: `LEGACY_ROW_MODEL`)."""
    return str(row.get("jet_model", LEGACY_ROW_MODEL))


def breakup_trend(at50: Sequence[dict[str, Any]]) -> str:
    """Whether the breakup time rises with concentration over ``at50``'s rows, in words.

    ``"yes"``, or ``"no: ..."`` naming where it falls or where no breakup came, or why it
    cannot tell (fewer than two concentrations).
    """
    rows = sorted(at50, key=lambda r: r["concentration_pct"])
    if len(rows) < 2:
        return "needs two concentrations at 50 V"
    missing = [r["concentration_pct"] for r in rows if r["breakup_time_s"] is None]
    if missing:
        return "no: no breakup at " + ", ".join(f"{c:g} %" for c in missing)
    falls = [
        f"{a['concentration_pct']:g} % → {b['concentration_pct']:g} %"
        for a, b in itertools.pairwise(rows)
        if b["breakup_time_s"] <= a["breakup_time_s"]
    ]
    return "yes" if not falls else "no: falls from " + ", ".join(falls)


def _seed_shows(c: float, n_models: int = 1) -> Shows:
    """The seed numbers a 50 V row at ``c`` is compared with: time per model, and mode."""
    if c not in SEED_BREAKUP:
        return OURS
    return Shows((breakup_quantity(c, "time"),) * n_models + (breakup_quantity(c, "mode"),))


def _others(model: str) -> tuple[str, ...]:
    """The calibrations of the other jet models (not applied to ``model``'s numbers)."""
    return tuple(c.command for c in CALIBRATIONS if not c.command.endswith(f" {model}"))


def breakup_tables(rows: Sequence[dict[str, Any]]) -> tuple[Table, ...]:
    """Our breakups beside the seed's: the 50 V series, its trend, the voltage series.

    With rows of more than one jet model, the tables come once per model (titled with
    it) after a table that puts the models' 50 V breakups side by side.

    Parameters
    ----------
    rows : sequence of dict
        Sweep rows (`microfab.machines.printhead.droplet_sweep`): ``concentration_pct``,
        ``voltage_v``, ``breakup_time_s``, ``breakup_mode``, ``breakup_z_m``,
        ``head_speed_m_s``, ``satellites``, ``drop_diameter_m`` and ``jet_model``
        (rows without one are `LEGACY_ROW_MODEL`'s).

    Returns
    -------
    tuple of Table
        Two or three tables per model (the voltage series only when the rows hold one).
    """
    models = list(dict.fromkeys(row_model(r) for r in rows))
    if len(models) <= 1:
        return _tables_of_one_model(rows, "")
    out: list[Table] = [_model_comparison(rows, models)]
    for m in models:
        out += _tables_of_one_model([r for r in rows if row_model(r) == m], f" ({m} model)")
    return tuple(out)


def _model_comparison(rows: Sequence[dict[str, Any]], models: Sequence[str]) -> Table:
    at50 = [r for r in rows if r["voltage_v"] == FIG4_VOLTAGE_V]
    cs = sorted({r["concentration_pct"] for r in at50})
    table_rows = []
    for c in cs:
        cells = []
        for m in models:
            r = next((r for r in at50 if r["concentration_pct"] == c and row_model(r) == m), None)
            t = None if r is None else _us(r["breakup_time_s"])
            tail = None if r is None else r.get("tail_length_at_breakup_m")
            cells.append(
                DASH if t is None else f"{t:.0f} µs {r['breakup_mode']}"  # type: ignore[index]
            )
            cells.append(DASH if tail is None else f"{tail * 1e6:.0f}")
        seed_t, seed_mode = SEED_BREAKUP.get(c, (None, None))
        seed = DASH if seed_t is None else f"{seed_t * 1e6:.0f} µs {seed_mode}"
        table_rows.append((f"{c:g}", *cells, seed))
    columns = ["NaAlg [% w/v]"]
    for m in models:
        columns += [f"{m}: first breakup", f"{m}: tail [µm]"]
    table = Table(
        title=f"Jet models side by side at {FIG4_VOLTAGE_V:g} V, and the seed",
        columns=(*columns, "seed 003"),
        rows=table_rows,
        note="tail: length of the ligament behind the head in the last 10 µs frame before "
        "the first breakup (microfab.process.inkjet.head_tail); a plug has none.",
    )
    return labelled(table, [_seed_shows(c, len(models)) for c in cs])


def _tables_of_one_model(rows: Sequence[dict[str, Any]], label: str) -> tuple[Table, ...]:
    model = row_model(rows[0]) if rows else DEFAULT_JET_MODEL
    skip = _others(model)

    def cells(r: dict[str, Any]) -> tuple[str, ...]:
        z = r.get("breakup_z_m")
        d = r.get("drop_diameter_m")
        return (
            DASH if z is None else f"{z * 1e6:.0f}",
            f"{r['head_speed_m_s']:.2f}" if r.get("head_speed_m_s") is not None else DASH,
            str(r.get("satellites", DASH)),
            DASH if d is None or not math.isfinite(d) else f"{d * 1e6:.0f}",
        )

    at50 = sorted(
        (r for r in rows if r["voltage_v"] == FIG4_VOLTAGE_V), key=lambda r: r["concentration_pct"]
    )
    series = []
    for r in at50:
        seed_t, seed_mode = SEED_BREAKUP.get(r["concentration_pct"], (None, None))
        series.append(
            (
                f"{r['concentration_pct']:g}",
                versus(_us(r["breakup_time_s"]), _us(seed_t), "{:.0f}".format),
                f"{r['breakup_mode'] or DASH} / {seed_mode or DASH}",
                *cells(r),
            )
        )
    tail = ("z [µm]", "head speed [m/s]", "satellites", "drop Ø [µm]")
    tables = [
        labelled(
            Table(
                title=f"First breakup at {FIG4_VOLTAGE_V:g} V, ours / seed 003 part 1{label}",
                columns=("NaAlg [% w/v]", "time [µs]", "mode", *tail),
                rows=series,
                note="The seed quotes two breakups (0.15 % at 95 µs by front-pinching, 1 % at "
                "230 µs by exit-pinching; 'Typical droplet formation process', Fig. 2); "
                "Fig. 4's other points are drawn, not tabulated. z is measured from the "
                "nozzle exit; a dash: no breakup within the simulated time.",
            ),
            [_seed_shows(r["concentration_pct"]) for r in at50],
            not_applied=skip,
        ),
        labelled(
            Table(
                title=f"Seed Fig. 4 trend: breakup time rises with concentration (50 V){label}",
                columns=("claim", "ours", "seed"),
                rows=[("breakup time rises with concentration", breakup_trend(at50), "yes")],
            ),
            Shows((quantity("003", "Fig. 4", "trend at 50 V"),)),
        ),
    ]
    by_c: dict[float, list[dict[str, Any]]] = {}
    for r in rows:
        by_c.setdefault(r["concentration_pct"], []).append(r)
    longest = max(by_c.values(), key=len, default=[])
    if len(longest) > 1:
        vrows = sorted(longest, key=lambda r: r["voltage_v"])
        tables.append(
            labelled(
                Table(
                    title=f"Voltage series at {vrows[0]['concentration_pct']:g} % NaAlg "
                    f"(ours){label}",
                    columns=("voltage [V]", "time [µs]", "mode", *tail),
                    rows=[
                        (
                            f"{r['voltage_v']:g}",
                            DASH
                            if r["breakup_time_s"] is None
                            else f"{r['breakup_time_s'] * 1e6:.0f}",
                            r["breakup_mode"] or DASH,
                            *cells(r),
                        )
                        for r in vrows
                    ],
                    note="Seed 003 Table 1 lists the voltages (40-70 V) but publishes no breakup "
                    "numbers for them.",
                ),
                OURS,
            )
        )
    return tuple(tables)
