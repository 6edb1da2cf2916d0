"""The droplet-sweep job kind: its file, its tables beside the seed, its run and report."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS, load_job
from microfab.experiments.seed003_inkjet.job import DropletSweepConfig
from microfab.io.job import JobFileError
from microfab.io.sweep import SweepResult
from microfab.machines.printhead import machine as printhead
from microfab.machines.printhead.machine import DropletSettings, SweepPoint
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL

EXAMPLES = Path(__file__).parents[3] / "examples"


def _write(tmp_path: Path, sweep: str, run: str = "") -> Path:
    p = tmp_path / "job.toml"
    p.write_text(
        f'[job]\nkind = "droplet-sweep"\nout = "{tmp_path / "out"}"\n[sweep]\n{sweep}\n'
        + (f"[run]\n{run}\n" if run else ""),
        encoding="utf-8",
    )
    return p


def test_example_is_the_seed_sweep() -> None:
    job = load_job(EXAMPLES / "droplet_sweep.toml")
    assert job.kind is JOB_KINDS["droplet-sweep"]
    cfg = job.config
    assert cfg.concentrations_pct == (0.15, 0.2, 0.25, 1.0, 1.5, 2.0)
    assert len(cfg.points) == 6 + 6  # 50 V at 1 % is in both series, run once
    assert cfg.settings == DropletSettings(duration_s=400e-6, after_breakup_s=20e-6)
    assert cfg.workers == 2 and cfg.scheduler is None
    assert cfg.models == (DEFAULT_JET_MODEL,)  # the example runs the default model


def test_job_file_values_are_checked(tmp_path: Path) -> None:
    with pytest.raises(JobFileError, match=r"\[sweep\] voltages_v = \[30\].*\[40, 70\] V"):
        load_job(_write(tmp_path, "voltages_v = [30]"))
    with pytest.raises(JobFileError, match=r"concentrations_pct = \[2.5\].*\[0, 2\] % w/v"):
        load_job(_write(tmp_path, "concentrations_pct = [2.5]"))
    with pytest.raises(JobFileError, match=r"\[run\] workers = 0"):
        load_job(_write(tmp_path, "", "workers = 0"))
    with pytest.raises(JobFileError, match=r"duration_us = inf"):
        load_job(_write(tmp_path, "duration_us = inf"))
    cfg = load_job(_write(tmp_path, "concentrations_pct = [0.15]\nvoltages_v = []")).config
    assert cfg.points == [SweepPoint(0.15, 50.0)]


def test_models_default_to_the_one_constant(tmp_path: Path) -> None:
    assert DropletSweepConfig().models == (DEFAULT_JET_MODEL,)
    # a job file that names no models runs the default one
    cfg = load_job(_write(tmp_path, "concentrations_pct = [0.15]\nvoltages_v = []")).config
    assert cfg.models == (DEFAULT_JET_MODEL,)
    assert cfg.settings.model == DEFAULT_JET_MODEL


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


def test_run_writes_report_summary_and_resumes(tmp_path: Path) -> None:
    """A real one-point job: 0.15 % at 50 V (seed: 95 µs)."""
    job = load_job(
        _write(tmp_path, "concentrations_pct = [0.15]\nvoltages_v = []\nduration_us = 120")
    )
    out = tmp_path / "out"
    seen: list[tuple[str, int, int | None]] = []
    result = job.kind.run(job.config, out, lambda *a: seen.append(a))
    assert seen[-1] == ("droplet sweep", 1, 1)
    (row,) = result.rows
    assert 80e-6 < row["breakup_time_s"] < 120e-6
    summary = (out / "summary.json").read_text()
    assert '"breakup_at_50V"' in summary and result.failures() == ()
    report = job.kind.write_report(result, out, job.title).read_text()
    assert "95" in report and f"{row['breakup_time_s'] * 1e6:.0f} / 95" in report
    assert (out / "breakup_time.png").stat().st_size > 0
    again = job.kind.run(job.config, out, lambda *a: None)
    assert again.rows == result.rows  # resumed from out/sweep, not run again


def test_a_failed_point_is_reported_and_the_rest_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def flaky(p: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
        if p.concentration_pct == 2.0:
            raise RuntimeError("solver diverged")
        return _row(p.concentration_pct, p.voltage_v, 1e-4)

    real = printhead.droplet_sweep

    def sweep(*args: Any, **kwargs: Any) -> SweepResult[SweepPoint]:
        return real(*args, simulate=flaky, **kwargs)

    monkeypatch.setattr(printhead, "droplet_sweep", sweep)
    job = load_job(_write(tmp_path, "concentrations_pct = [0.15, 2.0]\nvoltages_v = []"))
    result = job.kind.run(job.config, tmp_path / "out", lambda *a: None)
    assert [r["concentration_pct"] for r in result.rows] == [0.15]
    assert result.failures() == ("2 %, 50 V: RuntimeError: solver diverged",)
    report = job.kind.write_report(result, tmp_path / "out", "t").read_text()
    assert "Failed point: 2 %, 50 V: RuntimeError: solver diverged" in report


def test_config_refuses_an_empty_sweep() -> None:
    with pytest.raises(ValueError, match="no points"):
        DropletSweepConfig(concentrations_pct=(), voltages_v=())
    with pytest.raises(ValueError, match="models must name one or more of lagrangian"):
        DropletSweepConfig(models=("lagrangian", "smooth"))


def test_two_models_are_run_saved_apart_and_compared(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    seen: list[str] = []

    def fake(p: SweepPoint, settings: DropletSettings) -> dict[str, Any]:
        seen.append(settings.model)
        t = 1e-4 if settings.model == "lagrangian" else 2e-4
        row = _row(p.concentration_pct, p.voltage_v, t, "front")
        return {**row, "tail_length_at_breakup_m": 5e-5}

    real = printhead.droplet_sweep

    def sweep(*args: Any, **kwargs: Any) -> SweepResult[SweepPoint]:
        return real(*args, simulate=fake, **kwargs)

    monkeypatch.setattr(printhead, "droplet_sweep", sweep)
    job = load_job(
        _write(
            tmp_path,
            'concentrations_pct = [0.15]\nvoltages_v = []\nmodels = "lagrangian, eulerian"',
        )
    )
    out = tmp_path / "out"
    result = job.kind.run(job.config, out, lambda *a: None)
    assert seen == ["lagrangian", "eulerian"]
    assert [r["jet_model"] for r in result.rows] == ["lagrangian", "eulerian"]
    assert (out / "sweep-lagrangian").is_dir() and (out / "sweep-eulerian").is_dir()
    tables = result.comparison()
    assert tables[0].title.startswith("Jet models side by side")
    assert tables[0].rows[0][:-1] == (
        "0.15", "100 µs front", "50", "200 µs front", "50", "95 µs front"
    )  # fmt: skip
    assert tables[0].labels[0].counts == {"fitted": 2, "predicted": 1}  # both models' times
    report = job.kind.write_report(result, out, "t").read_text()
    assert "eulerian model: 0.15 %: front at 200 µs" in report
    assert (out / "breakup_time_eulerian.png").stat().st_size > 0


def test_fig4_reproduction_options() -> None:
    rep = REPRODUCTIONS["droplet-fig4"]
    assert rep.parse_options({}) == {
        "duration_us": 400.0,
        "models": "lagrangian,eulerian",
        "workers": 1,
    }
    with pytest.raises(JobFileError, match="workers"):
        rep.parse_options({"workers": 0})
    # the models are names, checked before a run (make fuzz: "/" was called valid)
    assert rep.preflight is not None
    rep.preflight(rep.parse_options({"models": "eulerian"}))
    for bad in ("/", "../../../x", "eulerian,smoothed", " , "):
        with pytest.raises(ValueError, match="models must name one or more of"):
            rep.preflight(rep.parse_options({"models": bad}))


def test_the_report_names_the_fitted_parameters() -> None:
    from microfab.experiments.seed003_inkjet.job import _fitted
    from microfab.process.inkjet.fluids import load_table

    law = load_table().law("eulerian")
    note = _fitted("eulerian")
    assert f"λ_ref = {law.lambda_ref_s * 1e6:.3g} µs" in note
    assert f"m = {law.exponent:.3g}" in note
    assert "microfab droplet calibrate --model eulerian" in note
