"""`microfab.cli._options`: every number a command takes declares its unit and range."""

from __future__ import annotations

import typing
from typing import Annotated, Any

import pytest
import typer
import typer.main
from typer.testing import CliRunner

from microfab.cli import app
from microfab.cli._kit import OneLineErrors
from microfab.cli._options import (
    choice,
    declared,
    integer,
    number,
    refuse_unused,
    repeated_option,
)
from microfab.io.job import Key

runner = CliRunner()


def _leaves() -> dict[str, Any]:
    out: dict[str, Any] = {}

    def walk(c: Any, words: list[str]) -> None:
        if hasattr(c, "commands"):
            for name, sub in c.commands.items():
                walk(sub, [*words, name])
        else:
            out[" ".join(words)] = c

    walk(typer.main.get_command(app), [])
    return out


def _base(annotation: Any) -> Any:
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    return args[0] if args and typing.get_origin(annotation) is not Annotated else annotation


def test_every_number_of_every_command_declares_its_range() -> None:
    bare = []
    for name, cmd in _leaves().items():
        for p in cmd.params:
            if _base(p.type_descriptor.annotation) in (int, float) and declared(p) is None:
                bare.append(f"{name} {p.opts[0] if p.opts else p.name}")
    assert not bare, f"numbers without a declared unit and range (cli._options): {bare}"


def test_declared_ranges_are_ranges() -> None:
    for name, cmd in _leaves().items():
        for p in cmd.params:
            key = declared(p)
            if key is None or key.choices is not None:
                continue
            assert key.low is not None or key.high is not None, (name, p.opts)
            if key.low is not None and key.high is not None:
                assert key.low < key.high, (name, p.opts, key.range_text())
            default = p.default
            if isinstance(default, int | float) and not isinstance(default, bool):
                assert not key.outside(default), (name, p.opts, default, key.range_text())


# ------------------------------------------------------------------ a command of its own
demo = typer.Typer(cls=OneLineErrors)


@demo.command("a")
def _a(
    ctx: typer.Context,
    speed: Annotated[
        float, number(help="Speed.", unit="m/s", low=0.0, low_open=True, high=10.0)
    ] = 1.0,
    count: Annotated[int, integer(help="Count.", low=1, high=5)] = 2,
    shared: Annotated[
        float | None,
        number(key=Key(name="total_s", type="float", default=5.0, low=1.0, unit="s")),
    ] = None,
    mode: Annotated[str, typer.Option()] = "on",
    extra: Annotated[list[str] | None, typer.Option()] = None,
) -> None:
    if mode == "off":
        refuse_unused(ctx, ["count"], "with --mode off")
    print(f"ok {speed} {count} {shared} {extra}")


@demo.command("b")
def _b() -> None:
    print("b")


def _run(*argv: str) -> Any:
    return runner.invoke(demo, list(argv))


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--speed", "0"], "0 m/s is outside the allowed range (0, 10] m/s"),
        (["--speed", "10.5"], "outside the allowed range (0, 10] m/s"),
        (["--speed", "nan"], "nan is not a finite number"),
        (["--speed", "-inf"], "-inf is not a finite number"),
        (["--count", "0"], "0 is outside the allowed range [1, 5]"),
        (["--count", "2.5"], "--count"),
        (["--shared", "0.5"], "0.5 s is outside the allowed range [1, inf) s"),
        (["--speed", "1", "--speed", "2"], "--speed given twice"),
        (["--mode", "off", "--count", "2"], "--count has no effect with --mode off"),
    ],
)
def test_refusals_are_one_line(argv: list[str], says: str, one_error_line: Any) -> None:
    one_error_line(_run("a", *argv), says)


def test_values_inside_pass_and_repeatable_options_repeat() -> None:
    res = _run("a", "--speed", "10", "--count", "5", "--shared", "1", "--extra", "x",
               "--extra", "y")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "ok 10.0 5 1.0 ['x', 'y']" in res.output


def test_the_range_is_in_the_help() -> None:
    res = _run("a", "--help")
    assert "Range (0, 10] m/s" in " ".join(res.output.split())


def test_repeated_option_reads_values_and_the_end_of_options() -> None:
    root = typer.main.get_command(demo)
    assert repeated_option(root, ["a", "--speed", "--speed"]) is None  # a value
    assert repeated_option(root, ["a", "--speed=1", "--speed", "2"]) is not None
    assert repeated_option(root, ["a", "--", "--speed", "--speed"]) is None
    assert repeated_option(root, ["b"]) is None
    assert repeated_option(root, ["nope", "--x", "--x"]) is None


def test_a_repeated_option_of_a_real_command_is_refused(one_error_line: Any) -> None:
    res = runner.invoke(app, ["trajectory", "x.dxf", "--speed", "0.1", "--speed", "0.2"])
    one_error_line(res, "--speed given twice; give it once (see 'microfab trajectory --help')")


