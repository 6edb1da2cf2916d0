"""Parameter files in which every value carries its source: the strict reader.

A twin's data file (``microfab/data/<twin>.toml``) holds sections of ``key = value`` pairs,
each value followed by ``key_source = "..."``: ``"seed 00N ..."`` for a number taken from a
seed (its table or equation), ``"assumed: <why>"`` otherwise. Per-axis values live under
``[axes.x]`` and ``[axes.y]``. `read_sourced` reads such a file and refuses unknown
sections and keys, values without a source, sources that are not non-empty strings and
missing values, each with one message naming the file, the section and the key.

The nanomanipulator twin (`microfab.plants.nanomanipulator_params`) and the seed 004 twins
(`microfab.plants.lmw_stage`, `microfab.plants.lmw_focus`) read their files here.
"""

from __future__ import annotations

import os
import tomllib
from importlib import resources
from typing import Any

__all__ = ["read_sourced", "sources_of"]


def _text(path: str | os.PathLike[str] | None, default: str) -> tuple[str, str]:
    """``(origin, text)`` of ``path``, or of ``data/<default>`` in the package."""
    if path is None:
        return f"data/{default}", resources.files("microfab.data").joinpath(default).read_text()
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
