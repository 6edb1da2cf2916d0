"""Console helpers: every refusal, a usage error included, is one ``error:`` line."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli._kit import one_line

runner = CliRunner()


def _single_error_line(output: str) -> str:
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert len(lines) == 1, output
    assert lines[0].startswith("error: "), output
    return lines[0]


def test_one_line_collapses_breaks_and_escapes_control_characters() -> None:
    assert one_line('Invalid group code "x\n" at line 3.') == 'Invalid group code "x " at line 3.'
    assert one_line("a\r\n  b\u2028c\x0bd") == "a b c d"
    assert one_line("bell\x07 and \x1b[31mred") == "bell\\x07 and \\x1b[31mred"
    assert one_line("µm, é, 😀") == "µm, é, 😀"


@pytest.mark.parametrize(
    "argv, says",
    [
        (["droplet", "simulate", "--duration", "abc"], "Invalid value for '--duration'"),
        (["droplet", "sweep", "--jobs", "0"], "'--jobs' / '--workers'"),
        (["kinds", "--bogus"], "No such option: --bogus"),
        (["bogus"], "No such command 'bogus'"),
        (["path", "show"], "Missing argument"),
        (["trajectory", "spiral", "--time-optimal", "--n-grid", "5"], "'--n-grid'"),
    ],
)
def test_usage_errors_are_one_line_with_exit_code_2(argv: list[str], says: str) -> None:
    # click printed a usage line, a hint and a boxed message
    res = runner.invoke(app, argv)
    assert res.exit_code == 2
    line = _single_error_line(res.output)
    assert says in line and "--help" in line


def test_help_and_no_arguments_still_show_the_help() -> None:
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0 and "Usage" in res.output
    res = runner.invoke(app, ["path"])
    assert "show" in res.output and "error:" not in res.output


def test_an_output_is_checked_before_any_work(tmp_path, capsys) -> None:
    import typer

    from microfab.cli._kit import check_output_path

    (tmp_path / "d").mkdir()
    (tmp_path / "f").write_text("measured")
    refused = [
        (("--json", tmp_path / "d"), {}, "is a folder; give a file name"),
        (("--out", tmp_path / "f"), {"kind": "folder"}, "is a file; give a folder"),
        (("--json", tmp_path / "f" / "x.json"), {}, "is a file, not a folder"),
        (("--json", tmp_path / "f"), {"inputs": [tmp_path / "f"]}, "is also an input"),
    ]
    for args, kw, says in refused:
        with pytest.raises(typer.Exit):
            check_output_path(*args, **kw)
        assert says in capsys.readouterr().err.replace("\n", " ")
    check_output_path("--json", tmp_path / "new.json")  # a new file in an existing folder
    check_output_path("--json", tmp_path / "new" / "sub" / "x.json")  # folders to create
    check_output_path("--out", tmp_path / "d", kind="folder")  # a folder to resume in
    check_output_path("--json", None)
    assert (tmp_path / "f").read_text() == "measured"


@pytest.mark.parametrize(
    ("argv", "target", "says"),
    [
        (["path", "show", "circle:radius=1e-3"], "microfab.cli.geometry._load",
         "no file is left half-written"),
        (["run", "examples/galvo_msl_default.toml"], "microfab.experiments.catalog.load_job",
         "rerun the same command to resume"),
    ],
)  # fmt: skip
def test_ctrl_c_is_one_line_and_exit_130(monkeypatch, argv, target, says) -> None:
    """Issue 32 class 9: Ctrl-C exits 130 with one line saying what to do."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    import signal

    monkeypatch.setattr(target, interrupted)
    before = signal.getsignal(signal.SIGINT)
    try:
        res = CliRunner().invoke(app, argv)
        # once shutting down, a second SIGINT is ignored, by a Python handler (not SIG_IGN,
        # which processes started afterwards would inherit)
        assert signal.getsignal(signal.SIGINT) not in (before, signal.SIG_IGN, signal.SIG_DFL)
    finally:
        signal.signal(signal.SIGINT, before)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 130, res.output
    assert len(lines) == 1 and lines[0].startswith("interrupted; "), res.output
    assert says in lines[0]
