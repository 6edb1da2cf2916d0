"""``microfab laser analyze`` reads its trace through the trace schema (issue 44, cause A)."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import write_columns

runner = CliRunner()
R = 30e-6  # m, the drawing's radius
DT = 1e-4  # s, the laser stage controller's sample time


def _trace(path: Path, n: int, time_scale: float = 1.0, unit: str = "m") -> None:
    phi = np.linspace(0.0, 2 * np.pi, n)
    x, y = R * np.cos(phi), R * np.sin(phi)
    cols = {"time": np.arange(n) * DT * time_scale, "ref_x": x, "ref_y": y, "x": x, "y": y}
    write_columns(path, cols, unit=unit)


def _run(path: Path, tmp_path: Path) -> object:
    args = ["laser", "analyze", str(path), "--drawing", f"circle:radius={R}"]
    return runner.invoke(app, [*args, "--json", str(tmp_path / "a.json")])


@pytest.mark.parametrize(
    "n, scale, unit, says",
    [
        (3, 1.0, "m", "3 samples; this needs at least 200"),
        (400, 1e3, "m", "sample time 0.1 s, but the stage's controller samples every 0.0001 s"),
        (400, 1.0, "parsecs", "unknown unit 'parsecs'"),
        (400, 1.0, "V", "unit 'V'; the stage's positions are read in m"),
    ],
)
def test_a_trace_the_stage_cannot_have_recorded_is_refused(
    tmp_path: Path, n: int, scale: float, unit: str, says: str
) -> None:
    path = tmp_path / "t.csv"
    _trace(path, n, scale, unit)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    res = _run(path, tmp_path)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert says in res.output, res.output
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest
    assert not (tmp_path / "a.json").exists()


def test_a_trace_at_the_controller_rate_is_analysed(tmp_path: Path) -> None:
    _trace(tmp_path / "t.csv", 400)
    res = _run(tmp_path / "t.csv", tmp_path)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "a.json").is_file()
