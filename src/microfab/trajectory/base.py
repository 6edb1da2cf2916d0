"""`Trajectory`: a time-sampled multi-axis reference with its derivatives."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.signals import Trace, check_samples
from microfab.core.validate import check_positive

__all__ = ["MAX_SAMPLES", "Trajectory"]

#: Most samples a sampled reference may hold (17 minutes at 10 kHz; about 1 GB in memory
#: with its derivatives). More means a speed or a sample rate off by orders of magnitude.
MAX_SAMPLES = 10_000_000


@dataclass(frozen=True, kw_only=True, eq=False)
class Trajectory:
    """A reference sampled uniformly in time, with optional analytic derivatives.

    Parameters
    ----------
    dt : float
        Sample time, s.
    position : array_like, shape (n, n_axes)
        Positions, m.
    velocity, acceleration, jerk : array_like, shape (n, n_axes), optional
        Analytic derivatives at the samples, m/s, m/s², m/s³. ``None`` where the
        generator does not know them; :func:`~microfab.core.limits.check_trajectory`
        then relies on finite differences of the samples.
    s : array_like, shape (n,), optional
        Path progress (arc length, m) at each sample, where the trajectory traces a path.
    axes : tuple of str
        Axis names, ``("x", "y")`` by default.
    at_rest : bool
        Whether the trajectory starts and ends at rest; the limit check then assumes
        the machine holds still before and after it. ``False`` for one period of a
        periodic reference, which the check wraps around instead.

    Raises
    ------
    ValueError
        If ``dt`` is not positive, ``position`` is not (n, n_axes) with n >= 1, a
        derivative is not shaped like ``position`` or ``s`` not (n,), or a sample is NaN
        or inf (the message names the field, the axis and the sample; the checks are
        :func:`~microfab.core.signals.check_samples`).
    """

    dt: float
    position: np.ndarray
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    jerk: np.ndarray | None = None
    s: np.ndarray | None = None
    axes: tuple[str, ...] = ("x", "y")
    at_rest: bool = True
    meta: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_positive("dt", self.dt, "s")
        pos = np.array(self.position, dtype=float)
        # No unit in the messages: a feedforward filters commands (e.g. in V) as trajectories.
        check_samples("position", pos, self.axes)
        object.__setattr__(self, "position", readonly(pos))
        for name in ("velocity", "acceleration", "jerk", "s"):
            value = getattr(self, name)
            if value is not None:
                arr = readonly(value)
                axes = None if name == "s" else self.axes
                check_samples(name, arr, axes, n_samples=pos.shape[0])
                object.__setattr__(self, name, arr)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.position.shape[0])

    @property
    def time(self) -> np.ndarray:
        """Sample times, s, starting at 0."""
        return np.arange(self.n_samples) * self.dt

    @property
    def duration(self) -> float:
        """``n_samples * dt``, s."""
        return self.n_samples * self.dt

    def to_trace(self) -> Trace:
        """The positions as a :class:`~microfab.core.signals.Trace` (unit m)."""
        return Trace(dt=self.dt, values=self.position, axes=self.axes, unit="m")

    def columns(self) -> dict[str, np.ndarray]:
        """Named columns for a CSV / HDF5 file: time, positions and known derivatives."""
        cols: dict[str, np.ndarray] = {"time": self.time}
        if self.s is not None:
            cols["s"] = self.s
        for prefix, arr in (
            ("", self.position),
            ("v", self.velocity),
            ("a", self.acceleration),
            ("j", self.jerk),
        ):
            if arr is None:
                continue
            for k, ax in enumerate(self.axes):
                cols[f"{prefix}{ax}" if prefix == "" else f"{prefix}_{ax}"] = arr[:, k]
        return cols
