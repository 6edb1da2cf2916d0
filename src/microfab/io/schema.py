"""What every file microfab reads must be: budgets, units, arrays, JSON documents, paths.

Each loader of a file kind (traces and FRF files: :mod:`microfab.io.trace`,
:mod:`microfab.io.frf`; state files: :mod:`microfab.io.checkpoint`; the learning state:
``microfab.control.ilc.FrequencyILC.load``; the frame index ``frames.json``:
``microfab.measure.frames``; the stage run list ``runs.json``:
``microfab.identify.excitation.read_runs``) checks what it reads with the pieces here,
and refuses a file with a `SchemaError` (a `ValueError`) on one line that names the
file, the field and what is wrong:

- **sizes before allocation**: `check_count` against `MAX_SAMPLES` (one column or array)
  and `MAX_VALUES` (all of one file), called on the sizes a file *declares* (an HDF5
  dataset's shape, a MAT variable's header, an ``.npy`` member's header, a text file's
  byte count) before anything of that size is allocated; `npz_members` reads the headers
  of an ``.npz`` archive without reading its data;
- **arrays**: `check_array` (dtype kind, shape, finiteness, range);
- **units**: `unit_factor` converts between the units of `UNITS` (``m``, ``mm``, ``um``,
  ``µm``, ``nm``, ``s``, ``ms``, ``us``, ``V``, ``A``, ``rad``, ``deg``, ``Hz``, ``bit``...,
  and ratios ``a/b`` of them) and refuses any other unit;
- **JSON documents**: `read_json` (a size budget, no ``RecursionError`` on deep nesting,
  the kind of a file of another kind named) and `validated` (a pydantic model, strict
  types, the first error on one line);
- **paths**: `inside` (a relative path listed in a file stays inside the folder of that
  file, symbolic links resolved).
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any, TypeVar

import numpy as np

__all__ = [
    "MAX_JSON_BYTES",
    "MAX_SAMPLES",
    "MAX_TEXT_BYTES",
    "MAX_VALUES",
    "UNITS",
    "SchemaError",
    "check_array",
    "check_count",
    "check_npz",
    "describe_file",
    "inside",
    "npz_members",
    "parse_unit",
    "read_json",
    "unit_factor",
    "validated",
]

#: Most samples in one column or array of a file. Assumed budget: the memory acceptance
#: of issue 44 is a peak of 2 GB for a command; 2e7 float64 samples are 160 MB, so a
#: command that keeps a few working copies of a column (FFTs, differences) stays well
#: below it. 2e7 samples are 2000 s at the stage's 10 kHz or 20 s at the galvo's 1 MHz,
#: far above any period or run microfab learns from or analyses.
MAX_SAMPLES = 20_000_000
#: Most values of all columns or arrays of one file (assumed: 4e7 float64 = 320 MB, the
#: same reasoning as `MAX_SAMPLES` for a file of a few columns).
MAX_VALUES = 40_000_000
#: Largest text file (CSV) read, bytes (assumed: Python holds each line of a CSV as a
#: string and a row tuple while parsing, about 8 times the file; 64 MiB stays below 1 GB).
MAX_TEXT_BYTES = 64 * 2**20
#: Largest JSON document read, bytes (assumed: an index or a model is kilobytes; a
#: parsed JSON document takes about 10 times its text).
MAX_JSON_BYTES = 16 * 2**20

_M = TypeVar("_M")
#: What reading a damaged archive may raise (zipfile, zlib, numpy's header parser).
_UNREADABLE = (
    OSError,
    ValueError,
    KeyError,
    EOFError,
    AttributeError,
    zipfile.BadZipFile,
    zlib.error,
    NotImplementedError,
    RuntimeError,
)


class SchemaError(ValueError):
    """A file that does not hold what its kind must hold (type, shape, value, size, unit)."""


# --------------------------------------------------------------------------------- sizes
def check_count(where: str, what: str, n: int, budget: int = MAX_SAMPLES) -> int:
    """Return ``n`` if a declared number of samples or values fits ``budget``.

    Parameters
    ----------
    where : str
        The file (and member) for the message.
    what : str
        What is counted, e.g. ``"samples of column 'x'"``.
    n : int
        The declared count (from a header or shape, before anything is allocated).
    budget : int
        The most allowed.

    Raises
    ------
    SchemaError
        ``n`` is above ``budget``.
    """
    if n > budget:
        raise SchemaError(
            f"{where}: declares {n:.4g} {what}, more than the {budget:.4g} this microfab "
            "reads (microfab.io.schema budgets; a damaged header or a unit mistake?)"
        )
    return int(n)


def _size(shape: Sequence[int]) -> int:
    return int(math.prod(int(s) for s in shape))


# -------------------------------------------------------------------------------- arrays
_KINDS = {"f": "a real number", "b": "a boolean", "c": "a complex number", "i": "an integer"}


def check_array(
    where: str,
    name: str,
    value: object,
    *,
    kind: str = "f",
    shape: Sequence[int | None] | None = None,
    finite: bool = True,
    low: float | None = None,
    high: float | None = None,
    unit: str = "",
) -> np.ndarray:
    """An array of the expected dtype kind and shape, finite and in range.

    Parameters
    ----------
    where : str
        The file for the message.
    name : str
        The array's name in the file.
    value : object
        What was read.
    kind : {"f", "c", "b", "i"}
        Real (integers and booleans are not accepted as reals), complex (reals
        accepted), boolean or integer.
    shape : sequence of int or None, optional
        The expected shape, ``None`` for any length along that dimension.
    finite : bool
        Refuse NaN and infinite values (for kinds ``"f"`` and ``"c"``).
    low, high : float, optional
        Bounds of the values (kind ``"f"`` and ``"i"``).
    unit : str
        Unit of the values, for the message.

    Returns
    -------
    numpy.ndarray
        The array (float64, complex128, bool or int64 by ``kind``).

    Raises
    ------
    SchemaError
        Not an array of that kind or shape, a NaN or infinite value, a value out of range.
    """
    arr = np.asarray(value) if isinstance(value, np.ndarray) else None
    if arr is None:
        raise SchemaError(f"{where}: {name} must be an array, got {type(value).__name__}")
    ok = {
        "f": arr.dtype.kind == "f",
        "c": arr.dtype.kind in "fc",
        "b": arr.dtype.kind == "b",
        "i": arr.dtype.kind in "iu",
    }[kind]
    if not ok:
        raise SchemaError(
            f"{where}: {name} must hold {_KINDS[kind]} per element, got dtype {arr.dtype}"
        )
    if shape is not None and (
        arr.ndim != len(shape)
        or any(s is not None and s != d for s, d in zip(shape, arr.shape, strict=True))
    ):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise SchemaError(f"{where}: {name} must have shape {want}, got {arr.shape}")
    out = arr.astype({"f": np.float64, "c": np.complex128, "b": bool, "i": np.int64}[kind])
    if finite and kind in "fc" and out.size and not np.isfinite(out).all():
        bad = np.unravel_index(int(np.argmin(np.isfinite(out))), out.shape)
        raise SchemaError(f"{where}: {name} holds {out[bad]} at {tuple(map(int, bad))}")
    if kind in "fi" and out.size and (low is not None or high is not None):
        lo = -np.inf if low is None else low
        hi = np.inf if high is None else high
        bad_mask = (out < lo) | (out > hi)
        if bad_mask.any():
            at = np.unravel_index(int(np.argmax(bad_mask)), out.shape)
            raise SchemaError(
                f"{where}: {name} must lie in [{lo:g}, {hi:g}] {unit}".rstrip()
                + f", got {out[at]} at {tuple(map(int, at))}"
            )
    return out


def npz_members(path: str | os.PathLike[str]) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Shape and dtype of every member of an ``.npz`` archive, read from the headers only.

    Raises
    ------
    OSError, ValueError, zipfile.BadZipFile
        Not a readable archive of ``.npy`` members.
    """
    fmt = np.lib.format
    out: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            name = info.filename.removesuffix(".npy")
            with zf.open(info) as f:
                version = fmt.read_magic(f)
                if version == (1, 0):
                    shape, _, dtype = fmt.read_array_header_1_0(f)
                elif version == (2, 0):
                    shape, _, dtype = fmt.read_array_header_2_0(f)
                else:
                    raise ValueError(f"member {name!r}: .npy format {version} not read")
            out[name] = (tuple(int(s) for s in shape), np.dtype(dtype))
    return out


