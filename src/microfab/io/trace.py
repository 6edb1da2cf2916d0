"""Sampled multi-axis signals (:class:`Trace`) and their CSV / MAT / HDF5 files.

A file holds named 1-D columns of equal length: ``time`` (in s) and one column per axis.
:func:`read_columns` / :func:`write_columns` handle raw named columns; :func:`read_trace` /
:func:`write_trace` build a validated, uniformly sampled :class:`Trace` on top of them.
The format follows the suffix: ``.csv``, ``.mat`` or ``.h5`` / ``.hdf5``. All writers are
atomic (see :mod:`microfab.io.atomic`).
"""

from __future__ import annotations

import dataclasses
import io
import os
import re
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.atomic import atomic_path, atomic_write_text

__all__ = ["Trace", "read_columns", "read_trace", "write_columns", "write_trace"]

PathLike = str | os.PathLike[str]
_FORMATS = {".csv": "csv", ".mat": "mat", ".h5": "h5", ".hdf5": "h5"}
# MATLAB variable names: a letter first (scipy drops names starting with "_"), then
# letters, digits, underscores. Also safe as CSV headers and HDF5 dataset names.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
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


def _check_name(name: object, what: str) -> str:
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(
            f"{what} name must start with a letter and contain only letters, digits and "
            f"underscores, got {name!r}"
        )
    return name


def _check_unit(unit: object) -> str:
    if not isinstance(unit, str) or "\n" in unit or "\r" in unit:
        raise ValueError(f"unit must be a single-line string, got {unit!r}")
    return unit


