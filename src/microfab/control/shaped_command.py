"""Shaped commands: filter a command through a shaper and refuse it outside its field.

Split out of `microfab.control.shaping` (the model-inverse design); the classic impulse
shapers (`microfab.control.shapers`) and the inverse both end here. A shaped command is
checked before it is emitted: outside its field bounds or a machine's declared limits it
is refused (`ShapedCommandError`, naming axis, time, value and bound).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.signal

from microfab.core.limits import AxisLimits, LimitViolation, check_command
from microfab.core.validate import check_positive
from microfab.trajectory.base import Trajectory

__all__ = [
    "Bounds",
    "ShapedCommandError",
    "check_design_dt",
    "check_shaped_command",
    "filter_command",
    "shaped_trajectory",
]

#: Field bounds of a command: one ``(low, high)`` pair for every axis, or one per axis name.
Bounds = tuple[float, float] | Mapping[str, tuple[float, float]]


class ShapedCommandError(LimitViolation):
    """A shaped command leaves its field or the declared limits; nothing was emitted."""


def check_design_dt(dt: float, design_dt: float) -> None:
    """Refuse a command sample time ``dt`` (s) other than the shaper's ``design_dt`` (s)."""
    check_positive("dt", dt, "s")
    if abs(dt - design_dt) > 1e-9 * design_dt:
        raise ValueError(
            f"the command's dt = {dt} s differs from the shaper's dt = {design_dt} s: "
            "design the shaper at the command's sample time"
        )


def _axis_names(axes: Sequence[str] | None, n_axes: int) -> tuple[str, ...]:
    if axes is not None:
        names = tuple(axes)
        if len(names) != n_axes:
            raise ValueError(f"axes names {names} do not match the {n_axes} command columns")
        return names
    return ("x", "y", "z")[:n_axes] if n_axes <= 3 else tuple(f"a{i}" for i in range(n_axes))


def check_shaped_command(
    command: np.ndarray,
    dt: float,
    *,
    axes: Sequence[str] | None = None,
    bounds: Bounds | None = None,
    limits: Mapping[str, AxisLimits] | None = None,
    unit: str = "",
    periodic: bool = False,
) -> None:
    """Refuse a shaped command outside a field or a machine's declared limits.

    Parameters
    ----------
    command : numpy.ndarray
        Shaped command, shape (n,) or (n, n_axes), sample ``k`` at ``k dt``.
    dt : float
        Sample time, s.
    axes : sequence of str, optional
        Column names (default ``x``, ``y``, ``z``, or ``a0``, ...).
    bounds : (low, high) or mapping of axis to (low, high), optional
        Field per axis (one pair for all, or one per name; an axis without one is refused).
    limits : mapping of str to AxisLimits, optional
        Declared position / velocity / acceleration limits, checked by
        `microfab.core.limits.check_command`.
    unit : str
        Unit of the command for the messages.
    periodic : bool
        Whether the command is one period of a repeated one (for ``limits``).

    Raises
    ------
    ShapedCommandError
        At the first sample outside ``bounds``: names axis, time, value and bound.
    LimitViolation
        From ``check_command`` when ``limits`` are exceeded.
    """
    check_positive("dt", dt, "s")
    cmd = np.asarray(command, dtype=float)
    cmd2 = cmd[:, None] if cmd.ndim == 1 else cmd
    names = _axis_names(axes, cmd2.shape[1])
    u = f" {unit}" if unit else ""
    if not np.all(np.isfinite(cmd2)):
        k, a = np.argwhere(~np.isfinite(cmd2))[0]
        raise ShapedCommandError(
            f"axis {names[a]}: the shaped command is {cmd2[k, a]} at t = {k * dt:.6g} s "
            f"(sample {k}); nothing was emitted"
        )
    if bounds is not None:
        for a, name in enumerate(names):
            if isinstance(bounds, Mapping):
                if name not in bounds:
                    raise ShapedCommandError(f"axis {name!r} has no field bounds; nothing emitted")
                lo, hi = bounds[name]
            else:
                lo, hi = bounds
            col = cmd2[:, a]
            bad = np.flatnonzero((col < lo) | (col > hi))
            if bad.size:
                k = int(bad[0])
                side, lim = ("below the low", lo) if col[k] < lo else ("above the high", hi)
                raise ShapedCommandError(
                    f"axis {name}: the shaped command reaches {col[k]:.6g}{u} at t = "
                    f"{k * dt:.6g} s (sample {k}), {side} field bound {lim:.6g}{u} "
                    f"(peak {col[np.argmax(np.abs(col))]:.6g}{u}); lower the jump or the "
                    f"shaper's gain; nothing was emitted"
                )
    if limits is not None:
        check_command(cmd2, dt, limits, names, periodic=periodic)


