from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from microfab.io.sweep import SweepError, load_results
from microfab.machines.printhead.machine import (
    DATA_FILES,
    DropletSettings,
    SweepPoint,
    droplet_sweep,
    limits,
    play,
    run_point,
    sweep_points,
    twin,
)
from microfab.plants.printhead import Printhead, nozzle_flow
from microfab.process.inkjet.dispenser import REFERENCE_PEAK_VELOCITY_M_S, default_printhead
from microfab.process.inkjet.fluids import naalg
from microfab.trajectory.waveform import seed003_waveform

cloudpickle = pytest.importorskip("cloudpickle")
# The stand-in simulation below travels to the worker processes by value (this test
# module is not importable there).
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _fake(calls: list[SweepPoint]):
    def sim(p: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
        calls.append(p)
        t = None if p.concentration_pct > 1.5 else 1e-4 * (1 + p.concentration_pct)
        return {"breakup_time_s": t, "breakup_mode": None if t is None else "exit"}

    return sim


def _picklable_sim(p: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
    if p.voltage_v == 65.0:
        raise ValueError("voltage 65 V: this stand-in model refuses it")
    return {"breakup_time_s": 1e-4 * p.concentration_pct, "duration_s": settings.duration_s}


def test_points_cover_both_series_once() -> None:
    pts = sweep_points([0.15, 1.0], [45, 50, 55])
    assert pts == [
        SweepPoint(0.15, 50.0),
        SweepPoint(1.0, 50.0),
        SweepPoint(1.0, 45.0),
        SweepPoint(1.0, 55.0),
    ]


def test_sweep_saves_each_point_and_resumes(tmp_path: Path) -> None:
    pts = sweep_points([0.15, 1.0, 2.0], [60])
    calls: list[SweepPoint] = []
    res = droplet_sweep(pts[:2], results_dir=tmp_path, simulate=_fake(calls))
    assert len(calls) == 2 and len(res.rows) == 2
    assert len(list((tmp_path / "points").glob("*.json"))) == 2
    res = droplet_sweep(pts, results_dir=tmp_path, simulate=_fake(calls))
    assert calls[2:] == pts[2:]  # only the new points ran
    assert res.skipped == tuple(pts[:2])
    assert [(r["concentration_pct"], r["voltage_v"]) for r in res.rows] == [
        (p.concentration_pct, p.voltage_v) for p in pts
    ]
    assert load_results(tmp_path) == list(res.rows)


def test_sweep_refuses_a_folder_with_other_settings(tmp_path: Path) -> None:
    droplet_sweep([SweepPoint(1.0, 50.0)], results_dir=tmp_path, simulate=_fake([]))
    with pytest.raises(ValueError, match=r"duration_s 0.0004 -> 0.0001"):
        droplet_sweep(
            [SweepPoint(1.0, 50.0)],
            settings=DropletSettings(duration_s=1e-4),
            results_dir=tmp_path,
            simulate=_fake([]),
        )


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"duration_s": 0.0}, "duration_s"),
        ({"after_breakup_s": float("nan")}, "after_breakup_s"),
        ({"max_steps": 0}, "max_steps"),
    ],
)
def test_settings_refuse_bad_values(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        DropletSettings(**kwargs)


def test_sweep_on_worker_processes_keeps_order_and_isolates_a_failure(tmp_path: Path) -> None:
    pts = sweep_points([0.15, 1.0, 1.5], [40, 65])
    seen: list[tuple[int, bool]] = []
    with pytest.raises(SweepError, match=r"(?s)1 sweep point\(s\) failed.*65 V") as err:
        droplet_sweep(
            pts,
            settings=DropletSettings(duration_s=3e-4),
            results_dir=tmp_path,
            simulate=_picklable_sim,
            workers=2,
            progress=lambda n, total, p, ok: seen.append((n, ok)),
        )
    rows = err.value.result.rows
    assert [(r["concentration_pct"], r["voltage_v"]) for r in rows] == [
        (p.concentration_pct, p.voltage_v) for p in pts if p.voltage_v != 65.0
    ]
    assert all(r["duration_s"] == 3e-4 for r in rows)  # settings reach the workers
    assert sorted(n for n, _ in seen) == [1, 2, 3, 4, 5]
    assert sum(not ok for _, ok in seen) == 1
    saved = [json.loads(f.read_text())["point"] for f in (tmp_path / "points").glob("*.json")]
    assert len(saved) == 4 and {"concentration_pct": 1.0, "voltage_v": 65.0} not in saved


# ------------------------------------------------------- the machine: twin, limits, play
WATER = {"density_kg_m3": 1000.0, "viscosity_pa_s": 1e-3, "surface_tension_n_m": 0.072}


def test_default_printhead_is_calibrated_and_cached() -> None:
    # moved from tests/process/inkjet/test_dispenser.py: the cache is now the machine's twin
    head = twin()
    assert twin() is head
    peak = nozzle_flow(head, seed003_waveform(50.0), **WATER).peak_velocity_m_s
    assert peak == pytest.approx(REFERENCE_PEAK_VELOCITY_M_S, rel=1e-9)
    # the class default is the same gain, rounded to three digits
    assert Printhead().gain_m3_per_v == pytest.approx(head.gain_m3_per_v, rel=5e-3)
    # the process layer's default (a new head per call) is the same head
    assert default_printhead() == head and default_printhead() is not head


def test_limits_are_the_calibrated_voltages_of_table_1() -> None:
    assert limits().voltage_v == (40.0, 70.0)
    assert DATA_FILES == ("naalg.toml",)


def test_play_a_voltage_or_its_waveform_is_one_run_on_the_twin() -> None:
    settings = DropletSettings(duration_s=30e-6, after_breakup_s=5e-6)
    by_volts = run_point(SweepPoint(0.15, 50.0), settings)
    by_wave = play(seed003_waveform(50.0), naalg(0.15), settings)
    assert by_volts.printhead is twin() and by_wave.printhead is twin()
    assert by_wave.to_dict() == by_volts.to_dict()


def test_model_defaults_follow_the_one_constant() -> None:
    import inspect

    from microfab.machines.printhead import calibration as printhead_calibration
    from microfab.machines.printhead import sensitivity as printhead_sensitivity
    from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL

    assert DropletSettings().model == DEFAULT_JET_MODEL
    for fn in (
        printhead_calibration.simulated_breakup,
        printhead_calibration.evaluate,
        printhead_calibration.problem,
        printhead_calibration.write_twin,
        printhead_sensitivity.perturbed_fluid,
    ):
        assert inspect.signature(fn).parameters["model"].default == DEFAULT_JET_MODEL, fn