@dataclass(frozen=True, kw_only=True, eq=False)
class Trace:
    """A uniformly sampled multi-axis signal.

    Parameters
    ----------
    dt : float
        Sample time in s, positive and finite.
    values : array_like, shape (n_samples, n_axes)
        Samples, finite. Copied to a read-only float64 array. A 1-D array is accepted
        when there is one axis and becomes shape (n_samples, 1).
    axes : tuple of str
        Unique axis names (a letter, then letters, digits, underscores; not ``time``).
    unit : str, optional
        Unit of ``values``, e.g. ``"m"`` or ``"V"``; empty if unknown.
    t0 : float, optional
        Time of the first sample in s, 0 by default.

    Raises
    ------
    ValueError
        If any field is invalid; the message names the quantity, the value and its unit.
    """

    dt: float
    values: np.ndarray
    axes: tuple[str, ...]
    unit: str = ""
    t0: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        unit = _check_unit(self.unit)
        dt, t0 = _as_float(self.dt), _as_float(self.t0)
        if dt is None or not (np.isfinite(dt) and dt > 0):
            shown = self.dt if dt is None else dt
            raise ValueError(f"dt must be a positive finite number of seconds, got {shown!r} s")
        if t0 is None or not np.isfinite(t0):
            shown = self.t0 if t0 is None else t0
            raise ValueError(f"t0 must be a finite number of seconds, got {shown!r} s")
        axes = (self.axes,) if isinstance(self.axes, str) else tuple(self.axes)
        if not axes:
            raise ValueError("a Trace needs at least one axis, got axes=()")
        for name in axes:
            if _check_name(name, "axis") == "time":
                raise ValueError("'time' is reserved for the time column and cannot be an axis")
        if len(set(axes)) != len(axes):
            dups = sorted({a for a in axes if axes.count(a) > 1})
            raise ValueError(f"axis names must be unique, got duplicates {dups} in {axes}")
        try:
            values = np.array(self.values, dtype=np.float64, order="C", copy=True)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"values must be real numbers: {exc}") from exc
        if values.ndim == 1 and len(axes) == 1:
            values = values.reshape(-1, 1)
        if values.ndim != 2 or values.shape[1] != len(axes):
            raise ValueError(
                f"values must have shape (n_samples, {len(axes)}) for axes {axes}, "
                f"got shape {values.shape}"
            )
        if values.shape[0] < 1:
            raise ValueError("values must hold at least 1 sample, got 0")
        bad = ~np.isfinite(values)
        if bad.any():
            col = int(np.flatnonzero(bad.any(axis=0))[0])
            row = int(np.flatnonzero(bad[:, col])[0])
            raise ValueError(
                f"values of axis {axes[col]!r} must be finite, got {values[row, col]} {unit} "
                f"at sample {row}"
            )
        values.setflags(write=False)
        for field, value in (("dt", dt), ("t0", t0), ("axes", axes), ("values", values)):
            set_(self, field, value)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Trace):
            return NotImplemented
        return (self.dt, self.t0, self.axes, self.unit) == (
            other.dt,
            other.t0,
            other.axes,
            other.unit,
        ) and np.array_equal(self.values, other.values)

    def __hash__(self) -> int:
        # + 0.0 maps -0.0 to 0.0, which compare equal
        return hash((self.dt, self.t0, self.axes, self.unit, (self.values + 0.0).tobytes()))

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return self.values.shape[0]

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return self.values.shape[1]

    @property
    def time(self) -> np.ndarray:
        """Sample times ``t0 + dt * k`` in s, shape (n_samples,)."""
        return self.t0 + self.dt * np.arange(self.n_samples)

    @property
    def duration(self) -> float:
        """Duration ``n_samples * dt`` in s."""
        return self.n_samples * self.dt

    @property
    def fs(self) -> float:
        """Sampling frequency ``1 / dt`` in Hz."""
        return 1.0 / self.dt

    def __getitem__(self, name: str) -> np.ndarray:
        """Return the read-only samples of axis ``name``, shape (n_samples,)."""
        try:
            return self.values[:, self.axes.index(name)]
        except ValueError:
            raise KeyError(f"no axis {name!r}; available axes: {list(self.axes)}") from None

    def select(self, *names: str) -> Trace:
        """Return a trace with only the axes ``names``, in that order.

        Raises
        ------
        KeyError
            If a name is not an axis.
        """
        if not names:
            raise ValueError("select() needs at least one axis name")
        cols = [self[name] for name in names]
        return dataclasses.replace(self, values=np.column_stack(cols), axes=names)

    def with_values(self, values: np.ndarray) -> Trace:
        """Return a trace with new ``values`` and the same dt, t0, axes and unit."""
        return dataclasses.replace(self, values=values)

    def to_dict(self) -> dict[str, np.ndarray]:
        """Return ``{"time": time, axis: samples, ...}``, 1-D arrays in s and ``unit``."""
        return {"time": self.time, **{name: self[name] for name in self.axes}}

    @classmethod
    def from_columns(
        cls, time: np.ndarray, columns: Mapping[str, np.ndarray], unit: str = ""
    ) -> Trace:
        """Build a trace from a time vector and named columns.

        Parameters
        ----------
        time : array_like, shape (n_samples,)
            Sample times in s: strictly increasing and uniform to within 1e-6 * dt, where
            ``dt = (time[-1] - time[0]) / (n_samples - 1)``; at least 2 samples.
        columns : Mapping of str to array_like, shape (n_samples,)
            One column per axis; the mapping order is the axis order.
        unit : str, optional
            Unit of the columns.

        Raises
        ------
        ValueError
            If time is not 1-D, too short, not increasing or not uniform, or if a column
            length differs from that of time.
        """
        time = np.asarray(time, dtype=np.float64)
        if time.ndim != 1 or time.size < 2 or not np.isfinite(time).all():
            raise ValueError(f"time must be a finite 1-D array of >= 2 samples, got {time.shape}")
        steps = np.diff(time)
        if (steps <= 0).any():
            k = int(np.flatnonzero(steps <= 0)[0])
            a, b = float(time[k]), float(time[k + 1])
            raise ValueError(
                f"time must be strictly increasing, got {a!r} s then {b!r} s at sample {k + 1}"
            )
        dt, dev = _infer_dt(time)
        if dev > 1e-6 * dt:
            raise ValueError(
                f"time must be uniformly sampled: max deviation from a uniform grid with "
                f"dt={dt!r} s is {dev!r} s (tolerance {1e-6 * dt!r} s)"
            )
        if not columns:
            raise ValueError("need at least one axis column besides time, got none")
        for name, col in columns.items():
            if np.shape(col) != time.shape:
                raise ValueError(
                    f"column {name!r} has shape {np.shape(col)}, time has shape {time.shape}"
                )
        values = np.column_stack([np.asarray(c, dtype=np.float64) for c in columns.values()])
        return cls(dt=dt, values=values, axes=tuple(columns), unit=unit, t0=float(time[0]))

    def save(self, path: PathLike) -> None:
        """Write the trace to ``path`` atomically; see :func:`write_trace`."""
        write_trace(self, path)

    @classmethod
    def load(cls, path: PathLike, unit: str = "") -> Trace:
        """Read a trace from ``path``; see :func:`read_trace`."""
        return read_trace(path, unit=unit)


def _infer_dt(time: np.ndarray) -> tuple[float, float]:
    # The endpoint estimate is off by an ulp or so; also try it rounded to fewer digits and
    # its float neighbours, and keep the one that best reproduces `time` (ties: roundest),
    # so that a trace written and read back gets exactly its dt again.
    est = float((time[-1] - time[0]) / (time.size - 1))
    cands = [float(f"{est:.{d}g}") for d in range(10, 17)] + [est]
    cands += [est + k * float(np.spacing(est)) for k in (-2, -1, 1, 2)]
    k = np.arange(time.size)
    devs = [float(np.max(np.abs(time - (time[0] + c * k)))) for c in cands]
    best = int(np.argmin(devs))
    return float(cands[best]), devs[best]


def _as_float(x: Any) -> float | None:
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


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
    unit = _check_unit(unit)
    cols = {_check_name(k, "column"): np.asarray(v, dtype=np.float64) for k, v in columns.items()}
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
    if "time" not in cols:
        raise ValueError(f"{os.fspath(path)}: no 'time' column; columns are {list(cols)}")
    time = cols.pop("time")
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
