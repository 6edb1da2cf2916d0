"""Periodic scan references: the square traced at constant speed (seed 000 §4)."""

from __future__ import annotations

import numpy as np

from microfab.core.validate import check_positive

__all__ = ["samples_per_period", "square_scan"]


def samples_per_period(fs_hz: float, features_per_s: float) -> int:
    """Samples in one period of a signal repeated ``features_per_s`` times per second.

    Parameters
    ----------
    fs_hz : float
        Sample rate, Hz.
    features_per_s : float
        Repetition rate, features/s (periods per second).

    Returns
    -------
    int
        ``fs_hz / features_per_s``, a whole number >= 8.

    Raises
    ------
    ValueError
        If a rate is not positive, or a period is not a whole number (>= 8) of samples.
    """
    check_positive("repetition rate", features_per_s, "features/s")
    check_positive("sample rate", fs_hz, "Hz")
    n_float = fs_hz / features_per_s
    n = round(n_float)
    if n < 8 or abs(n - n_float) > 1e-9 * n_float:
        raise ValueError(
            f"one period must be a whole number (>= 8) of samples: {fs_hz:g} Hz / "
            f"{features_per_s:g} features/s = {n_float:.6g}"
        )
    return n


def square_scan(
    features_per_s: float,
    half_sizes: tuple[float, float],
    fs_hz: float,
) -> np.ndarray:
    """One period of a square traced at constant speed, as x and y signals.

    The square is traversed counter-clockwise from the corner ``(-a, -b)``: along the
    bottom edge x ramps from ``-a`` to ``a``, then y ramps up the right edge, and so on, a
    quarter period per edge. x and y are thus trapezoidal waves a quarter period apart.

    Parameters
    ----------
    features_per_s : float
        Repetition rate, features/s (laps of the square per second); seed 000 §4 uses
        100, 200 and 400.
    half_sizes : tuple of float
        Half side lengths ``(a, b)`` in the signal's unit (seed 000 §4.3: 1 V and 1.44 V
        encoder signal for the 0.6 mm square).
    fs_hz : float
        Sample rate in Hz; ``fs_hz / features_per_s`` must be an integer number of samples.

    Returns
    -------
    numpy.ndarray
        Shape (N, 2), ``N = fs_hz / features_per_s``.

    References
    ----------
    Seed 000 §4: square trajectory, 0.6 × 0.6 mm, 100/200/400 features/s.
    """
    n = samples_per_period(fs_hz, features_per_s)
    a, b = (float(h) for h in half_sizes)
    if a <= 0 or b <= 0:
        raise ValueError(f"half sizes must be positive, got {half_sizes}")
    p = np.arange(n) / n
    x = np.select(
        [p < 0.25, p < 0.5, p < 0.75], [-a + 8 * a * p, a + 0 * p, a - 8 * a * (p - 0.5)], -a
    )
    y = np.select(
        [p < 0.25, p < 0.5, p < 0.75],
        [-b + 0 * p, -b + 8 * b * (p - 0.25), b + 0 * p],
        b - 8 * b * (p - 0.75),
    )
    return np.column_stack([x, y])
