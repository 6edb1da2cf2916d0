"""Cases for every option of every ``microfab`` command, enumerated from the CLI itself.

The other fuzz kinds mutate *inputs* (drawings, trials, job files). This module attacks
every parameter of every command, as the click tree of `microfab.cli.app` lists them, from
one valid cheap invocation per command (`fuzz_workspace.RECIPES`, run in a folder filled by
`fuzz_workspace.build_workspace`). Each case changes one parameter:

=============  ==========================================================================
kind           what one case does
=============  ==========================================================================
opt-number     an int or float option set to an extreme or broken magnitude (``nan``,
               ``inf``, ``1e308``, ``5e-324``, ``0``, ``-1``, ``2**63``, ``abc``...)
opt-text       a string option or argument set to an empty, numeric, malformed or huge
               text (ranges ``10:1``, ``nan:nan``, lists ``a,b``, a 10 000-character word)
opt-flag       a boolean flag turned the other way
out-path       an output that is one of the command's inputs (class 1: it must be refused
               and the input kept), an existing folder where a file goes or an existing
               file where a folder goes, a path under a file, a new nested folder
in-path        an input missing, empty, cut in half, junk bytes, a folder where a file is
               read (or the reverse), or another command's input of the wrong kind
state          a learning state or resume folder with every file emptied, cut or junk, or
               the folder replaced by a file
set            ``reproduce NAME --set key=value --check`` for every key of every
               reproduction, with values of the wrong type, out of range or malformed
special        a path the command reads or writes replaced by a FIFO or a symbolic link
               to itself (looked at, never opened: a FIFO would block)
opt-bound      a declared number (`microfab.cli._options`) just outside its range, or
               on an open bound: every one must be refused
mode           the mode-versus-option matrix: each mode of a command (a flag toggled,
               each choice of a declared choice option) with each option the recipe
               leaves out, at a value inside its declaration
=============  ==========================================================================

Every case also names the command's inputs in `Case.keep`: whatever the exit, an input
that changed is ``clobbered`` (an output that overwrote measured data).

`missing_generators` lists the parameters no class covers (a new command without a recipe,
a path option whose role is unknown): ``test_fuzz.py`` fails when it is not empty.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fuzz_driver
from fuzz_driver import Case
from fuzz_workspace import RECIPES, Recipe, build_workspace
from hypothesis import strategies as st

from microfab.cli._options import declared

__all__ = [
    "OPTION_KINDS",
    "Param",
    "cases_of",
    "commands",
    "missing_generators",
    "params",
]

fuzz_driver.FIXTURES["workspace"] = build_workspace

FLOAT_TEXT = (
    "nan", "-nan", "inf", "-inf", "1e308", "-1e308", "1e400", "1e-308", "5e-324", "0",
    "-0", "-1", "1e12", "-1e12", "1e-12", "abc", "", "1,5", "0x10",
)  # fmt: skip
INT_TEXT = (
    "0", "-1", "-2147483649", "2147483648", "9223372036854775808", "1" + "0" * 30, "1.5",
    "1e3", "nan", "abc", "",
)  # fmt: skip
TEXT = (
    "", " ", "nan", "inf", "-1", "0", "1e308", "abc", "a,b", ",", ":", "1:2:3", "10:1",
    "nan:nan", "0:1e308", "-5:-1", "=", "x=1e308", "1,nan,3", "1e308,1e308", "é",
    "W" * 10_000, "../../../x", "a\x00b", "text:\x00",
)  # fmt: skip
OUTPUT_DAMAGE = ("empty", "half", "junk", "file", "remove")
INPUT_DAMAGE = ("empty", "half", "junk", "remove")
SET_VALUES = {
    "float": ("nan", "inf", "-inf", "1e308", "-1e308", "5e-324", "-1", "0", '"1"', "true",
              "[1]", "abc"),
    "int": ("-1", "0", "1.5", "9223372036854775808", "1" + "0" * 30, "nan", '"1"', "true",
            "abc"),
    "bool": ("1", "0", '"true"', "maybe", "[true]"),
    "str": ('""', "1", "nan", "[1]", "1e308", "../../../x", "true", "/"),
    "list": ("[]", "[nan]", "[1e308]", "[-1]", "1", '["a"]', "[[1]]", "[0, -0.0]"),
}  # fmt: skip

#: Path parameters that the recipe does not give, with their role and a value to try
#: them with: ``("in", workspace path)`` or ``("out", kind)`` (``kind`` "file"/"folder").
EXTRA_PATHS: dict[tuple[str, str], tuple[str, str]] = {
    ("ilc step", "--frf"): ("in", "frf.csv"),
    ("shaper design", "--frf"): ("in", "frf.csv"),
    ("shaper design", "--psd"): ("in", "chirp.csv"),
    ("nanomanipulator analyze", "--job"): ("in", "nano_job.toml"),
    ("reproduce", "--out"): ("out", "reproduce_page"),
    ("calibrate laser", "--json"): ("out", "laser_cal.json"),
    ("calibrate laser", "--out"): ("out", "laser_cal_run"),
    ("calibrate nanomanipulator", "--json"): ("out", "nano_cal.json"),
    ("calibrate nanomanipulator", "--out"): ("out", "nano_cal_run"),
}


# ----------------------------------------------------------------------------- the CLI
@dataclass(frozen=True)
class Param:
    """One parameter of one command, as click lists it."""

    command: str
    name: str
    flags: tuple[str, ...]
    secondary: tuple[str, ...]
    annotation: Any
    is_flag: bool
    multiple: bool
    nargs: int
    key: Any = None  # the declaration (`microfab.cli._options.declared`), if any
    default: Any = None

    @property
    def argument(self) -> bool:
        """A positional argument (no option string)."""
        return not self.flags

    @property
    def label(self) -> str:
        """``--out`` or the argument's name."""
        return self.flags[0] if self.flags else self.name

    @property
    def base_type(self) -> str:
        """``int``, ``float``, ``bool``, ``path`` or ``str`` (of a list: its element)."""
        a = self.annotation
        args = getattr(a, "__args__", None)
        if args and getattr(a, "__origin__", None) in (list, tuple):
            a = args[0]
        if a is bool or self.is_flag:
            return "bool"
        if a is int:
            return "int"
        if a is float:
            return "float"
        if isinstance(a, type) and issubclass(a, Path):
            return "path"
        return "str"


