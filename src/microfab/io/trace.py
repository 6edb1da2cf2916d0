"""CSV / MAT / HDF5 files of sampled signals (:class:`~microfab.core.signals.Trace`).

A file holds named 1-D columns of equal length: ``time`` (in s) and one column per axis.
:func:`read_columns` / :func:`write_columns` handle raw named columns; :func:`read_trace` /
:func:`write_trace` build a validated, uniformly sampled :class:`Trace` on top of them.
The format follows the suffix: ``.csv``, ``.mat`` or ``.h5`` / ``.hdf5``. All writers are
atomic (see :mod:`microfab.io.atomic`).

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


def _read_csv(path: Path) -> tuple[dict[str, np.ndarray], str]:
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
    return {name: data[:, j].copy() for j, name in enumerate(header)}, unit


def _read_mat(path: Path) -> tuple[dict[str, np.ndarray], str]:
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    try:
        raw = loadmat(path, squeeze_me=True)
    except (MatReadError, NotImplementedError, OSError, *_DAMAGED) as exc:  # cut or damaged
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: not a readable MAT file (v7.3 files are HDF5): {why}") from exc
    unit = raw.pop("unit", "") if isinstance(raw.get("unit"), str) else ""
    return {k: _column(path, k, v) for k, v in raw.items() if not k.startswith("__")}, unit


def _read_h5(path: Path) -> tuple[dict[str, np.ndarray], str]:
    h5py = _h5py()
    if not h5py.is_hdf5(path):
        raise ValueError(f"{path}: not an HDF5 file")
    try:
        with h5py.File(path, "r") as f:
            unit = f.attrs.get("unit", "")
            unit = unit.decode() if isinstance(unit, bytes) else str(unit)
            raw = {k: v[()] for k, v in f.items() if isinstance(v, h5py.Dataset)}
    except (OSError, RuntimeError, *_DAMAGED) as exc:  # HDF5's own errors on damage
        why = " ".join(str(exc).split()) or type(exc).__name__
        raise ValueError(f"{path}: damaged HDF5 file: {why}") from exc
    return {k: _column(path, k, v) for k, v in raw.items()}, unit


def _read(path: PathLike) -> tuple[dict[str, np.ndarray], str]:
    path = Path(path)
    fmt = _format(path)
    if not path.is_file():
        raise FileNotFoundError(f"trace file not found: {path}")
    return {"csv": _read_csv, "mat": _read_mat, "h5": _read_h5}[fmt](path)


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


def read_trace(path: PathLike, unit: str = "") -> Trace:
    """Read a :class:`Trace` from a file with a ``time`` column (in s) and axis columns.

    Parameters
    ----------
    path : str or os.PathLike
        File to read; see :func:`read_columns`. Axes are all columns except ``time``, in
        file order.
    unit : str, optional
        Unit of the values; if empty, the unit stored in the file (or ``""``).

    Returns
    -------
    Trace
        The trace; ``t0`` and ``dt`` are inferred from ``time``.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        As for :func:`read_columns`, if ``time`` is missing or not uniform, or the data are
        not a valid :class:`Trace`; the message names the file.
    """
    cols, file_unit = _read(path)
    if TIME not in cols:
        raise ValueError(f"{os.fspath(path)}: no 'time' column; columns are {list(cols)}")
    time = cols.pop(TIME)
    try:
        return Trace.from_columns(time, cols, unit=unit or file_unit)
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
