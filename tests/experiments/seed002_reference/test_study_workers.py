"""The reference study's points on worker processes: the same numbers, saved, resumed."""

from __future__ import annotations

import math
from typing import Any

import pytest

pytest.importorskip("casadi")
pytest.importorskip("torch")
pytest.importorskip("distributed")

from microfab.experiments.seed002_reference.study import ReferenceSettings, run_reference
from microfab.machines.xy_stage import reference as xy_stage_reference
from microfab.machines.xy_stage.cases import CaseSizes
from microfab.machines.xy_stage.machine import TwinSettings

#: Relative tolerance between a point run in this process and on a worker. Both run their
#: BLAS/OpenMP pools on one thread on the same machine; measured: identical to the last
#: bit (run on a 2-core SkylakeX, OpenBLAS 0.3.31). A few times 1e-12 leaves room for a
#: differently aligned buffer taking another kernel path, far below any printed digit.
RTOL = 1e-9


def _close(a: Any, b: Any, where: str = "") -> None:
    """``a`` and ``b`` equal as JSON trees, floats to `RTOL` (wall times excepted)."""
    if isinstance(a, dict):
        assert set(a) == set(b), where
        for k in a:
            if not k.startswith("wall"):  # seconds the point took, not its numbers
                _close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=RTOL, abs_tol=1e-15), (where, a, b)
    else:
        assert a == b, (where, a, b)


def _settings(models: str, workers: int) -> ReferenceSettings:
    return ReferenceSettings(models_dir=models, twin=TwinSettings(hold_s=0.51), cases=("r",),
                             a_max=(2.0, 3.0), airfoil_extra=(), tolerance_m=100e-6,
                             sizes=CaseSizes(5e-3, 20e-3), stage2_max_iter=3,
                             workers=workers)  # fmt: skip


def test_points_on_two_workers_match_this_process_and_resume(
    tiny_models, tmp_path, monkeypatch
) -> None:
    d, _ = tiny_models
    here = run_reference(_settings(str(d), 1), tmp_path / "one")
    there = run_reference(_settings(str(d), 2), tmp_path / "two")
    assert list(there.points) == list(here.points) == [("r", 2.0), ("r", 3.0)]
    for key in here.points:
        _close(here.points[key], there.points[key], str(key))
    saved = sorted(p.name for p in (tmp_path / "two" / "points").glob("*.json"))
    assert saved == ["r_a2.json", "r_a3.json"]

    def boom(*a: Any, **k: Any) -> None:
        raise AssertionError("a saved point was run again")

    monkeypatch.setattr(xy_stage_reference, "run_point", boom)
    again = run_reference(_settings(str(d), 2), tmp_path / "two")
    assert again.points == there.points  # read back from the files, nothing run