@functools.cache
def commands() -> dict[str, Any]:
    """Every leaf command of ``microfab``: ``{"ilc step": click command}``."""
    out: dict[str, Any] = {}

    def walk(c: Any, words: list[str]) -> None:
        if hasattr(c, "commands"):
            for name, sub in sorted(c.commands.items()):
                walk(sub, [*words, name])
        else:
            out[" ".join(words)] = c

    walk(fuzz_driver._command(), [])
    return out


@functools.cache
def params(command: str) -> tuple[Param, ...]:
    """The parameters of ``command`` (``--help`` left out)."""
    out = []
    for p in commands()[command].params:
        if p.name == "help":
            continue
        out.append(
            Param(
                command=command,
                name=p.name,
                flags=tuple(o for o in p.opts if o.startswith("-")),
                secondary=tuple(getattr(p, "secondary_opts", ()) or ()),
                annotation=p.type_descriptor.annotation,
                is_flag=bool(getattr(p, "is_flag", False)),
                multiple=bool(p.multiple),
                nargs=int(p.nargs),
                key=declared(p),
                default=p.default,
            )
        )
    return tuple(out)


# -------------------------------------------------------------------- the base argv
@dataclass(frozen=True)
class _Slot:
    param: Param
    token: str | None  # the option string used (None for an argument or a flag)
    value: str | None  # None for a flag


def _parse(command: str, recipe: Recipe) -> tuple[list[str], list[_Slot]]:
    """Split a recipe's argv into the command words and one slot per value given."""
    words = command.split()
    argv = list(recipe.argv)
    if argv[: len(words)] != words:
        raise ValueError(f"recipe {command!r} does not start with its command: {argv}")
    rest = argv[len(words) :]
    by_flag = {f: p for p in params(command) for f in (*p.flags, *p.secondary)}
    positional = [p for p in params(command) if p.argument]
    slots: list[_Slot] = []
    i = 0
    while i < len(rest):
        tok = rest[i]
        if tok.startswith("-") and tok in by_flag:
            p = by_flag[tok]
            if p.is_flag:
                slots.append(_Slot(p, tok, None))
                i += 1
            else:
                slots.append(_Slot(p, tok, rest[i + 1]))
                i += 2
            continue
        if not positional:
            raise ValueError(f"recipe {command!r}: {tok!r} is no option and no argument")
        p = positional[0]
        slots.append(_Slot(p, None, tok))
        if p.nargs != -1:
            positional.pop(0)
        i += 1
    return words, slots


