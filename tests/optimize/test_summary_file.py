"""`microfab.optimize.summary_file`: optimize's summary.json read back through a schema."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from microfab.io.schema import SchemaError, describe_file
from microfab.optimize.summary_file import read_optimize_summary

GOOD: dict[str, Any] = {
    "drawing": "circle:radius=0.002",
    "contour": 0,
    "sizing": {"chord": 0.1, "text_height": 0.01, "units": None},
    "m": 120,
    "path_length_m": 0.0126,
    "drawing_sha256": None,
    "commands": {"optimised": {"file": "command.csv", "t0_sample": 12, "lead": 3}},
    "stage1": {"iterations": 40},
}


def _write(tmp_path: Path, doc: Any) -> Path:
    p = tmp_path / "summary.json"
    p.write_text(json.dumps(doc))
    return p


def test_a_summary_reads_with_its_other_keys_kept(tmp_path: Path) -> None:
    doc = read_optimize_summary(_write(tmp_path, GOOD))
    assert doc.m == 120 and doc.commands["optimised"].lead == 3
    assert doc.model_extra == {"stage1": {"iterations": 40}}
    assert "optimize summary" in (describe_file(tmp_path / "summary.json") or "")


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"m": 0}, "m = 0"),
        ({"m": 1.5}, "m = 1.5"),
        ({"contour": -1}, "contour = -1"),
        ({"path_length_m": "1"}, "path_length_m = '1'"),
        ({"sizing": {"chord": -1.0, "text_height": 0.01}}, "sizing.chord = -1"),
        ({"commands": {}}, "commands"),
        ({"commands": {"o": {"file": "../x.csv", "lead": 0}}}, "not a path"),
        ({"commands": {"o": {"file": "c.csv", "lead": 2**40}}}, "lead"),
        ({"drawing_sha256": "abc"}, "drawing_sha256"),
    ],
)
def test_a_bad_key_is_refused_on_one_line(tmp_path: Path, change: dict, says: str) -> None:
    with pytest.raises(SchemaError, match=None) as err:
        read_optimize_summary(_write(tmp_path, {**GOOD, **change}))
    msg = str(err.value)
    assert "\n" not in msg and says in msg and "summary.json" in msg, msg


def test_a_missing_key_and_another_kind_are_named(tmp_path: Path) -> None:
    doc = {k: v for k, v in GOOD.items() if k != "sizing"}
    with pytest.raises(SchemaError, match="sizing is missing"):
        read_optimize_summary(_write(tmp_path, doc))
    runs = {"runs": [], "total_samples": 0}
    with pytest.raises(SchemaError, match="stage run list"):
        read_optimize_summary(_write(tmp_path, runs))
