"""The baselines of seed 002 §V: constant progress (eq. 15) and a stretched time-optimal one.

* `constant_progress`: ``r(t) = Ξ(t S / T)`` (eq. 15), the "state of practice" input at
  the optimised time ``T``. Its path speed jumps from 0 to ``S / T`` at the start and
  turns instantly at corners, so it breaks Table I's acceleration by design; it is *not*
  checked here: it is the seed's baseline and goes through the machine's set-point guard
  (the twin's guard limits it and counts the samples it changed).
* `stretched_time_optimal`: a stronger baseline, the jerk-free time-optimal command along
  the exact contour under the given limits (`microfab.trajectory.optimal.time_optimal`,
  stopping at corners), slowed uniformly to the same ``T``: ``q(t) = q_opt(t T_opt / T)``.
  Stretching time by ``k = T / T_opt ≥ 1`` divides velocities by ``k`` and accelerations
  by ``k²``, so it stays within the limits.
"""

from __future__ import annotations

import math

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.geometry.path import Path
from microfab.trajectory.optimal import time_optimal

__all__ = ["constant_progress", "stretched_time_optimal"]


def _times(duration_s: float, rate_hz: float) -> np.ndarray:
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"the duration must be positive, got {duration_s!r} s")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"the rate must be positive, got {rate_hz!r} Hz")
    n = round(duration_s * rate_hz) + 1
    return np.minimum(np.arange(n) / rate_hz, duration_s)


def constant_progress(path: Path, duration_s: float, rate_hz: float) -> np.ndarray:
    """Eq. (15) sampled at ``t = 0, 1/rate, …, T``: shape (round(T rate) + 1, 2), m."""
    t = _times(duration_s, rate_hz)
    return np.asarray(path.point(t * (path.length / duration_s)), dtype=float)


def stretched_time_optimal(
    path: Path, duration_s: float, limits: MachineLimits, rate_hz: float, n_grid: int = 1000
) -> np.ndarray:
    """The time-optimal command under ``limits`` slowed to ``duration_s`` (module doc).

    Returns
    -------
    numpy.ndarray
        Shape (round(T rate) + 1, 2), m, from rest to rest.

    Raises
    ------
    ValueError
        ``duration_s`` shorter than the time-optimal duration (both named).
    """
    t = _times(duration_s, rate_hz)
    res = time_optimal(path, limits, n_grid=n_grid, sample_rate_hz=rate_hz)
    t_opt = float(res.duration)
    if duration_s < t_opt * (1 - 1e-9):
        raise ValueError(
            f"the time-optimal command takes {t_opt:.6g} s under these limits; it cannot be "
            f"stretched to {duration_s:.6g} s"
        )
    pos = np.asarray(res.trajectory.position, dtype=float)
    ts = np.arange(pos.shape[0]) * res.trajectory.dt
    src = t * (ts[-1] / duration_s)
    return np.column_stack([np.interp(src, ts, pos[:, a]) for a in range(pos.shape[1])])