def _periodic_lfilter(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Steady-state response of ``b / a`` to a periodic ``x`` (one period, columns)."""
    n = x.shape[0]
    k = np.arange(n // 2 + 1)
    zi = np.exp(-2j * np.pi * k / n)
    H = np.polyval(b[::-1], zi) / np.polyval(a[::-1], zi)
    return np.fft.irfft(H[:, None] * np.fft.rfft(x, axis=0), n=n, axis=0)


def filter_command(
    command: np.ndarray,
    b: np.ndarray,
    a: np.ndarray,
    *,
    dt: float,
    periodic: bool = False,
    tail: int = 0,
    advance: int = 0,
    axes: Sequence[str] | None = None,
    bounds: Bounds | None = None,
    limits: Mapping[str, AxisLimits] | None = None,
    unit: str = "",
) -> np.ndarray:
    """Filter each column of a command by ``b / a`` (powers of ``z^-1``) and check it.

    Non-periodic: from rest at the first sample (``x[0]`` held before), ``tail`` samples
    of the last value appended, ``y = lfilter(b, a, x - x[0]) + x[0]`` (a shaper has unit
    static gain, so a held position stays where it is). Periodic: steady state, same
    length. ``advance`` reads the output that many samples later (a preview: the command
    is known ahead; the input is held ``advance`` samples longer, or rotated when
    periodic). The other arguments are those of `InverseShaper.shape`; ``b``, ``a`` are
    ``scipy.signal.lfilter``'s coefficients.
    """
    x = np.asarray(command, dtype=float)
    one_d = x.ndim == 1
    x2 = x[:, None] if one_d else x
    if x2.ndim != 2 or x2.shape[0] < 1:
        raise ValueError(f"command must have shape (n,) or (n, n_axes), got {x.shape}")
    if not np.all(np.isfinite(x2)):
        k = int(np.argwhere(~np.isfinite(x2))[0][0])
        raise ValueError(f"command holds NaN or inf at sample {k}")
    b = np.asarray(b, dtype=float)
    a = np.asarray(a, dtype=float)
    if periodic:
        y = np.roll(_periodic_lfilter(b, a, x2), -advance, axis=0)
    else:
        extra = tail + advance
        xe = np.vstack([x2, np.repeat(x2[-1:], extra, axis=0)]) if extra else x2
        y = (scipy.signal.lfilter(b, a, xe - x2[0], axis=0) + x2[0])[advance:]
    check_shaped_command(
        y, dt, axes=axes, bounds=bounds, limits=limits, unit=unit, periodic=periodic
    )
    return y[:, 0] if one_d else y


def shaped_trajectory(
    trajectory: Trajectory,
    b: np.ndarray,
    a: np.ndarray,
    tail: int,
    name: str,
    *,
    advance: int = 0,
) -> Trajectory:
    """A trajectory's positions through the filter ``b / a`` (a `Feedforward`'s result).

    At rest: from rest, ``tail`` held samples appended; otherwise one period in steady
    state; ``advance`` as in `filter_command`. The derivatives and the path progress
    ``s`` are dropped (the shaped command is no longer a path at known speed);
    ``meta["shaper"] = name``.
    """
    pos = filter_command(
        trajectory.position,
        b,
        a,
        dt=trajectory.dt,
        periodic=not trajectory.at_rest,
        tail=tail if trajectory.at_rest else 0,
        advance=advance,
        axes=trajectory.axes,
    )
    return Trajectory(
        dt=trajectory.dt,
        position=pos,
        axes=trajectory.axes,
        at_rest=trajectory.at_rest,
        meta={**trajectory.meta, "shaper": name},
    )