def check_npz(
    path: str | os.PathLike[str], *, budget: int = MAX_VALUES
) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """`npz_members`, each member and their sum checked against the budgets.

    Raises
    ------
    SchemaError
        A member declares more than `MAX_SAMPLES` values, all more than ``budget``, or a
        member holds Python objects (which would need pickle).
    OSError, ValueError, zipfile.BadZipFile
        As for `npz_members`.
    """
    members = npz_members(path)
    total = 0
    for name, (shape, dtype) in members.items():
        if dtype.hasobject:
            raise SchemaError(f"{path}: member {name!r} holds Python objects (dtype {dtype})")
        total += check_count(f"{path}", f"values in member {name!r}", _size(shape))
    check_count(f"{path}", "values in all members", total, budget)
    return members


# --------------------------------------------------------------------------------- units
#: Units microfab converts: spelling -> (quantity, factor to the quantity's SI unit).
UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "km": ("length", 1e3),
    "cm": ("length", 1e-2),
    "mm": ("length", 1e-3),
    "um": ("length", 1e-6),
    "µm": ("length", 1e-6),  # micro sign
    "μm": ("length", 1e-6),  # Greek mu
    "nm": ("length", 1e-9),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "µs": ("time", 1e-6),
    "μs": ("time", 1e-6),
    "ns": ("time", 1e-9),
    "V": ("voltage", 1.0),
    "mV": ("voltage", 1e-3),
    "kV": ("voltage", 1e3),
    "A": ("current", 1.0),
    "mA": ("current", 1e-3),
    "uA": ("current", 1e-6),
    "µA": ("current", 1e-6),
    "rad": ("angle", 1.0),
    "mrad": ("angle", 1e-3),
    "urad": ("angle", 1e-6),
    "µrad": ("angle", 1e-6),
    "deg": ("angle", math.pi / 180.0),
    "Hz": ("frequency", 1.0),
    "kHz": ("frequency", 1e3),
    "MHz": ("frequency", 1e6),
    "bit": ("bit", 1.0),
    "counts": ("count", 1.0),
    "1": ("ratio", 1.0),
}
#: The SI unit of each quantity of `UNITS` (what a column of mixed units is converted to).
SI = {
    "length": "m",
    "time": "s",
    "voltage": "V",
    "current": "A",
    "angle": "rad",
    "frequency": "Hz",
    "bit": "bit",
    "count": "counts",
    "ratio": "1",
}


