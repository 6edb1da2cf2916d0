"""Labelled signals: :class:`Trace` and the checks every sampled signal shares.

A sampled signal in microfab is a time base (sample time ``dt`` in s, uniform), named
channels (axes) and samples shaped (n_samples, n_axes), with a unit. :class:`Trace` is the
plain one; :class:`~microfab.trajectory.base.Trajectory` adds derivatives and path
progress; the results of a run (``SimResult``, ``Measurement``, ``Trial``) hold several
such arrays on one time base. The checks on these arrays and names are written once, here
(which class uses which, and why there is no common base class: ``docs/architecture.md``,
Signals):

- :func:`check_name`: a channel name is a letter, then letters, digits, underscores
  (valid as a CSV header, a MATLAB variable and an HDF5 dataset);
- :func:`check_unit`: a unit is a single-line string;
- :func:`check_axes`: at least one channel, valid, unique names, none called ``time``;
- :func:`check_samples`: samples shaped (n_samples, n_axes) (or (n_samples,) for one
  unnamed channel), at least one sample, all finite; the message names the channel, the
  value, its unit and the sample;
- :func:`check_time_base`: sample times that are finite, strictly increasing and uniform,
  returned as ``(t0, dt)``.

Reading and writing traces (CSV, MAT, HDF5) is :mod:`microfab.io.trace`; this module knows
no files.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.validate import check_positive

__all__ = [
    "TIME",
    "Trace",
    "check_axes",
    "check_name",
    "check_samples",
    "check_time_base",
    "check_unit",
    "period_samples",
]

#: Name of the time column; no channel may take it.
TIME = "time"
# MATLAB variable names: a letter first (scipy drops names starting with "_"), then
# letters, digits, underscores. Also safe as CSV headers and HDF5 dataset names.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
# Largest deviation of sample times from a uniform grid, relative to dt.
_UNIFORM_RTOL = 1e-6


def check_name(name: object, what: str = "axis") -> str:
    """Return ``name`` if it is a valid channel name.

    Parameters
    ----------
    name : object
        The name to check: a letter, then letters, digits and underscores.
    what : str, optional
        What the name is for the message (``"axis"``, ``"column"``).

    Returns
    -------
    str
        ``name``.

    Raises
    ------
    ValueError
        If ``name`` is not a string of that form.

    Examples
    --------
    >>> check_name("input_x")
    'input_x'
    >>> check_name("1x", "column")
    Traceback (most recent call last):
    ...
    ValueError: column name must start with a letter and contain only letters, digits and underscores, got '1x'
    """  # noqa: E501 - a doctest line
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(
            f"{what} name must start with a letter and contain only letters, digits and "
            f"underscores, got {name!r}"
        )
    return name


def check_unit(unit: object) -> str:
    """Return ``unit`` if it is a single-line string (``""`` for unknown).

    Raises
    ------
    ValueError
        If ``unit`` is not a string or holds a line break.
    """
    if not isinstance(unit, str) or "\n" in unit or "\r" in unit:
        raise ValueError(f"unit must be a single-line string, got {unit!r}")
    return unit


def check_axes(axes: str | Iterable[str]) -> tuple[str, ...]:
    """Return the channel names ``axes`` as a tuple if they are valid.

    Parameters
    ----------
    axes : str or iterable of str
        Channel names; a single string is one channel.

    Returns
    -------
    tuple of str
        The names, in order.

    Raises
    ------
    ValueError
        If there is none, a name is invalid (:func:`check_name`) or is ``"time"``, or a
        name repeats.

    Examples
    --------
    >>> check_axes("x")
    ('x',)
    >>> check_axes(["x", "y", "x"])
    Traceback (most recent call last):
    ...
    ValueError: axis names must be unique, got duplicates ['x'] in ('x', 'y', 'x')
    """
    names = (axes,) if isinstance(axes, str) else tuple(axes)
    if not names:
        raise ValueError("a signal needs at least one axis, got axes=()")
    for name in names:
        if check_name(name, "axis") == TIME:
            raise ValueError("'time' is reserved for the time column and cannot be an axis")
    if len(set(names)) != len(names):
        dups = sorted({a for a in names if names.count(a) > 1})
        raise ValueError(f"axis names must be unique, got duplicates {dups} in {names}")
    return names


def check_samples(
    name: str,
    values: np.ndarray,
    axes: Sequence[str] | None,
    *,
    n_samples: int | None = None,
    unit: str = "",
) -> None:
    """Check that ``values`` are finite samples of the channels ``axes``.

    Parameters
    ----------
    name : str
        Name of the signal for the messages (``"values"``, ``"position"``).
    values : numpy.ndarray, shape (n_samples, n_axes) or (n_samples,)
        The samples, a real array. Shape (n_samples, len(axes)) when ``axes`` is given,
        else (n_samples,) (one unnamed channel).
    axes : sequence of str or None
        Channel names, one per column; ``None`` for a 1-D signal.
    n_samples : int, optional
        Required number of samples (e.g. that of the signal ``values`` goes with);
        by default any number >= 1.
    unit : str, optional
        Unit of ``values`` for the messages.

    Raises
    ------
    ValueError
        If the shape is wrong, there is no sample, or a sample is NaN or infinite; the
        message names the signal and, for a non-finite sample, the channel, the value
        with its unit and the sample index.

    Examples
    --------
    >>> check_samples("position", np.zeros((3, 2)), ("x", "y"), unit="m")
    >>> check_samples("position", np.array([[0.0, 1.0], [np.nan, 2.0]]), ("x", "y"), unit="m")
    Traceback (most recent call last):
    ...
    ValueError: position of axis 'x' must be finite, got nan m at sample 1
    """
    rows = "n_samples" if n_samples is None else str(n_samples)
    if axes is None:
        if values.ndim != 1 or (n_samples is not None and values.shape[0] != n_samples):
            raise ValueError(f"{name} must have shape ({rows},), got shape {values.shape}")
    elif (
        values.ndim != 2
        or values.shape[1] != len(axes)
        or (n_samples is not None and values.shape[0] != n_samples)
    ):
        raise ValueError(
            f"{name} must have shape ({rows}, {len(axes)}) for axes {axes}, "
            f"got shape {values.shape}"
        )
    if values.shape[0] < 1:
        raise ValueError(f"{name} must hold at least 1 sample, got 0")
    bad = ~np.isfinite(values)
    if not bad.any():
        return
    if axes is None:
        row = int(np.flatnonzero(bad)[0])
        where, value = name, values[row]
    else:
        col = int(np.flatnonzero(bad.any(axis=0))[0])
        row = int(np.flatnonzero(bad[:, col])[0])
        where, value = f"{name} of axis {axes[col]!r}", values[row, col]
    got = f"{value} {unit}" if unit else f"{value}"
    raise ValueError(f"{where} must be finite, got {got} at sample {row}")


def check_time_base(time: np.ndarray) -> tuple[float, float]:
    """Return ``(t0, dt)`` of uniformly spaced sample times.

    Parameters
    ----------
    time : numpy.ndarray, shape (n_samples,)
        Sample times in s: finite, at least 2, strictly increasing and uniform to within
        ``1e-6 * dt``, where ``dt = (time[-1] - time[0]) / (n_samples - 1)``.

    Returns
    -------
    t0 : float
        ``time[0]`` in s.
    dt : float
        Sample time in s. Of the numbers within a few ulp of the endpoint estimate and
        its roundings to 10-16 significant digits, the one that reproduces ``time`` best
        (ties: the roundest), so that a trace written and read back gets its ``dt`` again.

    Raises
    ------
    ValueError
        If ``time`` is not 1-D, has fewer than 2 samples, is not finite, not strictly
        increasing (naming the sample) or not uniform (giving the largest deviation).

    Examples
    --------
    >>> check_time_base(0.5 + 0.1 * np.arange(4))
    (0.5, 0.1)
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
    if dev > _UNIFORM_RTOL * dt:
        raise ValueError(
            f"time must be uniformly sampled: max deviation from a uniform grid with "
            f"dt={dt!r} s is {dev!r} s (tolerance {_UNIFORM_RTOL * dt!r} s)"
        )
    return float(time[0]), dt


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

    See Also
    --------
    microfab.io.trace.read_trace, microfab.io.trace.write_trace : CSV, MAT and HDF5 files.
    """

    dt: float
    values: np.ndarray
    axes: tuple[str, ...]
    unit: str = ""
    t0: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        unit = check_unit(self.unit)
        dt, t0 = _as_float(self.dt), _as_float(self.t0)
        if dt is None or not (np.isfinite(dt) and dt > 0):
            shown = self.dt if dt is None else dt
            raise ValueError(f"dt must be a positive finite number of seconds, got {shown!r} s")
        if t0 is None or not np.isfinite(t0):
            shown = self.t0 if t0 is None else t0
            raise ValueError(f"t0 must be a finite number of seconds, got {shown!r} s")
        axes = check_axes(self.axes)
        try:
            values = np.array(self.values, dtype=np.float64, order="C", copy=True)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"values must be real numbers: {exc}") from exc
        if values.ndim == 1 and len(axes) == 1:
            values = values.reshape(-1, 1)
        check_samples("values", values, axes, unit=unit)
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
        return {TIME: self.time, **{name: self[name] for name in self.axes}}

    @classmethod
    def from_columns(
        cls, time: np.ndarray, columns: Mapping[str, np.ndarray], unit: str = ""
    ) -> Trace:
        """Build a trace from a time vector and named columns.

        Parameters
        ----------
        time : array_like, shape (n_samples,)
            Sample times in s: strictly increasing and uniform to within 1e-6 * dt, where
            ``dt = (time[-1] - time[0]) / (n_samples - 1)``; at least 2 samples (see
            :func:`check_time_base`).
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
        t0, dt = check_time_base(time)
        if not columns:
            raise ValueError("need at least one axis column besides time, got none")
        for name, col in columns.items():
            if np.shape(col) != time.shape:
                raise ValueError(
                    f"column {name!r} has shape {np.shape(col)}, time has shape {time.shape}"
                )
        values = np.column_stack([np.asarray(c, dtype=np.float64) for c in columns.values()])
        return cls(dt=dt, values=values, axes=tuple(columns), unit=unit, t0=t0)


