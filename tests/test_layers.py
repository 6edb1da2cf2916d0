"""The import contracts of docs/architecture.md (layers, reports apart from jobs, seed
packages independent, no cycles), checked by import-linter."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_layer_contract_is_kept():
    exe = Path(sys.executable).with_name("lint-imports")
    cmd = str(exe) if exe.exists() else shutil.which("lint-imports")
    if cmd is None:
        pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
    res = subprocess.run(
        [cmd, "--config", str(ROOT / "pyproject.toml"), "--no-cache"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]
    assert ", 0 broken" in res.stdout
    for name in ("microfab layers", "reports do not import jobs", "seed packages are independent",
                 "no import cycles"):  # fmt: skip
        assert f"{name} KEPT" in res.stdout, name
