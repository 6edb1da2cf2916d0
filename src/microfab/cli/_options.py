"""One schema for command-line options: type, unit and range declared with the option.

Every number a ``microfab`` command takes is declared with `number` (a float) or
`integer` (an int) instead of a bare ``typer.Option``: the declaration is a job-file
`microfab.io.job.Key` (type, unit, inclusive or open range), checked while the command
line is parsed, before the command reads or writes anything, and refused on one line
like a job-file value::

    error: Invalid value for '--rate': 1 Hz is outside the allowed range [100, 1e+08] Hz
    (see 'microfab trajectory --help')

An option that sets what a job-file key sets shares that key's declaration
(``number("--duration", key=EXCITE_TOTAL_S)``), so the two cannot drift apart. The range
is added to the option's help. `declared` returns the `Key` of a parsed option; the test
suite walks every command and fails on a number without one, and the fuzz cases are made
from the declarations (values just outside each bound, non-finite, of the wrong type).

Rules that tie options to each other or to the chosen mode live in the command, through
`given` (did the user type the option?) and `refuse_unused` (an option that has no
effect in the chosen mode is refused, never silently ignored). `repeated_option` finds an
option given twice on one command line, which the group refuses: click would keep the
last one silently.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, Literal, get_args, get_origin

import typer

from microfab.io.job import Key, KeyType

__all__ = [
    "USAGE_ERROR",
    "choice",
    "declared",
    "given",
    "integer",
    "number",
    "refuse_unused",
    "repeated_option",
    "resolve_choice_help",
]

#: Attribute of an option's callback holding its declaration.
_KEY_ATTR = "microfab_key"


def _shown(value: float, unit: str) -> str:
    text = f"{value:g}" if isinstance(value, float) else str(value)
    return f"{text} {unit}" if unit else text


def _declare(
    decls: Sequence[str],
    kind: KeyType,
    help: str,
    unit: str,
    low: float | None,
    high: float | None,
    low_open: bool,
    high_open: bool,
    key: Key | None,
    option: Mapping[str, Any],
) -> Any:
    if key is None:
        key = Key(
            name=decls[0] if decls else "",
            type=kind,
            default=None,
            low=low,
            high=high,
            unit=unit,
            help=help,
            low_open=low_open,
            high_open=high_open,
        )
    elif kind == "int" and key.type != "int":
        raise TypeError(f"integer option from the {key.type} key {key.name!r}")
    text = help or key.help

    def check(ctx: typer.Context, param: typer.CallbackParam, value: Any) -> Any:
        if value is None or ctx.resilient_parsing:
            return value
        if isinstance(value, float) and not math.isfinite(value):
            raise typer.BadParameter(f"{value} is not a finite number; allowed: {key.range_text()}")
        if key.outside(value):
            raise typer.BadParameter(
                f"{_shown(value, key.unit)} is outside the allowed range {key.range_text()}"
            )
        return value

    setattr(check, _KEY_ATTR, key)
    return typer.Option(*decls, help=f"{text} Range {key.range_text()}.", callback=check, **option)


def number(
    *decls: str,
    help: str = "",
    unit: str = "",
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    key: Key | None = None,
    **option: Any,
) -> Any:
    """A float option with its unit and range (a ``typer.Option`` for ``Annotated``).

    Parameters
    ----------
    *decls : str
        Option names, as for ``typer.Option`` (none: from the parameter's name).
    help : str
        One line of help; the range is appended (default: the key's help).
    unit : str
        The unit of the value, as messages show it (``"m/s"``, ``"µs"``).
    low, high : float, optional
        Bounds (``None``: none); inclusive unless ``low_open`` / ``high_open``.
    low_open, high_open : bool
        Exclude the bound itself (a speed is more than 0).
    key : Key, optional
        The job-file key this option sets: its unit and range are the option's (``unit``,
        ``low``, ``high`` are then ignored).
    **option
        Passed to ``typer.Option`` (``show_default``, ``rich_help_panel``...).

    Notes
    -----
    NaN and infinity are always refused.
    """
    return _declare(decls, "float", help, unit, low, high, low_open, high_open, key, option)


def integer(
    *decls: str,
    help: str = "",
    unit: str = "",
    low: int | None = None,
    high: int | None = None,
    key: Key | None = None,
    **option: Any,
) -> Any:
    """An int option with its unit and inclusive range (see `number`)."""
    return _declare(decls, "int", help, unit, low, high, False, False, key, option)


Choices = Sequence[str] | Mapping[str, Any] | Callable[[], Any]


def _is_lazy(source: Choices) -> bool:
    """Whether ``source`` is a function giving the choices (not the choices themselves)."""
    return (
        callable(source)
        and get_origin(source) is not Literal
        and not isinstance(source, (Mapping, Sequence))
    )


def _choice_tuple(source: Choices) -> tuple[str, ...]:
    """The choices ``source`` names: a sequence, a mapping's keys, a ``Literal``'s values."""
    value: Any = source() if _is_lazy(source) else source  # type: ignore[operator]
    if get_origin(value) is Literal:
        value = get_args(value)
    return tuple(str(v) for v in value)


class _Choice:
    """A `choice` declaration: its `Key`, made on first use (the choices may be lazy)."""

    def __init__(self, name: str, source: Choices, help: str, case_sensitive: bool) -> None:
        self.name, self.source, self.help = name, source, help
        self.case_sensitive = case_sensitive
        self._key: Key | None = None

    @property
    def key(self) -> Key:
        if self._key is None:
            self._key = Key(name=self.name, type="str", default=None, help=self.help,
                            choices=_choice_tuple(self.source))  # fmt: skip
        return self._key

    def help_text(self) -> str:
        """The option's help with its choices (``, any case`` when case-insensitive)."""
        case = "" if self.case_sensitive else " (any case)"
        return f"{self.help} One of: {', '.join(self.key.choices or ())}{case}."

    def match(self, value: str) -> str | None:
        """The choice ``value`` names (``None``: none)."""
        choices = self.key.choices or ()
        if self.case_sensitive:
            return value if value in choices else None
        folded = {c.lower(): c for c in choices}
        return folded.get(value.strip().lower())


def choice(
    *decls: str,
    choices: Choices,
    help: str = "",
    case_sensitive: bool = True,
    **option: Any,
) -> Any:
    """A text option that takes one of ``choices`` (a mode), checked while parsing.

    The choices are listed in the help and in the refusal, and are what the fuzz cases
    of the mode-versus-option matrix switch between (`declared`).

    Parameters
    ----------
    *decls : str
        Option names, as for ``typer.Option``.
    choices : sequence of str, mapping, or callable
        The constant the command or library uses: a sequence, a mapping (its keys), a
        ``typing.Literal`` or a function of no argument returning one of these. A function
        is called on first use (parsing, ``--help``, `declared`), so a constant that lives
        in a module heavy to import (SciPy, PyTorch) is not imported by ``microfab``'s
        start-up: the ``microfab`` group adds such choices to the help of the command it
        runs (`resolve_choice_help`).
    help : str
        One line of help; the choices are appended.
    case_sensitive : bool
        ``False``: a value in any case, with spaces around it, is accepted and passed on
        as the choice it names (``--units MM`` is ``mm``).
    **option
        Passed to ``typer.Option``.
    """
    decl = _Choice(decls[0] if decls else "", choices, help, case_sensitive)

    def check(ctx: typer.Context, param: typer.CallbackParam, value: Any) -> Any:
        if value is None or ctx.resilient_parsing:
            return value
        found = decl.match(str(value))
        if found is not None:
            return found
        shown = ", ".join(decl.key.choices or ())
        raise typer.BadParameter(f"{value!r} is not one of {shown}")

    setattr(check, _KEY_ATTR, decl)
    text = help if _is_lazy(choices) else decl.help_text()
    return typer.Option(*decls, help=text, callback=check, **option)


def resolve_choice_help(root: Any, args: Sequence[str]) -> None:
    """List the lazy choices of the command ``args`` name in its help (see `choice`).

    Parameters
    ----------
    root : click.Group
        The ``microfab`` command.
    args : sequence of str
        The command line after the program's name.
    """
    cmd, _, _ = _leaf(root, args)
    for param in getattr(cmd, "params", []):
        decl = getattr(getattr(param, "callback", None), _KEY_ATTR, None)
        if isinstance(decl, _Choice) and not getattr(param, "_microfab_choices_shown", False):
            param.help = decl.help_text()
            param._microfab_choices_shown = True


def declared(param: Any) -> Key | None:
    """The declaration of a parsed command's parameter (``None``: declared without one)."""
    decl = getattr(getattr(param, "callback", None), _KEY_ATTR, None)
    return decl.key if isinstance(decl, _Choice) else decl


def given(ctx: typer.Context, name: str) -> bool:
    """Whether the user gave the parameter ``name`` (its Python name), not its default."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name in ("COMMANDLINE", "ENVIRONMENT", "PROMPT")


def _flag(ctx: typer.Context, name: str) -> str:
    """The option ``name`` as the user spelt it (``--no-x`` for a flag turned off)."""
    for param in ctx.command.params:
        if param.name == name and param.opts:
            off = getattr(param, "secondary_opts", None)
            if getattr(param, "is_flag", False) and off and ctx.params.get(name) is False:
                return str(off[0])
            return str(param.opts[0])
    return "--" + name.replace("_", "-")


#: click's usage error (typer may vendor click): one ``error:`` line from the group (an
#: option without effect here, an option given twice in `microfab.cli._kit`).
USAGE_ERROR: type[Exception] = next(
    c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError"
)


def refuse_unused(ctx: typer.Context, names: Iterable[str], why: str) -> None:
    """Refuse options that have no effect in the mode the command line chose.

    Parameters
    ----------
    ctx : typer.Context
        The command's context.
    names : iterable of str
        Python names of the options that the chosen mode does not use.
    why : str
        The mode, completing "``--x`` has no effect ...": ``"with --law inverse"``.

    Raises
    ------
    click.UsageError
        Naming the first such option the user gave; the ``microfab`` group prints it
        on one ``error:`` line and exits with code 2.
    """
    for name in names:
        if given(ctx, name):
            raise USAGE_ERROR(f"{_flag(ctx, name)} has no effect {why}; leave it out", ctx)


def _leaf(root: Any, args: Sequence[str]) -> tuple[Any, list[str], list[str]]:
    """The command ``args`` name under ``root``, its path, and the words after its name."""
    cmd: Any = root
    rest = list(args)
    path: list[str] = []
    while hasattr(cmd, "commands"):
        words = [i for i, a in enumerate(rest) if not a.startswith("-")]
        if not words:
            return None, path, []
        i = words[0]
        sub = cmd.commands.get(rest[i])
        if sub is None:
            return None, path, []
        path.append(rest[i])
        cmd, rest = sub, rest[i + 1 :]
    return cmd, path, rest


def repeated_option(root: Any, args: Sequence[str]) -> str | None:
    """The refusal of an option given twice on the command line ``args`` (``None``: none).

    An option declared repeatable (``list[...]``, a counter) may come more than once;
    any other one given twice is ambiguous (click keeps the last), and the group refuses
    the command line. The words after ``--`` are arguments.

    Parameters
    ----------
    root : click.Group
        The ``microfab`` command.
    args : sequence of str
        The command line after the program's name.
    """
    cmd, path, rest = _leaf(root, args)
    if cmd is None:
        return None
    by_opt: dict[str, Any] = {}
    for param in getattr(cmd, "params", []):
        for opt in [*getattr(param, "opts", []), *getattr(param, "secondary_opts", [])]:
            if opt.startswith("-"):
                by_opt[opt] = param
    seen: dict[str, str] = {}
    i = 0
    while i < len(rest):
        word = rest[i]
        i += 1
        if word == "--":
            break
        name, eq, _ = word.partition("=")
        param = by_opt.get(name)
        if param is None:
            continue
        takes_value = not getattr(param, "is_flag", False) and not getattr(param, "count", False)
        if takes_value and not eq:
            i += 1  # its value, whatever it looks like
        if getattr(param, "multiple", False) or getattr(param, "count", False):
            continue
        if param.name in seen:
            first = seen[param.name]
            twice = name if first == name else f"{first} / {name}"
            where = " ".join(["microfab", *path])
            return f"{twice} given twice; give it once (see '{where} --help')"
        seen[param.name] = name
    return None