#: Most samples one period may hold. Assumed bound of the work (a period is held in
#: memory per axis, with its memory of errors): 1e8 samples, 100 s at 1 MHz.
MAX_PERIOD_SAMPLES = 1e8


def period_samples(period_s: float, dt: float) -> int:
    """Samples in one period, refusing a period that is not a whole number of samples.

    Parameters
    ----------
    period_s : float
        Period, s.
    dt : float
        Sample time, s.

    Returns
    -------
    int
        ``period_s / dt`` (>= 2).

    Raises
    ------
    ValueError
        If either is not positive, or ``period_s / dt`` is not whole to 1e-9 (relative)
        or below 2.
    """
    check_positive("period_s", period_s, "s")
    check_positive("dt", dt, "s")
    with np.errstate(over="ignore"):
        n_float = period_s / dt
    if not n_float <= MAX_PERIOD_SAMPLES:
        raise ValueError(
            f"period_s = {period_s:g} s at dt = {dt:g} s is {n_float:.3g} samples; the most "
            f"is {MAX_PERIOD_SAMPLES:.0e}: check the unit"
        )
    n = round(n_float)
    if n < 2 or abs(n - n_float) > 1e-9 * n_float:
        raise ValueError(
            f"period_s must be a whole number (>= 2) of samples: {period_s:g} s / {dt:g} s = "
            f"{n_float:.9g} samples; choose a period that is a multiple of dt"
        )
    return n