def _argv(words: list[str], slots: Sequence[_Slot]) -> tuple[str, ...]:
    out = list(words)
    # options first, then the arguments in their order (click accepts both orders)
    for s in slots:
        if s.token is not None:
            out += [s.token] if s.value is None else [s.token, s.value]
    for s in slots:
        if s.token is None and s.value is not None:
            out.append(s.value)
    return tuple(out)


def _with(
    command: str, recipe: Recipe, param: Param, values: Sequence[str] | None
) -> tuple[str, ...]:
    """The recipe's argv with ``param`` given ``values`` (``None``: a flag toggled)."""
    words, slots = _parse(command, recipe)
    mine = [s for s in slots if s.param == param]
    others = [s for s in slots if s.param != param]
    if values is None:  # toggle a boolean flag
        if mine:
            used = mine[0].token
            flip = [f for f in (*param.flags, *param.secondary) if f != used]
            new = [_Slot(param, flip[0], None)] if flip else []
        else:
            new = [_Slot(param, (param.flags or param.secondary)[0], None)]
        return _argv(words, others + new)
    token = mine[0].token if mine else (param.flags[0] if param.flags else None)
    return _argv(words, others + [_Slot(param, token, v) for v in values])


def _given(command: str, recipe: Recipe, param: Param) -> list[str]:
    """The values the recipe gives ``param``."""
    _, slots = _parse(command, recipe)
    return [s.value for s in slots if s.param == param and s.value is not None]


# ------------------------------------------------------------------------ the classes
def _case(kind: str, command: str, recipe: Recipe, argv: tuple[str, ...], note: str,
          **kw: Any) -> Case:  # fmt: skip
    kw.setdefault("keep", _kept_inputs(recipe))
    return Case(kind=kind, argv=argv, setup=("workspace",), note=f"{command}: {note}", **kw)


def _kept_inputs(recipe: Recipe, but: str = "") -> tuple[str, ...]:
    """The inputs a command must leave as they were (not those it also writes)."""
    return tuple(i for i in recipe.inputs if i not in recipe.outputs and i != but)


def _role(command: str, recipe: Recipe, p: Param) -> tuple[str, list[str]] | None:
    """``("in" | "out" | "state", values)`` of a path parameter, or None (unknown)."""
    given = _given(command, recipe, p)
    if given:
        ins = [v for v in given if v in recipe.inputs]
        outs = [v for v in given if v in recipe.outputs]
        if ins and outs:
            return "state", given
        if outs:
            return "out", given
        if ins:
            return "in", given
        return None
    extra = EXTRA_PATHS.get((command, p.label))
    if extra is not None:
        return extra[0], [extra[1]]
    return None


def _number_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    for v in INT_TEXT if p.base_type == "int" else FLOAT_TEXT:
        yield _case("opt-number", command, recipe, _with(command, recipe, p, [v]), f"{p.label} {v}")


def _outside(key: Any, integer: bool) -> list[str]:
    """Values just outside a declared range (the bound itself where it is open)."""
    out: list[str] = []
    for bound, is_open, sign in ((key.low, key.low_open, -1), (key.high, key.high_open, 1)):
        if bound is None:
            continue
        if integer:
            out.append(str(int(bound) + sign))
        elif is_open:
            out.append(repr(float(bound)))
        else:
            step = max(abs(bound) * 1e-6, 1e-9)
            out.append(repr(float(bound) + sign * step))
    return out


def _bound_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    """Values just outside the declared range: each must be refused (``opt-bound``)."""
    for v in _outside(p.key, p.base_type == "int"):
        yield _case("opt-bound", command, recipe, _with(command, recipe, p, [v]),
                    f"{p.label} {v} outside {p.key.range_text()}")  # fmt: skip


def _inside(p: Param) -> str | None:
    """A value of ``p`` inside its declaration: its default, else a bound, else None."""
    if p.key is not None and p.key.choices:
        return str(p.key.choices[0])
    if p.default is not None and not isinstance(p.default, bool | list | tuple):
        return str(p.default)
    if p.key is None:
        return None
    for bound, is_open in ((p.key.low, p.key.low_open), (p.key.high, p.key.high_open)):
        if bound is not None and not is_open:
            return str(int(bound)) if p.base_type == "int" else repr(float(bound))
    if p.key.low is not None and p.key.high is not None:
        mid = (p.key.low + p.key.high) / 2
        return str(int(mid)) if p.base_type == "int" else repr(mid)
    return None


def _modes(p: Param) -> list[tuple[str, ...] | None]:
    """The ways to switch the mode ``p`` sets: a flag toggled, each declared choice."""
    if p.base_type == "bool":
        return [None]
    if p.key is not None and p.key.choices:
        return [(c,) for c in p.key.choices]
    return []


