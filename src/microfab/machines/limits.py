"""Declared machine limits and the check every emitted command must pass."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["AxisLimits", "LimitViolation", "check_command"]


class LimitViolation(ValueError):  # noqa: N818 - reads as a sentence: "raise LimitViolation"
    """A command would exceed a machine's declared position, velocity or acceleration."""


@dataclass(frozen=True, kw_only=True)
class AxisLimits:
    """Declared limits of one machine axis, in the command's unit.

    Parameters
    ----------
    position : float
        Largest allowed ``|command|`` (unit).
    velocity : float
        Largest allowed ``|d command / dt|`` (unit/s).
    acceleration : float
        Largest allowed ``|d² command / dt²|`` (unit/s²).
    unit : str
        Unit of the command, for messages.
    """

    position: float
    velocity: float
    acceleration: float
    unit: str = "V"

    def __post_init__(self) -> None:
        for name, val, suffix in (
            ("position", self.position, ""),
            ("velocity", self.velocity, "/s"),
            ("acceleration", self.acceleration, "/s^2"),
        ):
            if not (val > 0):
                raise ValueError(f"{name} limit must be positive, got {val} {self.unit}{suffix}")


def check_command(
    command: np.ndarray,
    dt: float,
    limits: Mapping[str, AxisLimits],
    axes: tuple[str, ...],
    periodic: bool = True,
) -> None:
    """Refuse a command that exceeds the declared limits.

    Velocity and acceleration are finite differences of the sampled command (wrapping
    around for a periodic command, which the machine repeats).

    Parameters
    ----------
    command : numpy.ndarray
        Command, shape (n_samples, n_axes).
    dt : float
        Sample time, s.
    limits : mapping of str to AxisLimits
        Limits per axis name; axes without an entry are refused.
    axes : tuple of str
        Axis names of the columns.
    periodic : bool
        Whether the command is one period of a repeated signal.

    Raises
    ------
    LimitViolation
        With the axis, the quantity, the peak value, the limit and the sample index.
    """
    cmd = np.asarray(command, dtype=float)
    if cmd.ndim == 1:
        cmd = cmd[:, None]
    if not np.all(np.isfinite(cmd)):
        raise LimitViolation("command holds NaN or inf; nothing was emitted")
    for a, name in enumerate(axes):
        if name not in limits:
            raise LimitViolation(f"axis {name!r} has no declared limits; nothing was emitted")
        lim = limits[name]
        x = cmd[:, a]
        xe = np.concatenate([x[-2:], x, x[:2]]) if periodic else x
        v = np.diff(xe) / dt
        acc = np.diff(xe, 2) / dt**2
        for qty, sig, bound, suffix in (
            ("position", x, lim.position, ""),
            ("velocity", v, lim.velocity, "/s"),
            ("acceleration", acc, lim.acceleration, "/s^2"),
        ):
            if sig.size == 0:
                continue
            k = int(np.argmax(np.abs(sig)))
            if abs(sig[k]) > bound:
                raise LimitViolation(
                    f"axis {name}: {qty} {sig[k]:.4g} {lim.unit}{suffix} exceeds the declared "
                    f"limit {bound:.4g} {lim.unit}{suffix} (near sample {k}); "
                    "nothing was emitted"
                )
