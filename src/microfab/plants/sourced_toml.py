"""Parameter files in which every value carries its source: the strict reader and the writer.

A twin's data file (``microfab/data/<twin>.toml``) holds sections of ``key = value`` pairs,
each value followed by ``key_source = "..."``: ``"seed 00N ..."`` for a number taken from a
seed (its table or equation), ``"assumed: <why>"`` otherwise. Per-axis values live under
``[axes.x]`` and ``[axes.y]``. `read_sourced` reads such a file and refuses unknown
sections and keys, values without a source, sources that are not non-empty strings and
missing values, each with one message naming the file, the section and the key.

The nanomanipulator twin (`microfab.plants.nanomanipulator_params`) and the seed 004 twins
(`microfab.plants.lmw_stage`, `microfab.plants.lmw_focus`) read their files here.

`update_sourced` is the one writer: it gives the text of such a file with chosen values
and their ``_source`` strings replaced in place, every comment, blank line and other line
kept, and refuses a section or key the file does not hold. It returns the text rather than
writing it (``plants`` does not import ``io``): the calibrations write it with
`microfab.io.atomic.atomic_write_text`.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tomllib
from collections.abc import Mapping
from typing import Any

import numpy as np

from microfab.data import read_text as read_data_text

__all__ = ["read_sourced", "sources_of", "toml_value", "update_sourced"]


def _text(path: str | os.PathLike[str] | None, default: str) -> tuple[str, str]:
    """``(origin, text)`` of ``path``, or of ``data/<default>`` in the package."""
    if path is None:
        return f"data/{default}", read_data_text(default)
    with open(path, "rb") as fh:
        return os.fspath(path), fh.read().decode()


def _table(table: Any, known: tuple[str, ...], where: str) -> dict[str, Any]:
    """The values of one TOML table; unknown keys, missing values or sources refused."""
    if not isinstance(table, dict):
        raise ValueError(f"{where}: expected a table of key = value pairs, got {table!r}")
    out: dict[str, Any] = {}
    for key, val in table.items():
        base = key.removesuffix("_source")
        if base not in known:
            raise ValueError(f"{where}: unknown key {key!r}; known: {', '.join(known)}")
        if key == base:
            src = table.get(f"{key}_source")
            if src is None:
                raise ValueError(
                    f"{where}: {key} has no {key}_source string; add one stating its source "
                    '("seed 004 ..." or "assumed: why")'
                )
            if not isinstance(src, str) or not src.strip():
                raise ValueError(f"{where}: {key}_source must be a non-empty string, got {src!r}")
            out[key] = tuple(val) if isinstance(val, list) else val
    missing = [k for k in known if k not in out]
    if missing:
        raise ValueError(f"{where}: missing {', '.join(missing)}; add each with its _source")
    return out


def read_sourced(
    path: str | os.PathLike[str] | None,
    default: str,
    sections: dict[str, tuple[str, ...]],
    per_axis: tuple[str, ...] = (),
    axes: tuple[str, ...] = ("x", "y"),
) -> dict[str, Any]:
    """Read a sourced parameter file into one mapping of field name to value.

    Parameters
    ----------
    path : path-like or None
        The file; None reads ``data/<default>`` from the package.
    default : str
        File name of the packaged default, e.g. ``"lmw_stage.toml"``.
    sections : dict of str to tuple of str
        TOML section -> the keys it must hold (each once, each with its ``_source``).
    per_axis : tuple of str
        Keys of the ``[axes.<name>]`` tables (empty: the file has no ``[axes]``); each
        comes back as a tuple with one value per axis, in the order of ``axes``.
    axes : tuple of str
        Axis names.

    Returns
    -------
    dict of str to Any
        Field name -> value (TOML arrays as tuples), unchecked beyond the file's layout.

    Raises
    ------
    ValueError
        On an unknown section or key, a value without a non-empty ``_source`` string or a
        missing value; the message names the file, the section and the key.
    """
    origin, text = _text(path, default)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{origin}: not valid TOML ({exc})") from exc
    known = set(sections) | ({"axes"} if per_axis else set())
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(
            f"{origin}: unknown section [{unknown[0]}]; known: {', '.join(sorted(known))}"
        )
    values: dict[str, Any] = {}
    for sec, keys in sections.items():
        values.update(_table(data.get(sec, {}), keys, f"{origin} [{sec}]"))
    if per_axis:
        tables = data.get("axes", {})
        if not isinstance(tables, dict) or sorted(tables) != sorted(axes):
            got = sorted(tables) if isinstance(tables, dict) else tables
            raise ValueError(f"{origin}: [axes] needs the tables {', '.join(axes)}, got {got}")
        per = [_table(tables[ax], per_axis, f"{origin} [axes.{ax}]") for ax in axes]
        values.update({k: tuple(p[k] for p in per) for k in per_axis})
    return values


def sources_of(path: str | os.PathLike[str] | None, default: str) -> dict[str, str]:
    """Every ``<key>_source`` of a sourced file: ``"section.key"`` (or ``"axes.x.key"``) -> text.

    For reports and tests that list where each value comes from.
    """
    _origin, text = _text(path, default)
    data = tomllib.loads(text)
    out: dict[str, str] = {}

    def walk(table: dict[str, Any], prefix: str) -> None:
        for key, val in table.items():
            if isinstance(val, dict):
                walk(val, f"{prefix}{key}.")
            elif key.endswith("_source"):
                out[f"{prefix}{key.removesuffix('_source')}"] = str(val)

    walk(data, "")
    return out


_HEADER = re.compile(r"^[ \t]*\[([^\[\]]+)\][ \t]*(#.*)?$")
_ARRAY_HEADER = re.compile(r"^[ \t]*\[\[")


def toml_value(value: Any) -> str:
    """``value`` as a TOML literal: a bool, int, finite float, string or list of these.

    Floats are written with the fewest digits that read back to the same number, in
    exponent form below 1e-3 and from 1e5 on (``0.15``, ``24.0``, ``3.2323e-4``, ``4e7``).

    Raises
    ------
    ValueError
        On a non-finite float or a type TOML cannot hold here.
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML value must be finite, got {value!r}")
        if value != 0.0 and not 1e-3 <= abs(value) < 1e5:
            sci = np.format_float_scientific(value, unique=True, trim="-", exp_digits=1)
            return sci.replace("e+", "e")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a TOML basic string
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise ValueError(
        f"TOML value must be a bool, int, float, string or list, got {type(value).__name__}"
    )


