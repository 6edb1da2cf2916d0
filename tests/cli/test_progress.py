"""Progress bars end at their total on success and are cleared on failure."""

from __future__ import annotations

import io

import pytest
from rich.console import Console
from rich.progress import MofNCompleteColumn, TextColumn

from microfab.cli._kit import _Bars, progress, reporter


def _bars() -> tuple[_Bars, io.StringIO]:
    out = io.StringIO()
    console = Console(file=out, force_terminal=False, width=120)
    return _Bars(TextColumn("{task.description}"), MofNCompleteColumn(), console=console), out


def test_a_bar_left_short_of_its_total_ends_full_on_success() -> None:
    bars, out = _bars()
    with bars:
        report = reporter(bars)
        report("points", 8, 9)
        report("unknown total", 250, None)
    text = out.getvalue()
    assert "9/9" in text and "8/9" not in text
    assert "250/250" in text and "?" not in text


@pytest.mark.parametrize("error", [RuntimeError("refused"), KeyboardInterrupt()])
def test_bars_are_cleared_when_the_work_fails(error: BaseException) -> None:
    bars, out = _bars()
    with pytest.raises(type(error)), bars:
        reporter(bars)("points", 3, 9)
        raise error
    assert out.getvalue() == ""


def test_the_cli_progress_is_such_a_bar() -> None:
    assert isinstance(progress(), _Bars)