def _mode_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    """The mode-versus-option matrix: ``p``'s modes with each option the recipe leaves out.

    Each other option is given a value inside its declaration, so that a refusal can only
    be about the combination: an option without effect in that mode must be refused on
    one line (`microfab.cli._options.refuse_unused`), never ignored.
    """
    given = {s.param.name for s in _parse(command, recipe)[1]}
    for mode in _modes(p):
        base = _with(command, recipe, p, mode)
        for other in params(command):
            if other.name in given or other.name == p.name or other.argument:
                continue
            if other.base_type == "path":
                continue  # paths have their own kinds
            value = None if other.base_type == "bool" else _inside(other)
            if other.base_type != "bool" and value is None:
                continue
            flag = (other.flags or other.secondary)[0]
            argv = (*base, flag) if value is None else (*base, flag, value)
            what = "toggled" if mode is None else mode[0]
            yield _case("mode", command, recipe, argv,
                        f"{p.label} {what} with {flag} {value or ''}".rstrip())  # fmt: skip


def _text_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    for v in TEXT:
        yield _case("opt-text", command, recipe, _with(command, recipe, p, [v]),
                    f"{p.label} {v[:20]!r}")  # fmt: skip


def _flag_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    yield _case("opt-flag", command, recipe, _with(command, recipe, p, None), f"{p.label} toggled")


def _out_cases(command: str, recipe: Recipe, p: Param, given: list[str]) -> Iterator[Case]:
    suffix = Path(given[0]).suffix if given else ""
    tries: list[tuple[str, str, dict[str, Any]]] = []
    for inp in recipe.inputs:  # class 1: the output is an input
        tries.append((inp, f"{p.label} = the input {inp}", {}))
    tries += [
        ("adir", f"{p.label} an existing folder", {"damage": (("adir", "folder"),)}),
        ("afile", f"{p.label} an existing file", {"files": (("afile", b"kept?\n"),)}),
        (f"afile/x{suffix}", f"{p.label} under a file", {"files": (("afile", b"kept\n"),)}),
        (f"new/deeper/x{suffix}", f"{p.label} in new folders", {}),
        ("", f"{p.label} empty", {}),
    ]
    for value, note, kw in tries:
        yield _case("out-path", command, recipe, _with(command, recipe, p, [value]), note, **kw)


def _in_cases(command: str, recipe: Recipe, p: Param, given: list[str]) -> Iterator[Case]:
    for v in given:
        for how in INPUT_DAMAGE:
            yield _case("in-path", command, recipe, _with(command, recipe, p, given),
                        f"{p.label} {v} {how}", damage=((v, how),),
                        keep=_kept_inputs(recipe, v))  # fmt: skip
        yield _case("in-path", command, recipe, _with(command, recipe, p, given),
                    f"{p.label} {v} turned into a folder or a file",
                    damage=((v, "file" if v.endswith("/") else "folder"),),
                    keep=_kept_inputs(recipe, v))  # fmt: skip
    yield _case("in-path", command, recipe, _with(command, recipe, p, ["missing.csv"]),
                f"{p.label} missing")  # fmt: skip
    for other in _all_inputs():  # another command's input: the wrong kind of file
        if other not in given:
            yield _case("in-path", command, recipe, _with(command, recipe, p, [other]),
                        f"{p.label} {other}")  # fmt: skip


def _state_cases(command: str, recipe: Recipe, p: Param, given: list[str]) -> Iterator[Case]:
    for v in given:
        for how in OUTPUT_DAMAGE:
            yield _case("state", command, recipe, recipe.argv, f"{p.label} {v} {how}",
                        damage=((v, how),),
                        keep=_kept_inputs(recipe, v))  # fmt: skip


def _special_cases(command: str, recipe: Recipe, p: Param, given: list[str]) -> Iterator[Case]:
    """Each path the recipe gives ``p`` replaced by a FIFO or a symbolic link to itself:
    looked at, never opened (a FIFO opened blocks), and refused on one line."""
    for v in given:
        for how in ("fifo", "loop"):
            yield _case("special", command, recipe, _with(command, recipe, p, given),
                        f"{p.label} {v} as a {how}", damage=((v.rstrip("/"), how),),
                        keep=_kept_inputs(recipe, v))  # fmt: skip


