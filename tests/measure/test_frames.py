"""``frames.json`` is read through its schema (issue 44, cause A) by ``droplet analyze``."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.measure.frames import load_frames, read_sidecar
from microfab.measure.shadowgraph import Camera, write_frames

runner = CliRunner()
CAM = Camera(width_px=32, height_px=48)


def _folder(root: Path) -> Path:
    d = root / "frames"
    write_frames(np.full((3, 48, 32), 0.85), d, camera=CAM, frame_interval_s=5e-6)
    return d


def _edit(change: Callable[[dict], None]) -> Callable[[Path], None]:
    def apply(d: Path) -> None:
        meta = json.loads((d / "frames.json").read_text())
        change(meta)
        (d / "frames.json").write_text(json.dumps(meta))

    return apply


def _secret(d: Path) -> None:
    (d.parent / "secret.png").write_bytes((d / "frame_0000.png").read_bytes())
    _edit(lambda m: m["files"].__setitem__(0, "../secret.png"))(d)


CASES: dict[str, tuple[Callable[[Path], None], str]] = {
    "a frame outside the folder": (_secret, "'../secret.png' leaves the folder"),
    "an absolute frame path": (
        _edit(lambda m: m["files"].__setitem__(0, "/etc/hostname")),
        "leaves the folder",
    ),
    "a missing frame": (lambda d: (d / "frame_0001.png").unlink(), "'frame_0001.png' is missing"),
    "a bit depth of -1": (_edit(lambda m: m.__setitem__("bit_depth", -1)), "bit_depth = -1"),
    "a pixel size of 2 m": (
        _edit(lambda m: m.__setitem__("pixel_size_m", 2.0)),
        "pixel_size_m = 2.0 should be less than or equal to 0.0001",
    ),
    "n_frames against files": (
        _edit(lambda m: m.__setitem__("n_frames", 7)),
        "n_frames is 7 but files lists 3",
    ),
    "a frame interval of true": (
        _edit(lambda m: m.__setitem__("frame_interval_s", True)),
        "frame_interval_s = True is not a number",
    ),
    "deep nesting": (
        lambda d: (d / "frames.json").write_text('{"x": ' + "[" * 50_000 + "]" * 50_000 + "}"),
        "nested too deeply",
    ),
    "a stage run list in its place": (
        lambda d: (d / "frames.json").write_text(
            json.dumps({"format": 1, "runs": [], "total_samples": 0})
        ),
        "this is a stage run list",
    ),
}


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.parametrize("name", list(CASES))
def test_droplet_analyze_refuses_a_bad_frame_index(tmp_path: Path, name: str) -> None:
    change, says = CASES[name]
    d = _folder(tmp_path)
    change(d)
    before = _snapshot(tmp_path)
    res = runner.invoke(app, ["droplet", "analyze", str(d), "--json", str(tmp_path / "a.json")])
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert says in res.output, res.output
    assert _snapshot(tmp_path) == before


def test_the_listed_frames_are_read_in_their_order(tmp_path: Path) -> None:
    d = _folder(tmp_path)
    (d / "stray.png").write_bytes((d / "frame_0000.png").read_bytes())
    _edit(lambda m: m.__setitem__("files", m["files"][::-1]))(d)
    _, names = load_frames(d)
    assert names == ["frame_0002.png", "frame_0001.png", "frame_0000.png"]
    assert read_sidecar(d)["bit_depth"] == CAM.bit_depth