def parse_unit(unit: str, where: str = "") -> tuple[str, float]:
    """``(quantity, factor to SI)`` of a unit of `UNITS` or a ratio ``a/b`` of two.

    ``""`` (no unit declared) is ``("", 1.0)``.

    Raises
    ------
    SchemaError
        Any other unit; the message names ``where`` and the units known.
    """
    u = unit.strip()
    if not u:
        return "", 1.0
    if u in UNITS:
        return UNITS[u]
    num, sep, den = u.partition("/")
    if sep and num.strip() in UNITS and den.strip() in UNITS:
        (qn, fn), (qd, fd) = UNITS[num.strip()], UNITS[den.strip()]
        return f"{qn}/{qd}", fn / fd
    pre = f"{where}: " if where else ""
    raise SchemaError(
        f"{pre}unknown unit {unit!r}; microfab reads {', '.join(UNITS)} and ratios of them "
        "(e.g. m/V)"
    )


def unit_factor(from_unit: str, to_unit: str, where: str = "") -> float:
    """The factor that converts values in ``from_unit`` to ``to_unit``.

    Parameters
    ----------
    from_unit, to_unit : str
        Units of `UNITS` (or ratios); ``""`` on either side means "not declared": 1.0.
    where : str
        The file and column, for the message.

    Raises
    ------
    SchemaError
        An unknown unit, or units of different quantities (``m`` into ``s``).

    Examples
    --------
    >>> unit_factor("mm", "m")
    0.001
    """
    qf, ff = parse_unit(from_unit, where)
    qt, ft = parse_unit(to_unit, where)
    if not qf or not qt:
        return 1.0
    if qf != qt:
        pre = f"{where}: " if where else ""
        raise SchemaError(f"{pre}unit {from_unit!r} ({qf}) cannot be read as {to_unit!r} ({qt})")
    return ff / ft


# ---------------------------------------------------------------------------------- JSON
def _json_kind(doc: object) -> str | None:
    """The kind of a JSON document, by the keys `microfab.io.filekinds.FILE_KINDS` lists."""
    from microfab.io.filekinds import FILE_KINDS

    if isinstance(doc, dict):
        for kind in FILE_KINDS.values():
            if any(keys <= set(doc) for keys in kind.json_keys):
                return kind.what
    return None


def describe_file(path: str | os.PathLike[str]) -> str | None:
    """What a file is, from its first bytes and, for state files and JSON, its kind.

    Returns
    -------
    str or None
        e.g. ``"a stage run list (runs.json of stage excite)"``, ``"an ILC state file"``,
        ``"an HDF5 file"``; None when it is none of the kinds microfab knows.
    """
    p = Path(path)
    try:
        with p.open("rb") as f:
            head = f.read(128)
    except OSError:
        return None
    if head.startswith(b"\x89HDF"):
        return "an HDF5 file"
    if head.startswith(b"MATLAB"):
        return "a MAT file"
    if head.startswith(b"PK"):
        try:
            check_npz(p)
            with np.load(p, allow_pickle=False) as z:
                if "meta" in z.files and z["meta"].size == 1:
                    kind = json.loads(str(z["meta"])).get("kind")
                    if isinstance(kind, str):
                        return f"a {kind} file"
        except _UNREADABLE:
            pass
        return "a zip archive"
    if head.lstrip().startswith(b"{") and p.stat().st_size <= MAX_JSON_BYTES:
        try:
            return _json_kind(json.loads(p.read_text(encoding="utf-8"))) or "a JSON file"
        except (ValueError, RecursionError, UnicodeDecodeError):
            return None
    return None