def _split_comment(rest: str) -> tuple[str, str]:
    """``(value, trailing comment)`` of what follows ``key =`` on a line."""
    for i, ch in enumerate(rest):
        if ch == "#":
            try:
                tomllib.loads(f"v = {rest[:i]}")
            except tomllib.TOMLDecodeError:
                continue
            j = len(rest[:i].rstrip())
            return rest[:j], rest[j:]
    return rest.rstrip(), ""


def update_sourced(
    path: str | os.PathLike[str] | None,
    default: str,
    updates: Mapping[tuple[str, str], tuple[Any, str]],
) -> str:
    """The text of a sourced parameter file with values and their sources replaced in place.

    Each ``key = value`` line named in ``updates`` gets the new value and its
    ``key_source = "..."`` line the new source; every other line (comments, blank lines,
    other values, a comment after a replaced value) is kept as it was. The result is read
    back: it must be valid TOML, hold the new values and sources, and every other value as
    before.

    Parameters
    ----------
    path : path-like or None
        The file to start from; None reads ``data/<default>`` from the package.
    default : str
        File name of the packaged default, e.g. ``"lmw_stage.toml"``.
    updates : mapping
        ``(section, key) -> (value, source)``: the TOML section as written in its header
        (``"disturbance"``, ``"axes.x"``), a key of it, the new value (`toml_value`) and
        the new non-empty source string.

    Returns
    -------
    str
        The new text (write it atomically: `microfab.io.atomic.atomic_write_text`).

    Raises
    ------
    ValueError
        On an unknown section or key (the file must hold the key and its ``_source`` once
        in that section), an empty source, a value TOML cannot hold, or a result that does
        not read back as asked; the message names the file, the section and the key.
    """
    origin, text = _text(path, default)
    try:
        before = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{origin}: not valid TOML ({exc})") from exc
    wanted: dict[tuple[str, str], str] = {}
    for (sec, key), (value, source) in updates.items():
        if not isinstance(source, str) or not source.strip() or "\n" in source:
            raise ValueError(
                f"{origin} [{sec}]: {key}_source must be a non-empty single-line string, "
                f"got {source!r}"
            )
        try:
            wanted[(sec, key)] = toml_value(value)
        except ValueError as exc:
            raise ValueError(f"{origin} [{sec}]: {key}: {exc}") from exc
        wanted[(sec, f"{key}_source")] = toml_value(source)
    lines = text.splitlines(keepends=True)
    found: dict[tuple[str, str], int] = dict.fromkeys(wanted, 0)
    headers: dict[str, int] = {}
    section = ""
    for i, line in enumerate(lines):
        body = line.rstrip("\r\n")
        m = _HEADER.match(body)
        if m and not _ARRAY_HEADER.match(body):
            section = m.group(1).strip()
            headers[section] = headers.get(section, 0) + 1
            continue
        if _ARRAY_HEADER.match(body):
            section = ""
            continue
        m = re.match(r"^([ \t]*)([A-Za-z0-9_-]+)([ \t]*=[ \t]*)(.*)$", body)
        if m is None or (section, m.group(2)) not in wanted:
            continue
        indent, key, eq, rest = m.groups()
        _old, comment = _split_comment(rest)
        found[(section, key)] += 1
        ending = line[len(body) :]
        lines[i] = f"{indent}{key}{eq}{wanted[(section, key)]}{comment}{ending}"
    for sec, key in updates:
        if headers.get(sec) != 1:
            known = ", ".join(sorted(headers))
            raise ValueError(f"{origin}: unknown section [{sec}] (for {key}); known: {known}")
        if found[(sec, key)] != 1 or found[(sec, f"{key}_source")] != 1:
            raise ValueError(
                f"{origin}: unknown key {key!r}: [{sec}] must hold {key} and {key}_source once"
            )
    out = "".join(lines)
    values = {k: tomllib.loads(f"v = {v}")["v"] for k, v in wanted.items()}
    _check_update(origin, before, out, values)
    return out


def _check_update(
    origin: str, before: dict[str, Any], text: str, wanted: dict[tuple[str, str], Any]
) -> None:
    """Refuse ``text`` unless it is ``before`` with exactly the ``wanted`` values changed."""
    try:
        after = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # a value spread over lines, which is not rewritten
        raise ValueError(f"{origin}: the updated file is not valid TOML ({exc})") from exc

    def table(data: dict[str, Any], sec: str) -> dict[str, Any]:
        for part in sec.split("."):
            data = data[part.strip()]
        return data

    expected = copy.deepcopy(before)
    for (sec, key), value in wanted.items():
        table(expected, sec)[key] = value
    if after != expected:
        raise ValueError(f"{origin}: the updated file does not read back as asked; not written")
