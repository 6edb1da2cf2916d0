"""A learning state (``ilc_state.npz``) is read through its schema (issue 44, cause A).

Each damaged state is refused by ``microfab ilc step`` with one ``error:`` line, exit 2,
before ``next.csv`` is written and with every file left as it was.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.trace import write_columns
from microfab.machines.galvo.machine import galvo_twin
from microfab.trajectory.periodic import square_scan

runner = CliRunner()


def _trial(path: Path, seed: int) -> None:
    ref = square_scan(400, (1.0, 1.44), 1e6)
    y = galvo_twin(seed=seed).run(ref).output
    cols = {"time": np.arange(ref.shape[0]) * 1e-6}
    for i, a in enumerate(("x", "y")):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": ref[:, i], f"output_{a}": y[:, i]}
    write_columns(path, cols)


@pytest.fixture(scope="module")
def learned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a state after one step and a second trial (another noise seed)."""
    d = tmp_path_factory.mktemp("ilc")
    _trial(d / "t1.csv", 3)
    _trial(d / "t2.csv", 4)
    res = runner.invoke(
        app, ["ilc", "step", str(d / "t1.csv"), "--state", str(d / "s"), "--out", str(d / "n.csv")]
    )
    assert res.exit_code == 0, res.output
    (d / "n.csv").unlink()
    return d


def _members(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _half(a: np.ndarray) -> np.ndarray:
    return a[: a.shape[0] // 2]


def _meta(change: Callable[[dict], None]) -> Callable[[dict[str, np.ndarray]], None]:
    def apply(m: dict[str, np.ndarray]) -> None:
        doc = json.loads(str(m["meta"]))
        change(doc)
        m["meta"] = np.array(json.dumps(doc))

    return apply


CASES: dict[str, tuple[Callable[[dict[str, np.ndarray]], None], str]] = {
    "reference of the wrong shape": (
        lambda m: m.__setitem__("reference", m["reference"][:, :1]),
        "reference must have shape",
    ),
    "a scalar where an array belongs": (
        lambda m: m.__setitem__("pinv", np.array(1.0 + 0j)),
        "pinv must have shape",
    ),
    "inputs as a scalar": (lambda m: m.__setitem__("inputs", np.array(0.0)), "inputs must"),
    "NaN inputs": (
        lambda m: m.__setitem__("inputs", np.full_like(m["inputs"], np.nan)),
        "inputs holds nan",
    ),
    "half-length reference": (
        lambda m: m.__setitem__("reference", _half(m["reference"])),
        "inputs must have shape",
    ),
    "half-length arrays": (
        lambda m: m.update({k: _half(m[k]) for k in ("reference", "inputs", "best_input")}),
        "must have shape",
    ),
    "gain above 2": (lambda m: m.__setitem__("gain", m["gain"] * 10), "gain must lie in"),
    "mask of reals": (lambda m: m.__setitem__("mask", m["mask"].astype(float)), "mask must hold"),
    "rms of the wrong length": (
        lambda m: m.__setitem__("rms", np.zeros((3, 2))),
        "rms must have shape",
    ),
    "a record signal as a scalar": (
        lambda m: m.__setitem__("meta_array_0", np.array(1.0)),
        "first_output must have shape",
    ),
    "dt a string": (_meta(lambda d: d.__setitem__("dt", "1e-6")), "dt must be"),
    "iteration a float": (_meta(lambda d: d.__setitem__("iteration", 1.5)), "iteration must"),
    "axes not names": (_meta(lambda d: d.__setitem__("axes", [1, 2])), "axes must"),
    "config unknown key": (
        _meta(lambda d: d["config"].__setitem__("bogus", 1)),
        "saved ILC settings are not valid",
    ),
    "config gain a string": (
        _meta(lambda d: d["config"].__setitem__("gain", "big")),
        "saved ILC settings are not valid",
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_a_damaged_state_is_refused_before_anything_is_written(
    learned: Path, tmp_path: Path, name: str
) -> None:
    change, says = CASES[name]
    (tmp_path / "s").mkdir()
    m = _members(learned / "s" / "ilc_state.npz")
    change(m)
    np.savez(tmp_path / "s" / "ilc_state.npz", **m)
    trial = tmp_path / "t2.csv"
    trial.write_bytes((learned / "t2.csv").read_bytes())
    before = _snapshot(tmp_path)
    res = runner.invoke(
        app,
        [
            "ilc",
            "step",
            str(trial),
            "--state",
            str(tmp_path / "s"),
            "--out",
            str(tmp_path / "n.csv"),
        ],
    )
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert says in res.output, res.output
    assert _snapshot(tmp_path) == before and not (tmp_path / "n.csv").exists()


def test_a_file_of_another_kind_is_named(learned: Path, tmp_path: Path) -> None:
    (tmp_path / "s").mkdir()
    runs = {"format": 1, "runs": [], "total_samples": 0, "total_s": 0}
    (tmp_path / "s" / "ilc_state.npz").write_text(json.dumps(runs))
    res = runner.invoke(
        app,
        ["ilc", "step", str(learned / "t2.csv"), "--state", str(tmp_path / "s"),
         "--out", str(tmp_path / "n.csv")],
    )  # fmt: skip
    assert res.exit_code == 2, res.output
    assert "this is a stage run list (runs.json of stage excite), not a ILC state" in res.output


def test_an_intact_state_still_learns(learned: Path, tmp_path: Path) -> None:
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "ilc_state.npz").write_bytes((learned / "s" / "ilc_state.npz").read_bytes())
    res = runner.invoke(
        app,
        ["ilc", "step", str(learned / "t2.csv"), "--state", str(tmp_path / "s"),
         "--out", str(tmp_path / "n.csv")],
    )  # fmt: skip
    assert res.exit_code == 0 and "iteration 2" in res.output, res.output
