"""Job files (TOML): the ``[job]`` header and typed, strictly checked sections.

A job file names its kind and report folder in ``[job]``; every other section belongs to
the kind, which declares it as a schema of `Key` entries::

    [job]
    kind = "msl-ilc"          # a registered job kind (``microfab kinds`` lists them)
    name = "..."              # report title (optional)
    out = "report/msl-ilc"    # report folder, relative to the working directory
                              # (default: report/<kind>)

    [scan]                    # sections and keys of the kind
    features_per_s = 400

Values are checked, not coerced: an integer key refuses ``400.9`` and ``true``; a float
key refuses ``true``, ``inf`` and ``nan``; every number is checked against its range;
unknown sections and keys are refused. Every refusal is one `JobFileError` line naming
the file, the section, the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

__all__ = ["JobFile", "JobFileError", "Key", "parse_job", "parse_section", "read_job"]

KeyType = Literal["int", "float", "str", "bool", "int_list", "float_list"]


class JobFileError(ValueError):
    """A job file is unreadable or holds a value of the wrong type or range."""


@dataclass(frozen=True, kw_only=True)
class Key:
    """One key of a job-file section.

    Parameters
    ----------
    name : str
        Key name in the TOML file.
    type : {"int", "float", "str", "bool", "int_list", "float_list"}
        Accepted TOML type; ``float`` also takes integers, nothing takes a bool but
        ``bool``.
    default : Any
        Value when the key is absent.
    low, high : float, optional
        Inclusive range of a number (of every element of a list).
    unit : str
        Unit, for messages.
    help : str
        One line for documentation.
    alias : str, optional
        An older name still accepted for this key.
    allow_empty : bool
        A list key that accepts ``[]`` (default: a list must hold a value).
    path : bool
        The value may name an input file or folder. A relative one is looked up beside the
        job file first (`JobFile.parse` rewrites it to that path when it exists there),
        then in the working directory; when it names one that exists, its content is part
        of a run's fingerprint
        (`microfab.io.runstore`), so a run resumed on changed data is refused.
    choices : tuple of str, optional
        The values a ``str`` key takes (any non-empty string when not given).
    low_open, high_open : bool
        ``low`` (``high``) itself is outside the range: a speed or a period is more than 0,
        not 0.
    """

    name: str
    type: KeyType
    default: Any
    low: float | None = None
    high: float | None = None
    unit: str = ""
    help: str = ""
    alias: str | None = None
    allow_empty: bool = False
    path: bool = False
    choices: tuple[str, ...] | None = None
    low_open: bool = False
    high_open: bool = False

    def range_text(self) -> str:
        """The range as ``[low, high] unit`` (``(`` or ``)`` where a bound is excluded)."""
        lo = "-inf" if self.low is None else f"{self.low:g}"
        hi = "inf" if self.high is None else f"{self.high:g}"
        unit = f" {self.unit}" if self.unit else ""
        left = "(" if self.low is None or self.low_open else "["
        right = ")" if self.high is None or self.high_open else "]"
        return f"{left}{lo}, {hi}{right}{unit}"

    def outside(self, value: float) -> bool:
        """Whether the number ``value`` is outside the range (or not finite)."""
        if not math.isfinite(value):
            return True
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return True
        return self.high is not None and (
            value >= self.high if self.high_open else value > self.high
        )

    def check(self, value: Any, where: str, as_written: str | None = None) -> Any:
        """Return ``value`` checked against this key (lists become tuples).

        Parameters
        ----------
        value : Any
            The value read.
        where : str
            ``"file [section]"``, for messages.
        as_written : str, optional
            The key's name as the file spells it (an alias), for messages.

        Raises
        ------
        JobFileError
            Naming ``where``, the key, the value and what is allowed.
        """
        what = f"{where} {as_written or self.name} = {value!r}"
        if self.type == "str":
            if not isinstance(value, str) or not value.strip():
                raise JobFileError(f"{what}: expected a non-empty string")
            if self.choices is not None and value not in self.choices:
                raise JobFileError(f"{what}: expected one of {', '.join(self.choices)}")
            return value
        if self.type == "bool":
            if not isinstance(value, bool):
                raise JobFileError(f"{what}: expected true or false")
            return value
        if self.type in ("int_list", "float_list"):
            if not isinstance(value, list) or not (value or self.allow_empty):
                empty = "" if self.allow_empty else "non-empty "
                raise JobFileError(f"{what}: expected a {empty}list of numbers")
            scalar = "int" if self.type == "int_list" else "float"
            return tuple(self._number(v, what, scalar) for v in value)
        return self._number(value, what, self.type)

    def _number(self, value: Any, what: str, kind: str) -> int | float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise JobFileError(f"{what}: expected {'an integer' if kind == 'int' else 'a number'}")
        if kind == "int" and not isinstance(value, int):
            raise JobFileError(f"{what}: expected an integer, not {value!r}")
        if not math.isfinite(value):
            raise JobFileError(f"{what}: expected a finite number in {self.range_text()}")
        if self.outside(value):
            raise JobFileError(f"{what}: outside the allowed range {self.range_text()}")
        return int(value) if kind == "int" else float(value)


def parse_section(
    body: Mapping[str, Any], keys: Sequence[Key], source: str, section: str = ""
) -> dict[str, Any]:
    """Check one section against its keys; absent keys take their defaults.

    Parameters
    ----------
    body : mapping
        The section as read from TOML.
    keys : sequence of Key
        The section's schema.
    source : str
        Where the section comes from (file name), for messages.
    section : str
        Section name, for messages.

    Returns
    -------
    dict
        Key name to checked value, every key of the schema present.

    Raises
    ------
    JobFileError
        Unknown key, or a value of the wrong type or range.
    """
    by_name = {k.name: k for k in keys} | {k.alias: k for k in keys if k.alias}
    unknown = sorted(set(body) - set(by_name))
    inside = f" in [{section}]" if section else ""
    if unknown:
        known = ", ".join(k.name for k in keys) or "none"
        raise JobFileError(f"{source}: unknown key(s) {unknown}{inside} (known: {known})")
    out = {k.name: k.default for k in keys}
    where = f"{source} [{section}]" if section else source
    for name, value in body.items():
        key = by_name[name]
        out[key.name] = key.check(value, where, name)
    return out


@dataclass(frozen=True, kw_only=True)
class JobFile:
    """A parsed job file before its kind interprets the sections.

    Attributes
    ----------
    kind : str or None
        The ``[job] kind``; ``None`` when the file names none (the reader of the
        registry then takes its default kind).
    name : str or None
        Report title, if given.
    out : pathlib.Path or None
        Report folder, if given.
    sections : dict
        Every other section, as read.
    source : str
        Where it came from (for messages).
    folder : pathlib.Path or None
        The job file's folder (`read_job`), against which relative input paths (keys with
        ``path``) are resolved first; None for a job not read from a file.
    """

    kind: str | None
    name: str | None
    out: Path | None
    sections: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<job>"
    folder: Path | None = None

    def parse(self, schema: Mapping[str, Sequence[Key]]) -> dict[str, dict[str, Any]]:
        """Check every section against a kind's schema (unknown sections refused).

        Returns
        -------
        dict
            Section name to checked values (all sections of the schema, with defaults).
        """
        unknown = sorted(set(self.sections) - set(schema))
        if unknown:
            known = ", ".join(["job", *schema])
            raise JobFileError(
                f"{self.source}: unknown section(s) {unknown} for kind {self.kind!r} "
                f"(known: {known})"
            )
        parsed = {
            sec: parse_section(self.sections.get(sec, {}), keys, self.source, sec)
            for sec, keys in schema.items()
        }
        if self.folder is not None:
            for sec, keys in schema.items():
                for key in keys:
                    value = parsed[sec].get(key.name)
                    if key.path and isinstance(value, str) and value:
                        parsed[sec][key.name] = _beside(self.folder, value)
        return parsed


def _beside(folder: Path, value: str) -> str:
    """``value`` as a path beside the job file when it is relative and exists there."""
    p = Path(value).expanduser()
    if p.is_absolute():
        return value
    try:
        here = folder / p
        return str(here) if here.exists() else value
    except (OSError, ValueError):  # not a path (a spec string the kind reads)
        return value


_JOB_KEYS = (
    Key(name="kind", type="str", default=None, help="registered job kind"),
    Key(name="name", type="str", default=None, help="report title"),
    Key(name="out", type="str", default=None, help="report folder (default: report/<kind>)"),
)


def parse_job(data: Mapping[str, Any], source: str) -> JobFile:
    """Split TOML data into the ``[job]`` header and the kind's sections.

    Raises
    ------
    JobFileError
        A section that is not a table, or a bad ``[job]`` value.
    """
    for sec, body in data.items():
        if not isinstance(body, dict):
            raise JobFileError(f"{source}: [{sec}] must be a table, got {body!r}")
    head = parse_section(data.get("job", {}), _JOB_KEYS, source, "job")
    return JobFile(
        kind=head["kind"],
        name=head["name"],
        out=None if head["out"] is None else Path(head["out"]),
        sections={k: dict(v) for k, v in data.items() if k != "job"},
        source=source,
    )


def read_job(path: str | Path) -> JobFile:
    """Read a job file.

    Raises
    ------
    FileNotFoundError
        No such file.
    JobFileError
        Not UTF-8 TOML, or a bad ``[job]`` section.
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise JobFileError(f"{p}: not valid TOML: {' '.join(str(exc).split())}") from exc
    job = parse_job(data, str(p))
    return dataclasses.replace(job, folder=p.parent)
