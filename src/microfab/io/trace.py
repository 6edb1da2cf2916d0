"""CSV / MAT / HDF5 files of sampled signals (:class:`~microfab.core.signals.Trace`).

A file holds named 1-D columns of equal length: ``time`` (in s) and one column per axis.
:func:`read_columns` / :func:`write_columns` handle raw named columns; :func:`read_trace` /
:func:`write_trace` build a validated, uniformly sampled :class:`Trace` on top of them.
The format follows the suffix: ``.csv``, ``.mat`` or ``.h5`` / ``.hdf5``. All writers are
atomic (see :mod:`microfab.io.atomic`).

What a file may declare is checked before anything of that size is read (sample counts
against :data:`microfab.io.schema.MAX_SAMPLES` and ``MAX_VALUES``: an HDF5 dataset's shape,
a MAT variable's header, a CSV's size), and every declared unit must be one of
:data:`microfab.io.schema.UNITS`: the file's unit (CSV ``# unit:`` line, MAT ``unit``
variable, HDF5 root attribute ``unit``) and, in HDF5, a dataset's own ``unit`` attribute,
which is converted (``time`` to s, a data column to the file's unit, else to the SI unit of
its quantity).

The signal itself, its checks and the column-name rule live in
:mod:`microfab.core.signals`; ``Trace`` is re-exported here, so
``from microfab.io.trace import Trace`` keeps working.
"""

from __future__ import annotations

import io
import os
import re
import struct
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from microfab.core.signals import TIME, Trace, check_name, check_unit
from microfab.io.atomic import atomic_path, atomic_write_text
from microfab.io.schema import (
    MAX_SAMPLES,
    MAX_TEXT_BYTES,
    MAX_VALUES,
    SI,
    check_count,
    parse_unit,
    unit_factor,
)

__all__ = ["Trace", "read_columns", "read_trace", "write_columns", "write_trace"]

PathLike = str | os.PathLike[str]
_FORMATS = {".csv": "csv", ".mat": "mat", ".h5": "h5", ".hdf5": "h5"}
_UNIT_LINE = re.compile(r"#\s*unit\s*:(.*)")


#: What the MAT and HDF5 libraries raise on a damaged file besides their own errors.
_DAMAGED = (
    ValueError,
    TypeError,
    IndexError,
    KeyError,
    EOFError,
    OverflowError,
    UnicodeDecodeError,
    AttributeError,
    struct.error,
    zlib.error,
)


def _format(path: Path) -> str:
    fmt = _FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise ValueError(
            f"unsupported trace file suffix {path.suffix!r} for {path}; "
            f"supported: {', '.join(_FORMATS)}"
        )
    return fmt


def _h5py() -> Any:
    try:
        import h5py
    except ImportError as exc:
        raise ImportError("HDF5 support needs h5py: pip install 'microfab[hdf5]'") from exc
    return h5py


def write_columns(path: PathLike, columns: Mapping[str, np.ndarray], *, unit: str = "") -> None:
    """Write named 1-D columns of equal length to ``path`` atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Target; ``.csv`` (header row, ``%.17g`` values, ``# unit: ...`` line if a unit
        is given), ``.mat`` (one n x 1 variable per column, plus a char variable ``unit``
        if given) or ``.h5`` / ``.hdf5`` (one root dataset per column, root attribute
        ``unit``). Column order is kept in all three.
    columns : Mapping of str to array_like, shape (n,)
        Columns by name (a letter, then letters, digits, underscores), stored as float64.
    unit : str, optional
        Unit of the data columns, stored as metadata.

    Raises
    ------
    ValueError
        For an unsupported suffix, a bad name, non-1-D or unequal-length columns.
    """
    path = Path(path)
    fmt = _format(path)
    unit = check_unit(unit)
    cols = {check_name(k, "column"): np.asarray(v, dtype=np.float64) for k, v in columns.items()}
    if not cols or any(
        c.ndim != 1 or c.shape != next(iter(cols.values())).shape for c in cols.values()
    ):
        shapes = {k: c.shape for k, c in cols.items()}
        raise ValueError(f"need one or more 1-D columns of equal length, got shapes {shapes}")
    if fmt == "csv":
        buf = io.StringIO()
        buf.write(f"# unit: {unit}\n" if unit else "")
        buf.write(",".join(cols) + "\n")
        np.savetxt(buf, np.column_stack(list(cols.values())), fmt="%.17g", delimiter=",")
        atomic_write_text(path, buf.getvalue())
    elif fmt == "mat":
        from scipy.io import savemat

        if unit and "unit" in cols:
            raise ValueError(f"{path}: a column named 'unit' clashes with the unit variable")
        with atomic_path(path) as tmp:
            savemat(tmp, {**cols, **({"unit": unit} if unit else {})}, oned_as="column")
    else:
        h5py = _h5py()
        with atomic_path(path) as tmp, h5py.File(tmp, "w", track_order=True) as f:
            f.attrs["unit"] = unit
            for name, col in cols.items():
                f.create_dataset(name, data=col)


