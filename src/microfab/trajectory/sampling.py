"""Constant-speed sampling of a path (seed 002 eq. 15) and periodic repetition (seed 000).

``ρ(t) = Ξ(v t)``: the state-of-practice reference that traverses the target geometry at
a constant path speed ``v = S / T``. Velocity, acceleration and jerk follow analytically
from the path's arc-length derivatives: ``v T(s)``, ``v² q''(s)``, ``v³ q'''(s)``.
"""

from __future__ import annotations

import numpy as np

from microfab.core.validate import check_positive
from microfab.geometry.path import Path
from microfab.trajectory.base import MAX_SAMPLES, Trajectory
from microfab.trajectory.periodic import samples_per_period

__all__ = ["constant_speed", "periodic"]


def _sample(path: Path, s: np.ndarray, speed: float, dt: float, at_rest: bool) -> Trajectory:
    q, d1, d2, d3 = path.evaluate(s, 3)
    v = np.float64(speed)
    with np.errstate(over="ignore", invalid="ignore"):  # overflow: refused as not finite
        acc, jerk = v**2 * d2, v**3 * d3
    return Trajectory(
        dt=dt,
        position=q,
        velocity=v * d1,
        acceleration=acc,
        jerk=jerk,
        s=s,
        at_rest=at_rest,
        meta={"generator": "constant_speed", "speed_m_s": speed},
    )


def constant_speed(
    path: Path,
    *,
    sample_rate_hz: float,
    speed: float | None = None,
    duration: float | None = None,
) -> Trajectory:
    """Sample ``ρ(t) = Ξ(v t)`` at ``sample_rate_hz`` (seed 002 eq. 15).

    Give the path speed ``speed`` (m/s) or the traversal time ``duration`` (s, then
    ``v = S / T`` as in eq. 15). The last sample lands exactly on the end of the path.

    The trajectory starts and ends at full speed, so a machine at rest before and after
    sees a velocity step: :func:`~microfab.core.limits.check_trajectory` refuses it
    under any finite acceleration limit. It is the baseline of seed 002, and the way to
    repeat a closed contour (see :func:`periodic`); use
    :func:`~microfab.trajectory.optimal.time_optimal` for a reference a machine can run
    from rest.

    Parameters
    ----------
    path : Path
        The target geometry Ξ.
    sample_rate_hz : float
        Sample rate, Hz.
    speed : float, optional
        Path speed, m/s.
    duration : float, optional
        Traversal time, s.

    Returns
    -------
    Trajectory
        Marked ``at_rest=True`` (the machine holds still before and after).

    Raises
    ------
    ValueError
        A rate, speed or duration that is not positive and finite, more than
        `MAX_SAMPLES` samples, or derivatives that overflow.
    """
    check_positive("sample_rate_hz", sample_rate_hz, "Hz")
    if (speed is None) == (duration is None):
        raise ValueError("give exactly one of speed (m/s) or duration (s)")
    L = path.length
    if speed is not None:
        check_positive("speed", speed, "m/s")
        duration = L / speed
    assert duration is not None
    check_positive("duration", duration, "s")
    count = duration * sample_rate_hz
    if not count <= MAX_SAMPLES:
        raise ValueError(
            f"{count:.3g} samples ({duration:.3g} s at {sample_rate_hz:g} Hz) is more than "
            f"the {MAX_SAMPLES:,} a reference may hold: raise the speed or lower the sample rate"
        )
    n = max(round(count) + 1, 2)
    dt = duration / (n - 1)
    v = L / duration
    s = np.linspace(0.0, L, n)
    if path.closed:
        s[-1] = np.nextafter(L, 0.0)  # stay on the last segment instead of wrapping to 0
    try:
        return _sample(path, s, v, dt, at_rest=True)
    except ValueError as exc:  # v**3 times the curvature's derivative overflowed
        raise ValueError(f"at {v:.3g} m/s the path's derivatives overflow: {exc}") from exc


def periodic(path: Path, *, features_per_s: float, sample_rate_hz: float) -> Trajectory:
    """One period of a closed path repeated at ``features_per_s`` laps per second.

    Seed 000 §4 repeats a square at 100, 200 and 400 features/s; the path speed is
    ``length × features_per_s``. One period must be a whole number of samples.

    Parameters
    ----------
    path : Path
        The closed target geometry Ξ.
    features_per_s : float
        Repetition rate, features/s (laps of the path per second).
    sample_rate_hz : float
        Sample rate, Hz; ``sample_rate_hz / features_per_s`` must be a whole number
        (>= 8) of samples.

    Returns
    -------
    Trajectory
        One period (the start is not repeated), ``at_rest=False``: the limit check wraps
        around as the machine repeats it.
    """
    if not path.closed:
        raise ValueError("periodic repetition needs a closed path")
    n = samples_per_period(sample_rate_hz, features_per_s)
    L = path.length
    speed = L * features_per_s
    s = np.arange(n) * (L / n)
    return _sample(path, s, speed, 1.0 / sample_rate_hz, at_rest=False)
