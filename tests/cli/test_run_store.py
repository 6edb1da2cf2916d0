"""Every job kind through ``microfab run`` and the run store (issue 31).

For each kind, on settings small enough for the suite yet large enough to save more than
one checkpoint or result file: a run; the same job with one setting changed into the same
folder is refused on one ``error:`` line naming that setting (old -> new) and nothing
changes; ``--fresh`` runs it and gives its own numbers (those of the changed job in a clean
folder); a run interrupted right after its first saved file resumes to the numbers of an
uninterrupted run, bit for bit.
"""

from __future__ import annotations

import importlib
import json
import sys
import threading
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.experiments.catalog import JOB_KINDS
from microfab.io.atomic import watch_writes

runner = CliRunner()


@dataclass(frozen=True)
class Case:
    kind: str
    body: str
    old: str  # a line of body
    new: str  # what it becomes
    named: str  # the setting the refusal names


CASES = [
    Case("msl-ilc", "[scan]\nfeatures_per_s = 400\niterations = 4\nlearning_rates = [400]\n"
         "[ilc]\ngain = 0.4\n", "gain = 0.4", "gain = 0.2", "ilc.gain 0.4 -> 0.2"),
    Case("nanomanipulator-msl", "[pattern]\nn_circles = 2\nperiods = 3\nfield_mm = 0.3\n"
         "[twin]\nseed = 0\n", "seed = 0", "seed = 1", "twin.seed 0 -> 1"),
    Case("droplet-sweep", "[sweep]\nconcentrations_pct = [0.15, 0.5]\nvoltages_v = []\n"
         "duration_us = 110\n", "duration_us = 110", "duration_us = 100",
         "sweep.duration_us 110 -> 100"),
    Case("laser-micromachining", "[trajectory]\nlaps = 1\n[sweep]\nspeeds_mm_s = [0.5, 1.0]\n"
         "[focus]\nrun = false\n[twin]\nseed = 0\n", "seed = 0", "seed = 3",
         "twin.seed 0 -> 3"),
    Case("slm-shaping", "[identify]\nperiod_s = 0.1\nperiods = 3\ndropped = 1\n[shaper]\n"
         "compare = false\n[layer]\nsource = \"lattice:z=8.2e-4,radius=2e-3\"\n[build]\n"
         "layers = 2\nworkers = 1\noutline_radius_mm = 2.0\n[twin]\nseed = 0\n",
         "seed = 0", "seed = 1", "twin.seed 0 -> 1"),
    Case("stage-identify", "[linear]\ntotal_s = 10.0\norders = [2, 4]\n[ann]\ntotal_s = 10.0\n"
         "max_epochs = 1\nepoch_windows = 4096\nval_windows = 4096\nworkers = 1\n[cases]\n"
         "table_a_max = [1.0]\nsweep_a_max = [1.0]\n[studies]\ncoupling = false\n"
         "classic = false\n[twin]\nseed = 0\n", "seed = 0", "seed = 1", "twin.seed 0 -> 1"),
    Case("stage-reference-opt", "[models]\ndir = \"{models}\"\n[cases]\nnames = \"r\"\n"
         "a_max = [2.0]\nairfoil_a_max = []\ntolerance_um = 100.0\nletter_height_mm = 5.0\n"
         "airfoil_chord_mm = 20.0\n[tradeoff]\nletters_a_max = []\nairfoil_a_max = []\n[stage2]\n"
         "max_iter = 2\n[twin]\nseed = 0\n", "seed = 0", "seed = 1", "twin.seed 0 -> 1"),
]  # fmt: skip


class _Stop(BaseException):
    """Stands for Ctrl-C (a BaseException, like KeyboardInterrupt)."""


def _job(tmp_path: Path, case: Case, body: str, models: Path | None) -> Path:
    p = tmp_path / "job.toml"
    text = f'[job]\nkind = "{case.kind}"\n' + body.replace("{models}", str(models))
    p.write_text(text, encoding="utf-8")
    return p


def _run(job: Path, out: Path, *extra: str) -> tuple[int, str]:
    res = runner.invoke(app, ["run", str(job), "--out", str(out), *extra])
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception
    return res.exit_code, res.output


#: Bookkeeping in a summary, not results: wall and compute times, points found saved.
_BOOKKEEPING = {"wall_s", "compute_s", "seconds", "n_skipped", "resumed_from"}


def _numbers(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _numbers(v) for k, v in obj.items() if k not in _BOOKKEEPING}
    if isinstance(obj, list):
        return [_numbers(v) for v in obj]
    return obj


def _summary(out: Path) -> Any:
    """The run's summary.json without bookkeeping (floats compared exactly)."""
    return _numbers(json.loads((out / "summary.json").read_text(encoding="utf-8")))


def _tree(root: Path) -> dict[str, int]:
    return {p.relative_to(root).as_posix(): p.stat().st_mtime_ns for p in root.rglob("*")}


@pytest.fixture(params=CASES, ids=[c.kind for c in CASES])
def case(request: pytest.FixtureRequest) -> Case:
    c = request.param
    if c.kind.startswith("stage-"):
        pytest.importorskip("torch")
        pytest.importorskip("casadi")
    return c


