"""``runs.json`` of ``stage excite`` is read through its schema (issue 44, cause A)."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.identify import excitation as ex

runner = CliRunner()


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("runs") / "runs"
    ex.write_runs(ex.random_runs(total_s=1.0, seed=0), d)
    return d


def _entry(key: str, value: object) -> Callable[[dict], None]:
    return lambda m: m["runs"][0].__setitem__(key, value)


CASES: dict[str, tuple[Callable[[dict], None], str]] = {
    "dt_s true": (_entry("dt_s", True), "runs.0.dt_s = True is not a number"),
    "n_samples a string": (_entry("n_samples", "10000"), "runs.0.n_samples = '10000' is not"),
    "n_samples a float": (_entry("n_samples", 10000.0), "runs.0.n_samples = 10000.0 is not"),
    "n_samples off": (_entry("n_samples", 7), "total_samples is 10000, the runs hold 7"),
    "a file outside the folder": (_entry("file", "../x.csv"), "'../x.csv' leaves the folder"),
    "seed negative": (_entry("seed", -1), "runs.0.seed = -1"),
    "no runs": (lambda m: m.__setitem__("runs", []), "runs = []"),
    "another unit": (lambda m: m.__setitem__("unit", "mm"), "unit = 'mm'"),
}


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.parametrize("name", list(CASES))
def test_stage_play_refuses_a_bad_run_list(runs_dir: Path, tmp_path: Path, name: str) -> None:
    change, says = CASES[name]
    d = tmp_path / "runs"
    d.mkdir()
    for f in runs_dir.iterdir():
        (d / f.name).write_bytes(f.read_bytes())
    meta = json.loads((d / ex.INDEX_FILE).read_text())
    change(meta)
    (d / ex.INDEX_FILE).write_text(json.dumps(meta))
    before = _snapshot(tmp_path)
    res = runner.invoke(app, ["stage", "play", str(d), "--out", str(tmp_path / "m")])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert says in res.output, res.output
    assert _snapshot(tmp_path) == before


def test_an_intact_run_list_reads_back(runs_dir: Path) -> None:
    runs = ex.read_runs(runs_dir)
    assert runs and all(r.n_samples > 1 for r in runs)
