"""Argument checks shared by the parameter dataclasses and functions.

Every check raises :class:`ValueError` with a message that names the parameter, the
value given and its unit, and returns the value converted (``float``, or ``int`` for
:func:`check_int`) so that a call site can write ``x = check_positive("x", x, "m")``.

A number is an ``int``, a ``float`` or a NumPy real scalar (any :class:`numbers.Real`);
``bool`` (and ``numpy.bool_``), strings, ``None`` and arrays are refused with a
``ValueError`` rather than read as numbers. NaN and infinite values are refused by
every check (:func:`check_in_range` takes finite bounds).

Examples
--------
>>> check_positive("dwell_s", 30e-6, "s")
3e-05
>>> check_positive("dwell_s", -1.0, "s")
Traceback (most recent call last):
...
ValueError: dwell_s must be positive and finite, got -1.0 s
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

__all__ = [
    "check_axis_pair",
    "check_finite",
    "check_in_range",
    "check_int",
    "check_nonnegative",
    "check_positive",
    "replace_known",
]


def _got(value: object, unit: str) -> str:
    """``"got <value> <unit>"``: numbers as printed, anything else as its repr."""
    shown = str(value) if isinstance(value, numbers.Number) else repr(value)
    return f"got {shown} {unit}".rstrip()


def _real(name: str, value: object, unit: str) -> float:
    """``value`` as a float if it is a real number (not a bool), else ``ValueError``."""
    # numpy.bool_ is no numbers.Real; bool is (a subclass of int) and is refused here.
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        where = f" in {unit}" if unit else ""
        raise ValueError(f"{name} must be a number{where}, got {value!r}")
    return float(value)


def check_finite(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as a float if it is a finite number.

    Parameters
    ----------
    name : str
        Parameter name (or short description) for the message.
    value : float
        The value to check; ``int``, ``float`` or a NumPy real scalar.
    unit : str, optional
        Unit of ``value`` for the message (default none).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    ValueError
        If ``value`` is not a number (``bool`` included), NaN or infinite; the message
        names ``name``, ``value`` and ``unit``.

    Examples
    --------
    >>> check_finite("t0_s", -2e-6, "s")
    -2e-06
    >>> check_finite("t0_s", float("nan"), "s")
    Traceback (most recent call last):
    ...
    ValueError: t0_s must be finite, got nan s
    """
    v = _real(name, value, unit)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, {_got(value, unit)}")
    return v


