"""The droplet sweep's tables: the seed beside ours, the Fig. 4 trend, the voltage series."""

from __future__ import annotations

from typing import Any

from microfab.report.inkjet_tables import LEGACY_ROW_MODEL, breakup_tables, row_model


def _row(c: float, v: float, t: float | None, mode: str | None = "exit") -> dict[str, Any]:
    return {
        "concentration_pct": c,
        "voltage_v": v,
        "breakup_time_s": t,
        "breakup_mode": mode if t is not None else None,
        "breakup_z_m": None if t is None else 1e-4,
        "head_speed_m_s": 3.0,
        "satellites": 1,
        "drop_diameter_m": 80e-6,
    }


def test_tables_put_the_seed_beside_ours_and_judge_the_trend() -> None:
    rows = [_row(0.15, 50, 96e-6), _row(1.0, 50, 258e-6), _row(1.0, 60, 200e-6)]
    first, trend, volts = breakup_tables(rows)
    assert first.rows[0][:3] == ("0.15", "96 / 95", "exit / front")
    assert first.rows[1][:3] == ("1", "258 / 230", "exit / exit")
    assert trend.rows == (("breakup time rises with concentration", "yes", "yes", "predicted"),)
    # the quoted times are the calibration's targets, the modes are not
    assert first.labels[0].origin == "mixed" and first.labels[0].counts == {
        "fitted": 1,
        "predicted": 1,
    }
    assert first.labels[0].by == ("microfab droplet calibrate --model lagrangian",)
    assert [r[0] for r in volts.rows] == ["50", "60"]

    falling = [_row(0.15, 50, 96e-6), _row(1.0, 50, 258e-6), _row(1.5, 50, 133e-6)]
    assert breakup_tables(falling)[1].rows[0][1] == "no: falls from 1 % → 1.5 %"
    missing = [_row(0.15, 50, 96e-6), _row(2.0, 50, None)]
    tables = breakup_tables(missing)
    assert tables[1].rows[0][1] == "no: no breakup at 2 %"
    assert tables[0].rows[1][1] == "— / —"
    assert len(tables) == 2  # no voltage series in these rows


def test_rows_without_a_model_are_the_legacy_lagrangian_runs() -> None:
    # rows saved before they named their model came from the Lagrangian model, whatever
    # the default model is now
    assert LEGACY_ROW_MODEL == "lagrangian"
    assert row_model(_row(1.0, 50, 2e-4)) == "lagrangian"
    assert row_model({**_row(1.0, 50, 2e-4), "jet_model": "eulerian"}) == "eulerian"
