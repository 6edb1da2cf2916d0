"""`Trajectory`: a time-sampled multi-axis reference with its derivatives."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.validate import check_positive
from microfab.io.trace import Trace

__all__ = ["MAX_SAMPLES", "Trajectory"]

#: Most samples a sampled reference may hold (17 minutes at 10 kHz; about 1 GB in memory
#: with its derivatives). More means a speed or a sample rate off by orders of magnitude.
MAX_SAMPLES = 10_000_000


def _readonly(a: np.ndarray | None, shape: tuple[int, ...], name: str) -> np.ndarray | None:
    if a is None:
        return None
    arr = readonly(a)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} holds NaN or inf")
    return arr


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
        if pos.ndim != 2 or pos.shape[1] != len(self.axes) or pos.shape[0] < 1:
            raise ValueError(f"position must have shape (n, {len(self.axes)}), got {pos.shape}")
        shape = pos.shape
        object.__setattr__(self, "position", _readonly(pos, shape, "position"))
        for name in ("velocity", "acceleration", "jerk"):
            object.__setattr__(self, name, _readonly(getattr(self, name), shape, name))
        object.__setattr__(self, "s", _readonly(self.s, (shape[0],), "s"))

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
        """The positions as a :class:`~microfab.io.trace.Trace` (unit m)."""
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