def test_a_changed_job_is_refused_and_fresh_runs_it(
    case: Case, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    models = request.getfixturevalue("tiny_models")[0] if "{models}" in case.body else None
    out = tmp_path / "out"
    job = _job(tmp_path, case, case.body, models)
    code, text = _run(job, out)
    assert code == 0, text
    first = _summary(out)
    check = request.getfixturevalue("page_check")
    if check is not None:  # the kind's page as a reader sees it (issue 32)
        check(out / "report.html")
    manifest = json.loads((out / "run.json").read_text())
    assert len(manifest["files"]) >= 3, manifest["files"]  # results saved as they came
    # the same job again resumes and reports the same numbers
    code, text = _run(job, out)
    assert code == 0, text
    assert _summary(out) == first
    # one setting changed: refused on one line, nothing touched
    assert case.old in case.body
    changed = _job(tmp_path, case, case.body.replace(case.old, case.new), models)
    before = _tree(out)
    code, text = _run(changed, out)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), text
    assert case.named in lines[0] and "--fresh" in lines[0], lines[0]
    assert _tree(out) == before
    # --fresh: the changed job's own numbers, as in a clean folder
    code, text = _run(changed, out, "--fresh")
    assert code == 0, text
    fresh = _summary(out)
    assert fresh != first
    code, text = _run(changed, tmp_path / "clean")
    assert code == 0, text
    assert _summary(tmp_path / "clean") == fresh
    assert len(list((out / "_previous").iterdir())) == 1


def test_an_interrupted_run_resumes_bit_identical(
    case: Case, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    models = request.getfixturevalue("tiny_models")[0] if "{models}" in case.body else None
    job = _job(tmp_path, case, case.body, models)
    code, text = _run(job, tmp_path / "whole")
    assert code == 0, text
    out = tmp_path / "cut"
    main = threading.main_thread()
    saved: list[Path] = []

    def stop_after_first(path: Path) -> None:
        # the first file saved under the run folder, then Ctrl-C (in the main thread:
        # a checkpoint written on a worker thread stops the run at its next file)
        if out in Path(path).parents and Path(path).name != "run.json":
            saved.append(Path(path))
            if threading.current_thread() is main:
                raise _Stop

    with watch_writes(stop_after_first), pytest.raises(_Stop):
        _run(job, out)
    assert saved and not (out / "report.html").exists()
    code, text = _run(job, out)
    assert code == 0, text
    assert _summary(out) == _summary(tmp_path / "whole")


# --------------------------------------------------------------- the twin built once
_DATA = str(Path(__file__).parents[2] / "src" / "microfab" / "data")
_opened: list[str] | None = None


def _audit(event: str, args: tuple) -> None:  # an audit hook cannot be removed: gated
    if _opened is not None and event == "open" and isinstance(args[0], str):
        if args[0].startswith(_DATA) and args[0].endswith((".toml", ".json", ".dat")):
            _opened.append(Path(args[0]).name)


sys.addaudithook(_audit)

#: The twins' classes: a construction is counted per class and configuration.
_TWINS = (
    ("microfab.plants.galvo", "GalvoAxis"),
    ("microfab.plants.base", "LTIPlant"),
    ("microfab.plants.nanomanipulator", "NanomanipulatorPlant"),
    ("microfab.plants.xy_stage", "XYStagePlant"),
    ("microfab.plants.lmw_stage", "LMWStage"),
    ("microfab.plants.lmw_focus", "LMWFocus"),
    ("microfab.plants.printhead", "Printhead"),
)


def test_each_twin_is_built_once_per_configuration(
    case: Case, tmp_path: Path, request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Per run: each data file parsed at most once, each twin built once per configuration."""
    global _opened
    models = request.getfixturevalue("tiny_models")[0] if "{models}" in case.body else None
    job = _job(tmp_path, case, case.body, models)
    builds: Counter[tuple[str, str]] = Counter()
    for module, name in _TWINS:
        cls = getattr(importlib.import_module(module), name)
        init = cls.__init__

        def counted(self: Any, *a: Any, _init: Any = init, _name: str = name, **k: Any) -> None:
            builds[(_name, repr((a, sorted(k.items()))))] += 1
            _init(self, *a, **k)

        monkeypatch.setattr(cls, "__init__", counted)
    _opened = []
    try:
        code, text = _run(job, tmp_path / "out")
    finally:
        opened, _opened = _opened, None
    assert code == 0, text
    # every data file read is in the run's fingerprint (read once for its digest) and is
    # parsed once at most
    declared = set()
    for name in JOB_KINDS[case.kind].data_files:
        p = Path(_DATA) / name
        declared |= {f.name for f in p.rglob("*")} if p.is_dir() else {name}
    opens = Counter(opened)
    assert set(opens) <= declared, f"read but not fingerprinted: {set(opens) - declared}"
    assert all(n <= 2 for n in opens.values()), opens
    twice = {k[0]: n for k, n in builds.items() if n > 1}
    assert not twice, twice