def check_positive(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as a float if it is finite and > 0.

    Parameters
    ----------
    name : str
        Parameter name (or short description) for the message.
    value : float
        The value to check; ``int``, ``float`` or a NumPy real scalar.
    unit : str, optional
        Unit of ``value`` for the message (default none).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    ValueError
        If ``value`` is not a number (``bool`` included), NaN, infinite or <= 0; the
        message names ``name``, ``value`` and ``unit``.

    Examples
    --------
    >>> check_positive("dwell_s", 30e-6, "s")
    3e-05
    >>> check_positive("sample_rate_hz", 0, "Hz")
    Traceback (most recent call last):
    ...
    ValueError: sample_rate_hz must be positive and finite, got 0 Hz
    >>> check_positive("gain_ratio", float("inf"))
    Traceback (most recent call last):
    ...
    ValueError: gain_ratio must be positive and finite, got inf
    """
    v = _real(name, value, unit)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be positive and finite, {_got(value, unit)}")
    return v


def check_nonnegative(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as a float if it is finite and >= 0.

    Parameters
    ----------
    name : str
        Parameter name (or short description) for the message.
    value : float
        The value to check; ``int``, ``float`` or a NumPy real scalar.
    unit : str, optional
        Unit of ``value`` for the message (default none).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    ValueError
        If ``value`` is not a number (``bool`` included), NaN, infinite or < 0; the
        message names ``name``, ``value`` and ``unit``.

    Examples
    --------
    >>> check_nonnegative("relaxation_time_s", 0.0, "s")
    0.0
    >>> check_nonnegative("blur_px", -0.5, "px")
    Traceback (most recent call last):
    ...
    ValueError: blur_px must be non-negative and finite, got -0.5 px
    """
    v = _real(name, value, unit)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be non-negative and finite, {_got(value, unit)}")
    return v


def check_in_range(
    name: str,
    value: float,
    low: float,
    high: float,
    unit: str = "",
    *,
    low_closed: bool = True,
    high_closed: bool = True,
) -> float:
    """Return ``value`` as a float if it lies in the interval from ``low`` to ``high``.

    Parameters
    ----------
    name : str
        Parameter name (or short description) for the message.
    value : float
        The value to check; ``int``, ``float`` or a NumPy real scalar.
    low, high : float
        Finite bounds of the interval, ``low < high``.
    unit : str, optional
        Unit of ``value`` (and the bounds) for the message (default none).
    low_closed, high_closed : bool, optional
        Whether ``low`` (``high``) itself is allowed (default both: ``[low, high]``).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    ValueError
        If ``value`` is not a number (``bool`` included), NaN, or outside the interval
        (so never infinite); the message names ``name``, the interval, ``value`` and
        ``unit``.

    Examples
    --------
    >>> check_in_range("final_ratio", 0.5, 0.0, 1.0, low_closed=False)
    0.5
    >>> check_in_range("margin", 0.5, 0.0, 0.5, "(fraction)", high_closed=False)
    Traceback (most recent call last):
    ...
    ValueError: margin must lie in [0, 0.5), got 0.5 (fraction)
    """
    v = _real(name, value, unit)
    above = v >= low if low_closed else v > low
    below = v <= high if high_closed else v < high
    if not (above and below):
        interval = f"{'[' if low_closed else '('}{low:g}, {high:g}{']' if high_closed else ')'}"
        raise ValueError(f"{name} must lie in {interval}, {_got(value, unit)}")
    return v


def check_int(name: str, value: int, minimum: int, unit: str = "") -> int:
    """Return ``value`` as an int if it is an integer >= ``minimum``.

    Parameters
    ----------
    name : str
        Parameter name (or short description) for the message.
    value : int
        The value to check; ``int`` or a NumPy integer scalar (``bool`` and floats,
        even whole ones, are refused).
    minimum : int
        Smallest allowed value.
    unit : str, optional
        Unit of ``value`` for the message (default none).

    Returns
    -------
    int
        ``int(value)``.

    Raises
    ------
    ValueError
        If ``value`` is not an integer or is below ``minimum``; the message names
        ``name``, ``minimum``, ``value`` and ``unit``.

    Examples
    --------
    >>> check_int("width_px", 64, 2, "px")
    64
    >>> check_int("width_px", 1.0, 2, "px")
    Traceback (most recent call last):
    ...
    ValueError: width_px must be an integer >= 2, got 1.0 px
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, {_got(value, unit)}")
    return int(value)


def check_axis_pair(
    name: str, value: Any, unit: str, check: Callable[[str, Any, str], float]
) -> tuple[float, float]:
    """A per-axis pair ``(x, y)``, each value passed through ``check``.

    Parameters
    ----------
    name : str
        Parameter name for the messages (``name[x]``, ``name[y]``).
    value : tuple, list or numpy.ndarray
        Two values, x then y.
    unit : str
        Unit for the messages.
    check : callable
        ``check(name, value, unit) -> float``, e.g. `check_positive`.

    Raises
    ------
    ValueError
        ``value`` is not a pair, or ``check`` refuses one of its values.

    Examples
    --------
    >>> check_axis_pair("mass_kg", (1.5, 0.5), "kg", check_positive)
    (1.5, 0.5)
    """
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
        raise ValueError(
            f"{name} needs one value per axis (x, y), got {value!r} {unit}; give a pair"
        )
    return (check(f"{name}[x]", value[0], unit), check(f"{name}[y]", value[1], unit))


def replace_known(obj: T, what: str, **changes: Any) -> T:
    """A copy of the dataclass ``obj`` with ``changes``, validated by its ``__post_init__``.

    Parameters
    ----------
    obj : dataclass instance
        The parameters to copy.
    what : str
        What they are, for the message (``"unknown <what> parameter(s) ..."``).
    **changes
        Field values to replace.

    Raises
    ------
    ValueError
        A name that is not a field (naming the known ones), or a value the class refuses.
    """
    import dataclasses

    known = {f.name for f in dataclasses.fields(obj)}  # type: ignore[arg-type]
    unknown = sorted(set(changes) - known)
    if unknown:
        raise ValueError(
            f"unknown {what} parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
        )
    return dataclasses.replace(obj, **changes)  # type: ignore[type-var]
