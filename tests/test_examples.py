import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).parent.parent / "examples").glob("[0-9][0-9]_*.py"))
# quick arguments per example, and what its output must contain
QUICK = {
    "01_galvo_ilc.py": (["3"], ["iteration  3"], "example_01_xy.png"),
    "02_letters_time_optimal.py": (["150"], ["text:r", "airfoil:e344"], "example_02_profile.png"),
    "03_droplet_breakup.py": (
        ["0.15"],
        ["breakup", "measured from frames"],
        "example_03_frames.png",
    ),
}


def test_examples_exist():
    assert EXAMPLES
    assert {e.name for e in EXAMPLES} == set(QUICK)


@pytest.mark.parametrize("ex", EXAMPLES, ids=[e.name for e in EXAMPLES])
def test_examples_run_headless(ex, tmp_path, monkeypatch, capsys):
    args, expected, png_name = QUICK[ex.name]
    monkeypatch.setattr(sys, "argv", [str(ex), *args, str(tmp_path)])
    runpy.run_path(str(ex), run_name="__main__")
    out = capsys.readouterr().out
    for text in expected:
        assert text in out
    assert (tmp_path / png_name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