# ------------------------------------------------------------------ modes: choice options
def _library_choices(name: str) -> tuple[str, ...]:
    """The constant each named option's choices come from (imported here, not in the CLI)."""
    if name == "law":
        from microfab.control.ilc import Law

        return typing.get_args(Law)
    if name == "format":
        from microfab.cli.optimize import _FORMATS

        return _FORMATS
    if name == "units":
        from microfab.geometry.dxf import UNITS_M

        return tuple(UNITS_M)
    if name == "model":
        from microfab.process.inkjet.droplet import JET_MODELS

        return JET_MODELS
    if name == "weighting":
        from microfab.identify.subspace import WEIGHTINGS

        return WEIGHTINGS
    if name == "features":
        from microfab.identify.ann_data import FEATURES

        return FEATURES
    if name == "shaper kind":
        from microfab.control.shapers import SHAPER_NAMES

        return ("inverse", *SHAPER_NAMES)
    if name == "shaper":
        from microfab.process.slm.build import Shaper

        return typing.get_args(Shaper)
    assert name == "stage kind"
    from microfab.cli.stage import _KINDS

    return _KINDS


#: One choice option per command group: (command, option, constant, the rest of a command
#: line that parses up to the option).
_CHOICES = [
    ("ilc step", "--law", "law", ["t.csv", "--state", "s", "--out", "o.csv"]),
    ("optimize", "--format", "format", ["circle", "--out", "o"]),
    ("trajectory", "--units", "units", ["part.dxf"]),
    ("droplet simulate", "--model", "model", []),
    ("identify linear", "--weighting", "weighting", ["r.csv", "--out", "m.json"]),
    ("identify ann", "--features", "features", ["r.csv", "--out", "m"]),
    ("shaper design", "--kind", "shaper kind", ["--out", "s.json"]),
    ("slm build", "--shaper", "shaper", []),
    ("stage excite", "--kind", "stage kind", ["--out", "o"]),
]


@pytest.mark.parametrize(("command", "option", "constant", "rest"), _CHOICES)
def test_modes_are_declared_choices_of_the_library_constant(
    command: str, option: str, constant: str, rest: list[str], one_error_line: Any, tmp_path: Any
) -> None:
    param = next(p for p in _leaves()[command].params if option in p.opts)
    key = declared(param)
    assert key is not None and key.choices == _library_choices(constant)
    assert param.default is None or param.default in key.choices
    argv = [*command.split(), *(str(tmp_path / r) if "." in r else r for r in rest)]
    res = runner.invoke(app, [*argv, option, "nope"])
    shown = ", ".join(key.choices)
    one_error_line(res, f"Invalid value for '{option}': 'nope' is not one of {shown} (see ")
    assert res.output.rstrip().endswith(f" {command} --help')"), res.output
    assert list(tmp_path.iterdir()) == []  # refused while parsed: nothing written
    res = runner.invoke(app, [*command.split(), "--help"])  # lazy choices: in the help too
    assert f"One of: {shown}" in " ".join(res.output.split()), command


def test_every_default_of_a_choice_is_one_of_its_choices() -> None:
    for name, cmd in _leaves().items():
        for p in cmd.params:
            key = declared(p)
            if key is not None and key.choices is not None and p.default is not None:
                assert p.default in key.choices, (name, p.opts, p.default)


modes = typer.Typer(cls=OneLineErrors)


@modes.command("m")
def _m(
    law: Annotated[str, choice(choices=("inverse", "p-type"), help="Law.")] = "inverse",
    units: Annotated[
        str | None, choice(choices=lambda: {"mm": 1e-3, "um": 1e-6}, case_sensitive=False)
    ] = None,
) -> None:
    print(f"ok {law} {units}")


@modes.command("n")
def _n() -> None:
    print("n")


def test_a_case_insensitive_choice_passes_on_the_choice_it_names(one_error_line: Any) -> None:
    res = runner.invoke(modes, ["m", "--units", " MM "])
    assert res.exit_code == 0 and "ok inverse mm" in res.output, res.output
    res = runner.invoke(modes, ["m", "--law", "Inverse"])  # case-sensitive: refused
    one_error_line(res, "Invalid value for '--law': 'Inverse' is not one of inverse, p-type")
    one_error_line(runner.invoke(modes, ["m", "--units", "ft"]), "'ft' is not one of mm, um")


def test_lazy_choices_are_listed_in_the_help_of_the_command_run() -> None:
    res = runner.invoke(modes, ["m", "--help"])
    text = " ".join(res.output.split())
    assert "Law. One of: inverse, p-type." in text
    assert "One of: mm, um (any case)." in text