def _column(path: Path, name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf" or np.squeeze(arr).ndim > 1:
        raise ValueError(
            f"{path}: variable {name!r} is not a numeric 1-D column ({arr.dtype}, {arr.shape})"
        )
    return np.atleast_1d(np.squeeze(arr)).astype(np.float64)


def _parse_rows(path: Path, rows: list[tuple[int, str]], header: list[str]) -> np.ndarray:
    # Slow path, run only when np.loadtxt fails: parse line by line to say where it breaks.
    data = np.empty((len(rows), len(header)))
    for r, (lineno, line) in enumerate(rows):
        fields = line.split("#", 1)[0].split(",")
        if len(fields) != len(header):
            raise ValueError(
                f"{path}, line {lineno}: expected {len(header)} fields, got {len(fields)}"
            )
        for j, (name, field) in enumerate(zip(header, fields, strict=True)):
            try:
                data[r, j] = float(field)
            except ValueError:
                raise ValueError(
                    f"{path}, line {lineno}, column {name!r}: not a number: {field!r}"
                ) from None
    return data


def _read_csv(path: Path) -> tuple[dict[str, np.ndarray], str, dict[str, str]]:
    check_count(str(path), "bytes of text", path.stat().st_size, MAX_TEXT_BYTES)
    unit, header, rows = "", None, []
    for lineno, line in enumerate(path.read_text(encoding="utf-8-sig").splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith("#"):
            if header is None and (m := _UNIT_LINE.match(stripped)):
                unit = m.group(1).strip()
        elif not stripped:
            continue
        elif header is None:
            header = [n.strip().strip('"') for n in line.split(",")]
            if "" in header or len(set(header)) != len(header):
                raise ValueError(f"{path}, line {lineno}: empty or duplicate column names {header}")
        else:
            rows.append((lineno, line))
    if header is None:
        raise ValueError(f"{path}: no header row (expected 'time,<axis>,...')")
    data = np.empty((0, len(header)))
    if rows:
        try:
            lines = [line for _, line in rows]
            data = np.loadtxt(lines, delimiter=",", comments="#", ndmin=2, dtype=np.float64)
            if data.shape != (len(rows), len(header)):
                raise ValueError("shape mismatch")
        except ValueError:
            data = _parse_rows(path, rows, header)
    return {name: data[:, j].copy() for j, name in enumerate(header)}, unit, {}


#: MAT classes read as numeric columns (``whosmat`` names them so).
_MAT_NUMERIC = {
    "double",
    "single",
    "int8",
    "int16",
    "int32",
    "int64",
    "uint8",
    "uint16",
    "uint32",
    "uint64",
    "logical",
}


def _check_declared(path: Path, name: str, shape: tuple[int, ...], total: int) -> int:
    """Budget of one declared column (a 1-D or n x 1 shape) before it is read."""
    n = 1
    for d in shape:
        n *= int(d)
    check_count(f"{path}", f"samples in column {name!r}", n, MAX_SAMPLES)
    return check_count(f"{path}", "values in all columns", total + n, MAX_VALUES)


def _read_mat(path: Path) -> tuple[dict[str, np.ndarray], str, dict[str, str]]:
    from scipy.io import loadmat, whosmat
    from scipy.io.matlab import MatReadError

    try:
        total = 0
        for name, shape, cls in whosmat(path):  # headers only: sizes before any allocation
            if name == "unit" and cls == "char":
                check_count(f"{path}", "characters in 'unit'", int(np.prod(shape)), 1000)
                continue
            if cls not in _MAT_NUMERIC or sum(int(d) > 1 for d in shape) > 1:
                raise ValueError(
                    f"{path}: variable {name!r} is not a numeric 1-D column ({cls}, {tuple(shape)})"
                )
            total = _check_declared(path, name, tuple(shape), total)
        raw = loadmat(path, squeeze_me=True)
    except ValueError as exc:
        if str(path) in str(exc):  # a refusal above
            raise
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: not a readable MAT file (v7.3 files are HDF5): {why}") from exc
    except (MatReadError, NotImplementedError, OSError, *_DAMAGED) as exc:  # cut or damaged
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: not a readable MAT file (v7.3 files are HDF5): {why}") from exc
    unit = raw.pop("unit", "") if isinstance(raw.get("unit"), str) else ""
    cols = {k: _column(path, k, v) for k, v in raw.items() if not k.startswith("__")}
    return cols, unit, {}


def _attr_text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _read_h5(path: Path) -> tuple[dict[str, np.ndarray], str, dict[str, str]]:
    h5py = _h5py()
    if not h5py.is_hdf5(path):
        raise ValueError(f"{path}: not an HDF5 file")
    try:
        with h5py.File(path, "r") as f:
            unit = _attr_text(f.attrs.get("unit", ""))
            sets = {k: v for k, v in f.items() if isinstance(v, h5py.Dataset)}
            total = 0
            for k, v in sets.items():  # the declared shape, before any data is read
                if v.dtype.kind not in "biuf" or sum(int(d) > 1 for d in v.shape) > 1:
                    raise ValueError(
                        f"{path}: variable {k!r} is not a numeric 1-D column ({v.dtype}, {v.shape})"
                    )
                total = _check_declared(path, k, tuple(v.shape), total)
            units = {k: _attr_text(v.attrs["unit"]) for k, v in sets.items() if "unit" in v.attrs}
            raw = {k: v[()] for k, v in sets.items()}
    except ValueError as exc:
        if str(path) in str(exc):  # a refusal above
            raise
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: damaged HDF5 file: {why}") from exc
    except (OSError, RuntimeError, *_DAMAGED) as exc:  # HDF5's own errors on damage
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: damaged HDF5 file: {why}") from exc
    return {k: _column(path, k, v) for k, v in raw.items()}, unit, units


def _convert_units(
    path: Path, cols: dict[str, np.ndarray], unit: str, units: Mapping[str, str]
) -> tuple[dict[str, np.ndarray], str]:
    """Columns with their declared units converted; the unit of the data columns.

    ``time`` is converted to s; a data column with its own unit to the file's unit, or,
    without one, all to that unit when they share it, else each to the SI unit of its
    quantity (the trace's unit is then that SI unit, or ``""`` when they differ).
    """
    parse_unit(unit, f"{path}: the file's unit")
    for k, u in units.items():
        parse_unit(u, f"{path}: unit of column {k!r}")
    if TIME in units:
        cols[TIME] = cols[TIME] * unit_factor(units[TIME], "s", f"{path}: column 'time'")
    data = {k: u for k, u in units.items() if k != TIME and k in cols and u.strip()}
    if not data:
        return cols, unit
    target = unit
    if not target:
        plain = [k for k in cols if k != TIME and k not in data]
        same = set(data.values())
        if len(same) == 1 and not plain:
            return cols, same.pop()  # every column in one declared unit: kept as is
        quantities = {parse_unit(u)[0] for u in data.values()}
        target = _si(quantities.pop()) if len(quantities) == 1 else ""
    for k, u in data.items():
        to = target or _si(parse_unit(u)[0])
        cols[k] = cols[k] * unit_factor(u, to, f"{path}: column {k!r}")
    return cols, target


def _si(quantity: str) -> str:
    """The SI unit of a quantity of `microfab.io.schema.UNITS` (or of a ratio ``a/b``)."""
    return "/".join(SI[q] for q in quantity.split("/"))


def _read(path: PathLike) -> tuple[dict[str, np.ndarray], str]:
    path = Path(path)
    fmt = _format(path)
    if not path.is_file():
        raise FileNotFoundError(f"trace file not found: {path}")
    cols, unit, units = {"csv": _read_csv, "mat": _read_mat, "h5": _read_h5}[fmt](path)
    return _convert_units(path, cols, unit, units)


def read_columns(path: PathLike) -> dict[str, np.ndarray]:
    """Read every column of a ``.csv``, ``.mat`` or ``.h5`` / ``.hdf5`` file.

    Parameters
    ----------
    path : str or os.PathLike
        File to read.

    Returns
    -------
    dict of str to numpy.ndarray
        Float64 1-D arrays by name, in file order: the CSV header order, the MAT variable
        order as saved, the HDF5 creation order for files written with ``track_order``
        (as :func:`write_columns` does), else alphabetical. MAT variables starting with
        ``__``, a MAT char variable ``unit`` and HDF5 groups are skipped.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        For an unsupported suffix or a malformed file (ragged or non-numeric CSV, with the
        line number; non-numeric or multi-dimensional variables).
    """
    return _read(path)[0]


def read_trace(
    path: PathLike, unit: str = "", *, to_unit: str | None = None, min_samples: int = 2
) -> Trace:
    """Read a :class:`Trace` from a file with a ``time`` column (in s) and axis columns.

    Parameters
    ----------
    path : str or os.PathLike
        File to read; see :func:`read_columns`. Axes are all columns except ``time``, in
        file order.
    unit : str, optional
        Unit of the values; if empty, the unit stored in the file (or ``""``).
    to_unit : str, optional
        The unit the caller needs (a unit of :data:`microfab.io.schema.UNITS`): values
        in another unit of the same quantity are converted, of another quantity refused;
        a file that declares no unit is taken to be in ``to_unit``.
    min_samples : int, optional
        Fewest samples the caller can use (at least 2, to infer the sample time).

    Returns
    -------
    Trace
        The trace; ``t0`` and ``dt`` are inferred from ``time``.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        As for :func:`read_columns`, if ``time`` is missing or not uniform, the data are
        not a valid :class:`Trace`, there are fewer than ``min_samples`` samples, or the
        unit is unknown or of another quantity than ``to_unit``; the message names the
        file.
    """
    cols, file_unit = _read(path)
    if TIME not in cols:
        raise ValueError(f"{os.fspath(path)}: no 'time' column; columns are {list(cols)}")
    time = cols.pop(TIME)
    if time.size < max(2, min_samples):
        raise ValueError(
            f"{os.fspath(path)}: {time.size} samples; this needs at least {max(2, min_samples)}"
        )
    unit = unit or file_unit
    if to_unit is not None:
        k = unit_factor(unit, to_unit, f"{os.fspath(path)}: the trace's unit")
        cols = {name: col * k for name, col in cols.items()} if k != 1.0 else cols
        unit = to_unit
    try:
        return Trace.from_columns(time, cols, unit=unit)
    except ValueError as exc:
        raise ValueError(f"{os.fspath(path)}: {exc}") from exc


def write_trace(trace: Trace, path: PathLike) -> None:
    """Write ``trace`` atomically as ``time`` plus one column per axis.

    See :func:`write_columns` for the file layouts.

    Parameters
    ----------
    trace : Trace
        The trace to write; its unit is stored with it.
    path : str or os.PathLike
        Target file; the suffix chooses the format.
    """
    write_columns(path, trace.to_dict(), unit=trace.unit)