def read_json(path: str | os.PathLike[str], what: str, *, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """A JSON document of at most ``max_bytes``, refused on one line when unreadable.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file must be (``"a frame index (frames.json)"``), for the messages; a
        document of another known kind is named as such ("this is X, not Y").
    max_bytes : int
        Size budget, checked before the file is read.

    Raises
    ------
    FileNotFoundError
        No such file.
    SchemaError
        Too large, not UTF-8 JSON, nested too deeply, a NaN or infinity, or a document
        of another kind.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file ({what} expected)")
    if not p.is_file():
        raise SchemaError(f"{p}: not a file ({what} expected)")
    check_count(str(p), "bytes", p.stat().st_size, max_bytes)

    def no_constant(name: str) -> None:
        raise ValueError(f"{name} is not a JSON number")

    try:
        doc = json.loads(p.read_text(encoding="utf-8"), parse_constant=no_constant)
    except RecursionError:
        raise SchemaError(f"{p}: nested too deeply to be {what}") from None
    except (UnicodeDecodeError, ValueError) as exc:
        other = describe_file(p)
        if other is not None and other != "a JSON file":
            raise SchemaError(f"{p}: this is {other}, not {what}") from None
        why = " ".join(str(exc).split())
        raise SchemaError(f"{p}: not {what} (not JSON: {why})") from None
    other = _json_kind(doc)
    if other is not None and other != what:
        raise SchemaError(f"{p}: this is {other}, not {what}")
    return doc


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


#: Pydantic's error types said the way the rest of microfab says them.
_TYPE_WORDS = {
    "float_type": "is not a number",
    "float_parsing": "is not a number",
    "finite_number": "is not a finite number",
    "int_type": "is not an integer",
    "int_from_float": "is not an integer",
    "string_type": "is not a string",
    "bool_type": "is not true or false",
    "list_type": "is not a list",
    "dict_type": "is not a JSON object",
    "model_type": "is not a JSON object",
    "model_attributes_type": "is not a JSON object",
}


def validated(model: Callable[..., _M], data: object, where: str) -> _M:
    """``data`` validated by a pydantic model; its first error as one `SchemaError` line.

    The line reads ``<where>: <key> = <value> <what is wrong>``, e.g.
    ``frames.json: t0_s = [1.0] is not a number``.

    Parameters
    ----------
    model : pydantic model class
        The schema (strict types are advised: ``ConfigDict(strict=True)``).
    data : object
        The parsed document.
    where : str
        The file, for the message.
    """
    from pydantic import ValidationError

    try:
        return model.model_validate(data)  # type: ignore[attr-defined, no-any-return]
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"]) or "the document"
        if err["type"] == "missing":
            raise SchemaError(f"{where}: {loc} is missing") from None
        words = _TYPE_WORDS.get(err["type"]) or err["msg"].replace("Input should", "should")
        raise SchemaError(f"{where}: {loc} = {_shown(err.get('input'))} {words}") from None


# --------------------------------------------------------------------------------- paths
def inside(folder: str | os.PathLike[str], name: object, where: str) -> Path:
    """The file ``name`` listed in a file of ``folder``, if it stays inside ``folder``.

    Parameters
    ----------
    folder : str or os.PathLike
        The folder of the listing file.
    name : object
        What the listing holds: a relative path (``/`` separated).
    where : str
        The listing file and field, for the message.

    Returns
    -------
    pathlib.Path
        ``folder / name``.

    Raises
    ------
    SchemaError
        Not a non-empty string, an absolute path, a ``..`` component, or a path that a
        symbolic link takes outside ``folder``.
    """
    if not isinstance(name, str) or not name.strip() or "\x00" in name:
        raise SchemaError(f"{where}: a file name must be a non-empty string, got {name!r}")
    posix, win = PurePosixPath(name), PureWindowsPath(name)
    if posix.is_absolute() or win.is_absolute() or win.drive or ".." in posix.parts + win.parts:
        raise SchemaError(
            f"{where}: {name!r} leaves the folder {folder}; list files relative to it"
        )
    base = Path(folder)
    full = base / posix
    if not full.resolve().is_relative_to(base.resolve()):
        raise SchemaError(f"{where}: {name!r} is a link that leaves the folder {folder}")
    return full
