"""The motor-force check of a planned reference: peak and continuous (RMS) force per axis.

Seed 004 Table I gives the linear motors' peak (12 N) and continuous (3 N) force; a
reference whose inertial force ``m a`` passes either on an axis is refused before anything
is emitted (`check_force`). `microfab.trajectory.contour_laps` plans within them.
"""

from __future__ import annotations

import numpy as np

from microfab.core.limits import LimitViolation

__all__ = ["CONTINUOUS_FORCE_N", "PEAK_FORCE_N", "check_force"]

PEAK_FORCE_N = 12.0  # seed 004 Table I (experiments/seed004_laser/paper.py)
CONTINUOUS_FORCE_N = 3.0  # seed 004 Table I (experiments/seed004_laser/paper.py)


def check_force(
    acceleration: np.ndarray,
    masses_kg: tuple[float, float],
    dt: float,
    *,
    peak_n: float = PEAK_FORCE_N,
    continuous_n: float = CONTINUOUS_FORCE_N,
    axes: tuple[str, ...] = ("x", "y"),
) -> None:
    """Refuse a reference whose inertial force exceeds the motor's peak or continuous force.

    Parameters
    ----------
    acceleration : numpy.ndarray
        Reference acceleration, m/s², shape (n, n_axes).
    masses_kg : tuple of float
        Moving mass per axis, kg (the lower axis carries the upper one).
    dt : float
        Sample time, s (for the time named in the message).
    peak_n, continuous_n : float
        Peak and continuous force, N (seed 004 Table I: 12 N, 3 N).
    axes : tuple of str
        Axis names for the message.

    Raises
    ------
    LimitViolation
        Naming the axis, the time (peak) or the whole run (RMS), the value and the limit.
    """
    a = np.asarray(acceleration, dtype=float)
    for k, ax in enumerate(axes):
        f = masses_kg[k] * a[:, k]
        i = int(np.argmax(np.abs(f)))
        if abs(f[i]) > peak_n:
            raise LimitViolation(
                f"axis {ax}: force {f[i]:.4g} N (mass {masses_kg[k]:g} kg x acceleration "
                f"{a[i, k]:.4g} m/s^2) at t = {i * dt:.6g} s exceeds the peak force "
                f"{peak_n:g} N (seed 004 Table I); nothing was emitted"
            )
        rms = float(np.sqrt(np.mean(f**2)))
        if rms > continuous_n:
            raise LimitViolation(
                f"axis {ax}: RMS force {rms:.4g} N over the whole reference "
                f"(t = 0 to {(a.shape[0] - 1) * dt:.6g} s) exceeds the continuous force "
                f"{continuous_n:g} N (seed 004 Table I); nothing was emitted"
            )
