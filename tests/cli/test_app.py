"""The top-level command: --version, and help that reads well when piped."""

from __future__ import annotations

from importlib.metadata import version

import pytest
from typer.testing import CliRunner

from microfab.cli import app

runner = CliRunner()
GROUPS = ("run", "kinds", "reproduce", "trajectory", "ilc", "calibrate", "path", "droplet")


def test_version() -> None:
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.strip() == f"microfab {version('microfab')}"


@pytest.mark.parametrize(
    "args",
    [["--help"], ["droplet", "--help"], ["ilc", "step", "--help"], ["run", "--help"]],
)
def test_piped_help_is_plain_and_unwrapped(args: list[str]) -> None:
    res = runner.invoke(app, args)  # CliRunner's output is not a terminal
    assert res.exit_code == 0, res.output
    out = res.output
    assert "``" not in out and "╭" not in out and "│" not in out
    if args == ["--help"]:
        rows = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith("  ") and ln.split()}
        for group in GROUPS:
            assert group in rows, out
        assert rows["droplet"].rstrip().endswith("analyse camera frames."), out
