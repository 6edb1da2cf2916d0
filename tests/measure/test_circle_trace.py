"""``microfab nanomanipulator analyze`` on synthetic traces of the pattern with known errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import write_columns
from microfab.measure.circle_trace import analyze_trace, pattern_from_job
from microfab.trajectory.circle_pattern import PatternConfig, pattern_reference

runner = CliRunner()
DT = 1e-4  # the twin's 10 kHz (data/nanomanipulator_twin.toml)
CFG = PatternConfig(period_s=0.05, periods=4, pause_s=0.02, move_s=0.03, ramp_s=0.02)
OPTS = ["--period", "0.05", "--periods", "4", "--pause-s", "0.02", "--move-s", "0.03"]
OPTS += ["--ramp-s", "0.02"]
DELTA_MM = 3e-4  # every circle run 300 nm outside its circle


def _columns(cfg: PatternConfig = CFG, dt: float = DT) -> dict[str, np.ndarray]:
    ref = pattern_reference(cfg, dt)
    y = ref.position.copy()
    laser = np.zeros(ref.n_samples)
    n = ref.period_samples
    for i, c in enumerate(ref.centres):
        sl = ref.circle_slice(i)
        u = (ref.position[sl] - c) / ref.radius_mm
        y[sl] = c + (ref.radius_mm + DELTA_MM) * u
        laser[ref.starts[i] + 2 * n : ref.starts[i] + 3 * n] = 1.0  # exposes period 3
    return {
        "time": 5.0 + np.arange(ref.n_samples) * dt,  # a recorder's clock need not start at 0
        "ref_x": ref.position[:, 0],
        "ref_y": ref.position[:, 1],
        "x": y[:, 0],
        "y": y[:, 1],
        "laser": laser,
    }


def _analyze(*args: str) -> object:
    return runner.invoke(app, ["nanomanipulator", "analyze", *args])


def _one_error_line(res: object, *says: str) -> None:
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    for s in says:
        assert s in lines[0], lines[0]


@pytest.mark.parametrize("suffix", [".csv", ".mat", ".h5"])
def test_metrics_table_json_and_report_from_a_trace(tmp_path: Path, suffix: str) -> None:
    trace = tmp_path / f"trace{suffix}"
    write_columns(trace, _columns())
    out, js = tmp_path / "report", tmp_path / "m.json"
    res = _analyze(str(trace), *OPTS, "--out", str(out), "--json", str(js))
    assert res.exit_code == 0, res.output
    # radial 300 nm: contour RMS 300 nm, each axis 300/√2 = 212.1 nm, laser on in period 3
    assert "300.0 / 769.5" in res.output and "212.1 / 485.8" in res.output
    assert "3 / 3-4" in res.output
    s = json.loads(js.read_text())
    assert s["metrics"]["contour_rms_nm"] == pytest.approx(300.0, rel=1e-6)
    assert s["metrics"]["gate_period"] == [3, 3, 3, 3]
    assert s["sample_rate_hz"] == pytest.approx(1e4) and s["pattern"]["periods"] == 4
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "contour_phase.png",
        "error_time.png",
        "period_rms.png",
        "report.html",
        "xy.png",
    ]
    page = (out / "report.html").read_text()
    assert "Fig. 13b" in page and "300.0 / 769.5" in page and "per period" in page
    assert (out / "xy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_pattern_from_a_job_file(tmp_path: Path) -> None:
    trace = tmp_path / "t.csv"
    write_columns(trace, _columns())
    job = tmp_path / "job.toml"
    job.write_text(
        '[job]\nkind = "nanomanipulator-msl"\n[pattern]\nperiod_s = 0.05\nperiods = 4\n'
        "pause_s = 0.02\nmove_s = 0.03\nramp_s = 0.02\n[rbf]\nn_nodes = 25\n",
        encoding="utf-8",
    )
    assert pattern_from_job(job) == CFG
    res = _analyze(str(trace), "--job", str(job))
    assert res.exit_code == 0, res.output
    assert "300.0 / 769.5" in res.output
    _one_error_line(_analyze(str(trace), "--job", str(job), "--periods", "4"), "not both")
    job.write_text("[pattern]\nperods = 4\n", encoding="utf-8")
    _one_error_line(_analyze(str(trace), "--job", str(job)), "unknown key(s) ['perods']")
    job.write_text("[pattern]\nperiod_s = 0.0\n", encoding="utf-8")
    _one_error_line(_analyze(str(trace), "--job", str(job)), "[pattern]", "period_s")


def _bad(tmp_path: Path, cols: dict[str, np.ndarray], *args: str, says: tuple[str, ...]) -> None:
    trace = tmp_path / "t.csv"
    write_columns(trace, cols)
    out, js = tmp_path / "report", tmp_path / "m.json"
    res = _analyze(str(trace), *(args or OPTS), "--out", str(out), "--json", str(js))
    _one_error_line(res, *says)
    assert not out.exists() and not js.exists()


def test_refusals_name_the_fault_and_write_nothing(tmp_path: Path) -> None:
    good = _columns()
    cols = {k: v for k, v in good.items() if k not in ("laser", "y")}
    _bad(tmp_path, cols, says=("missing column(s) y, laser",))
    cols = dict(good, x=good["x"].copy())
    cols["x"][1234] = np.nan
    _bad(tmp_path, cols, says=("column 'x' holds nan at sample 1234", "t = 5.1234 s"))
    _bad(tmp_path, {k: v[:0] for k, v in good.items()}, says=("holds no samples",))
    cols = dict(good, time=good["time"].copy())
    cols["time"][3000:] += 0.5 * DT * np.arange(1, cols["time"].size - 2999)
    _bad(tmp_path, cols, says=("sample rate changes at sample 3000",))
    cols = dict(good, time=5.0 + 2 * np.arange(good["time"].size) * DT)
    _bad(tmp_path, cols, says=("sampled at 5000 Hz, the pattern at 10000 Hz",))
    cols = dict(good, laser=good["laser"] * 2.0)
    _bad(tmp_path, cols, says=("column 'laser' holds 2", "write 0 (off) or 1 (on)"))
    # the reference of a 0.16 mm circle is not the pattern's 0.15 mm one
    cols = _columns(PatternConfig(**{**vars(CFG), "diameter_mm": 0.16}))
    _bad(
        tmp_path,
        cols,
        says=("ref_", "departs from the pattern by 10 µm at t = 5.07 s", "--diameter-mm"),
    )
    # the default pattern (6 periods of 1 s) is longer than this trace
    _bad(
        tmp_path,
        good,
        "--sample-rate-hz",
        "10000",
        says=("the pattern 282000 (28.2 s)", "--periods"),
    )
    _bad(tmp_path, good, *OPTS[2:], "--period", "0.05005", says=("whole number",))
    _bad(tmp_path, good, *OPTS, "--circles", "0", says=("--circles", "outside the allowed range"))


def test_refused_before_reading_or_on_a_bad_file(tmp_path: Path) -> None:
    _one_error_line(_analyze(str(tmp_path / "none.csv"), *OPTS), "not found")
    (tmp_path / "t.txt").write_text("x")
    _one_error_line(_analyze(str(tmp_path / "t.txt"), *OPTS), "unsupported trace file suffix")
    _one_error_line(_analyze(str(tmp_path / "t.csv"), "--colour", "red"), "No such option")
    (tmp_path / "f").write_text("")
    _one_error_line(_analyze(str(tmp_path / "t.csv"), "--out", str(tmp_path / "f")), "is a file")


def test_library_call_matches_the_command(tmp_path: Path) -> None:
    trace = tmp_path / "t.h5"
    write_columns(trace, _columns())
    a = analyze_trace(trace, CFG, sample_rate_hz=1e4)
    np.testing.assert_allclose(a.metrics.axial_rms_nm, 300.0 / np.sqrt(2.0), rtol=1e-9)
    assert a.metrics.exposed_rms_nm == pytest.approx((300.0,) * 4, rel=1e-9)
    np.testing.assert_allclose(a.metrics.period_rms_nm, 300.0, rtol=1e-9)
