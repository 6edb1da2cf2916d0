from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from microfab.experiments.seed003_inkjet.sweep import SweepPoint, run_sweep, sweep_points


def _fake(calls: list[SweepPoint]):
    def sim(p: SweepPoint, duration_s: float) -> dict[str, Any]:
        calls.append(p)
        t = None if p.concentration_pct > 1.5 else 1e-4 * (1 + p.concentration_pct)
        return {"breakup_time_s": t, "breakup_mode": None if t is None else "exit"}

    return sim


def _picklable_sim(p: SweepPoint, duration_s: float) -> dict[str, Any]:
    if p.voltage_v == 66.0:
        raise ValueError("voltage 66 V: this stand-in model refuses it")
    return {"breakup_time_s": 1e-4 * p.concentration_pct, "breakup_mode": "exit"}


def test_parallel_sweep_keeps_order_and_saves_every_point(tmp_path: Path) -> None:
    path = tmp_path / "sweep.json"
    pts = sweep_points([0.15, 1.0, 1.5], [40, 60])
    seen: list[int] = []
    rows = run_sweep(
        pts,
        results_path=path,
        simulate=_picklable_sim,
        jobs=2,
        progress=lambda n, p: seen.append(n),
    )
    assert [(r["concentration_pct"], r["voltage_v"]) for r in rows] == [
        (p.concentration_pct, p.voltage_v) for p in pts
    ]
    assert [r["breakup_time_s"] for r in rows] == [1e-4 * p.concentration_pct for p in pts]
    assert seen == [1, 2, 3, 4, 5]
    assert len(json.loads(path.read_text())["rows"]) == len(pts)


def test_parallel_sweep_keeps_the_points_that_finished_when_one_fails(tmp_path: Path) -> None:
    path = tmp_path / "sweep.json"
    pts = sweep_points([0.15, 1.0], [66])
    with pytest.raises(ValueError, match="66 V"):
        run_sweep(pts, results_path=path, simulate=_picklable_sim, jobs=2)
    saved = json.loads(path.read_text())["rows"]
    assert sorted((r["concentration_pct"], r["voltage_v"]) for r in saved) == [
        (0.15, 50.0),
        (1.0, 50.0),
    ]
    with pytest.raises(ValueError, match="jobs"):
        run_sweep(pts, simulate=_picklable_sim, jobs=0)


def test_points_cover_both_series_once() -> None:
    pts = sweep_points([0.15, 1.0], [45, 50, 55])
    assert pts == [
        SweepPoint(0.15, 50.0),
        SweepPoint(1.0, 50.0),
        SweepPoint(1.0, 45.0),
        SweepPoint(1.0, 55.0),
    ]


def test_sweep_saves_each_point_and_resumes(tmp_path: Path) -> None:
    path = tmp_path / "sweep.json"
    pts = sweep_points([0.15, 1.0, 2.0], [60])
    calls: list[SweepPoint] = []
    rows = run_sweep(pts[:2], results_path=path, simulate=_fake(calls))
    assert len(calls) == 2 and len(rows) == 2
    assert len(json.loads(path.read_text())["rows"]) == 2
    rows = run_sweep(pts, results_path=path, simulate=_fake(calls))
    assert [c for c in calls[2:]] == pts[2:]  # only the new points ran
    assert [(r["concentration_pct"], r["voltage_v"]) for r in rows] == [
        (p.concentration_pct, p.voltage_v) for p in pts
    ]


def test_sweep_refuses_a_file_with_other_settings(tmp_path: Path) -> None:
    path = tmp_path / "sweep.json"
    run_sweep([SweepPoint(1.0, 50.0)], results_path=path, simulate=_fake([]))
    with pytest.raises(ValueError, match="other file"):
        run_sweep([SweepPoint(1.0, 50.0)], duration_s=1e-4, results_path=path, simulate=_fake([]))
    with pytest.raises(ValueError, match="duration"):
        run_sweep([SweepPoint(1.0, 50.0)], duration_s=0.0, simulate=_fake([]))
