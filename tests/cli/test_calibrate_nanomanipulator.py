"""``microfab calibrate nanomanipulator`` on the calibration core, on a small budget."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from typer.testing import CliRunner

from microfab.cli import app

ROOT = Path(__file__).resolve().parents[2]


def test_a_small_calibration_reports_every_target_and_writes_the_twin(tmp_path):
    # one circle of four periods (the seed's job has four of six): about 27 short runs
    text = (ROOT / "examples" / "nanomanipulator_msl.toml").read_text()
    text = text.replace("n_circles = 4", "n_circles = 1").replace("periods = 6", "periods = 4")
    job = tmp_path / "job.toml"
    job.write_text(text)
    argv = ["calibrate", "nanomanipulator", "--job", str(job), "--budget", "17"]
    argv += ["--conflict-budget", "0", "--json", str(tmp_path / "cal.json")]
    argv += ["--write", str(tmp_path / "twin.toml")]
    res = CliRunner().invoke(app, argv)
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "cal.json").read_text())
    roles = {t["name"]: t["role"] for t in doc["targets"]}
    assert roles == {
        "seed 001 §4.2 / axial RMS / x": "fit",
        "seed 001 §4.2 / axial RMS / y": "fit",
        "seed 001 §4.2 / contour RMS": "check",
        "seed 001 §4.2 / gate period": "check",
    }
    assert {p["name"] for p in doc["parameters"]} == {
        "noise_x_nm",
        "noise_y_nm",
        "noise_time_constant_ms",
        "d0_x_mm_s2",
        "d0_y_mm_s2",
    }
    assert len(doc["sensitivity"]) == 4 and all(len(r) == 5 for r in doc["sensitivity"])
    assert isinstance(doc["converged"], bool) and doc["requested"] >= 17
    for t in doc["targets"]:
        assert t["model"] is None or t["model"] > 0.0, t  # a diverged run is None
    assert "contour RMS" in res.output and "check" in res.output
    twin = tomllib.loads((tmp_path / "twin.toml").read_text())
    src = twin["axes"]["x"]["noise_rms_mm_source"]
    assert src.startswith("calibrated: `microfab calibrate nanomanipulator`")
    assert "checks held back: seed 001 §4.2 / contour RMS" in src
