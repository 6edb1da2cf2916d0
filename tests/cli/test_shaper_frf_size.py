"""``shaper design --frf`` refuses an FRF too short to place a mode (issue 44, cause A)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli.shaper import MIN_FRF_POINTS
from microfab.io.frf import write_frf

runner = CliRunner()


def test_an_frf_of_three_rows_is_refused(model_file: Path, tmp_path: Path) -> None:
    frf = tmp_path / "frf.csv"
    f = np.array([1000.0, 3000.0, 5000.0])
    write_frf(frf, f, np.array([[1.0 + 0j], [3.0 + 0j], [1.0 + 0j]]), ("x",))
    out = tmp_path / "s.json"
    argv = ["shaper", "design", str(model_file), "--kind", "zv", "--frf", str(frf)]
    res = runner.invoke(app, [*argv, "--out", str(out)])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert f"an FRF of 3 frequencies; a shaper is designed from at least {MIN_FRF_POINTS}" in (
        res.output
    )
    assert not out.exists()
