import runpy
import sys
from pathlib import Path

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("[0-9][0-9]_*.py"))


def test_examples_exist():
    assert EXAMPLES


def test_examples_run_headless(tmp_path, monkeypatch, capsys):
    for ex in EXAMPLES:
        monkeypatch.setattr(sys, "argv", [str(ex), "3", str(tmp_path)])
        runpy.run_path(str(ex), run_name="__main__")
    out = capsys.readouterr().out
    assert "iteration  3" in out
    png = tmp_path / "example_01_xy.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