def _set_cases(command: str, recipe: Recipe, p: Param) -> Iterator[Case]:
    from microfab.experiments.catalog import REPRODUCTION_ENTRIES, reproduction

    names = list(REPRODUCTION_ENTRIES)
    for name in names:
        keys = reproduction(name).options
        pairs = [("nope", "1"), ("", "1"), ("seed", "")]
        for k in keys:
            kind = "list" if k.type.endswith("_list") else k.type
            pairs += [(k.name, v) for v in SET_VALUES[kind]]
        for key, value in pairs:
            argv = ("reproduce", name, "--set", f"{key}={value}", "--check")
            yield _case("set", command, recipe, argv, f"{name} --set {key}={value[:20]}")
    yield _case("set", command, recipe, ("reproduce", names[0], "--set", "noequals", "--check"),
                "--set without =")  # fmt: skip


@functools.cache
def _all_inputs() -> tuple[str, ...]:
    seen: dict[str, None] = {}
    for r in RECIPES.values():
        for i in r.inputs:
            seen.setdefault(i, None)
    return tuple(seen)


def _generators(command: str, p: Param) -> list[Callable[[], Iterator[Case]]]:
    """The case generators of one parameter (empty: none covers it)."""
    recipe = RECIPES.get(command)
    if recipe is None:
        return []
    t = p.base_type
    if command == "reproduce" and p.label == "--set":
        return [lambda: _set_cases(command, recipe, p)]
    if t in ("int", "float"):
        if p.key is None:
            return []  # undeclared: `missing_generators` names it
        return [lambda: _number_cases(command, recipe, p),
                lambda: _bound_cases(command, recipe, p)]  # fmt: skip
    if t == "bool":
        return [lambda: _flag_cases(command, recipe, p), lambda: _mode_cases(command, recipe, p)]
    if p.key is not None and p.key.choices:
        return [lambda: _text_cases(command, recipe, p), lambda: _mode_cases(command, recipe, p)]
    if t == "path":
        role = _role(command, recipe, p)
        if role is None:
            return []
        kind, given = role
        special = lambda: _special_cases(command, recipe, p, given)  # noqa: E731
        if kind == "out":
            return [lambda: _out_cases(command, recipe, p, given), special]
        if kind == "in":
            return [lambda: _in_cases(command, recipe, p, given), special]
        return [
            lambda: _state_cases(command, recipe, p, given),
            lambda: _out_cases(command, recipe, p, given),
            special,
        ]
    return [lambda: _text_cases(command, recipe, p)]


def missing_generators() -> list[str]:
    """``"command param"`` for every parameter that no case class covers."""
    out = [f"{c} (no recipe in fuzz_workspace.RECIPES)" for c in commands() if c not in RECIPES]
    out += [f"{c} (recipe of no command)" for c in RECIPES if c not in commands()]
    for c in commands():
        if c not in RECIPES:
            continue
        for p in params(c):
            if p.base_type in ("int", "float") and p.key is None:
                out.append(f"{c} {p.label} (a number without a declared range: cli._options)")
            elif not _generators(c, p):
                out.append(f"{c} {p.label} ({p.base_type}: give it in the recipe or EXTRA_PATHS)")
    return out


@functools.cache
def cases_of(kind: str) -> tuple[Case, ...]:
    """Every case of one kind of `OPTION_KINDS`, over all commands, in a fixed order."""
    out: list[Case] = []
    for c in commands():
        if c not in RECIPES:
            continue
        for p in params(c):
            for gen in _generators(c, p):
                out += [case for case in gen() if case.kind == kind]
    return tuple(out)


def _strategy(kind: str) -> Callable[[], st.SearchStrategy[Case]]:
    def strategy() -> st.SearchStrategy[Case]:
        return st.sampled_from(cases_of(kind))

    strategy.__name__ = f"{kind.replace('-', '_')}_case"
    return strategy


#: The kinds of this module, with their share of ``make fuzz`` (as `fuzz_cases.KINDS`).
OPTION_KINDS: dict[str, tuple[Callable[[], st.SearchStrategy[Case]], float]] = {
    "opt-number": (_strategy("opt-number"), 0.19),
    "opt-text": (_strategy("opt-text"), 0.095),
    "opt-flag": (_strategy("opt-flag"), 0.002),
    "out-path": (_strategy("out-path"), 0.025),
    "in-path": (_strategy("in-path"), 0.055),
    "state": (_strategy("state"), 0.002),
    "set": (_strategy("set"), 0.02),
    "opt-bound": (_strategy("opt-bound"), 0.03),
    "mode": (_strategy("mode"), 0.03),
    "special": (_strategy("special"), 0.01),
}
