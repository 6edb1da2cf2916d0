"""Tracking-error metrics: RMS, peak-to-peak, error spectra and ILC learning transients.

These are the figures of merit of seed 000 §4.1: RMS and peak-to-peak tracking errors
(Table 1), the power spectral density of the error at the harmonics of the trajectory
(Fig. 5) and the learning transient of the per-iteration RMS error (Fig. 6).

References
----------
Seed 000 (galvo-scanner micro-stereolithography with ILC), §4.1 "Tracking Performance".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal

from microfab.core.validate import check_positive

__all__ = [
    "ErrorSpectrum",
    "ErrorStats",
    "LearningTransient",
    "error_psd",
    "error_stats",
    "learning_transient",
    "peak_to_peak",
    "rms",
]

#: Relative tolerance on "the record holds an integer number of periods".
_PERIOD_REL_TOL = 1e-6
#: Longest Welch segment used when no period is given [samples].
_WELCH_MAX_NPERSEG = 4096


def _as_2d(x: np.ndarray, name: str) -> np.ndarray:
    """Return ``x`` as a finite float array of shape (n_samples, n_axes)."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, np.newaxis]
    if arr.ndim != 2:
        raise ValueError(
            f"{name} must have shape (n_samples,) or (n_samples, n_axes), got {arr.shape}"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ValueError(f"{name} must not be empty, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite; found NaN or inf")
    return arr


def rms(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """Root mean square ``sqrt(mean(x**2))`` along ``axis``.

    Parameters
    ----------
    x : np.ndarray
        Signal, shape (n_samples,) or (n_samples, n_axes), any unit.
    axis : int, optional
        Axis to average over (default 0, the samples).

    Returns
    -------
    np.ndarray
        Same unit as ``x``; 0-d for 1-D input, (n_axes,) for 2-D input with ``axis=0``.

    References
    ----------
    Seed 000 §4.1, Table 1.
    """
    arr = np.asarray(x, dtype=float)
    if arr.size == 0:
        raise ValueError("rms of an empty array is undefined (x has 0 samples)")
    return np.sqrt(np.mean(np.square(arr), axis=axis))


def peak_to_peak(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """Peak-to-peak value ``max(x) - min(x)`` along ``axis``.

    Parameters
    ----------
    x : np.ndarray
        Signal, shape (n_samples,) or (n_samples, n_axes), any unit.
    axis : int, optional
        Axis to reduce (default 0, the samples).

    Returns
    -------
    np.ndarray
        Same unit as ``x``; 0-d for 1-D input, (n_axes,) for 2-D input with ``axis=0``.

    References
    ----------
    Seed 000 §4.1, Table 1.
    """
    arr = np.asarray(x, dtype=float)
    if arr.size == 0:
        raise ValueError("peak_to_peak of an empty array is undefined (x has 0 samples)")
    return np.ptp(arr, axis=axis)


@dataclass(frozen=True)
class ErrorStats:
    """RMS and peak-to-peak of a tracking error, per axis.

    Attributes
    ----------
    rms : np.ndarray
        RMS error, shape (n_axes,), unit of the error signal.
    pp : np.ndarray
        Peak-to-peak error, shape (n_axes,), unit of the error signal.
    """

    rms: np.ndarray
    pp: np.ndarray


def error_stats(error: np.ndarray) -> ErrorStats:
    """Compute the RMS and peak-to-peak tracking error per axis.

    Parameters
    ----------
    error : np.ndarray
        Tracking error, shape (n_samples,) or (n_samples, n_axes), any unit (the seed
        reports mV). A 1-D input is treated as a single axis.

    Returns
    -------
    ErrorStats
        Per-axis statistics, each of shape (n_axes,).

    References
    ----------
    Seed 000 §4.1, Table 1.
    """
    e = _as_2d(error, "error")
    return ErrorStats(rms=rms(e, axis=0), pp=peak_to_peak(e, axis=0))


@dataclass(frozen=True)
class ErrorSpectrum:
    """One-sided power spectral density of a tracking error.

    Attributes
    ----------
    freq_hz : np.ndarray
        Frequency grid, shape (n_freq,), in Hz.
    psd : np.ndarray
        One-sided PSD, shape (n_freq, n_axes), in unit²/Hz (unit of the error signal).
    harmonic_number : np.ndarray
        Harmonic indices 1, 2, ..., shape (n_harm,), int. Empty without a period.
    harmonic_freq_hz : np.ndarray
        Fundamental ``1/period_s`` and its multiples up to Nyquist, shape (n_harm,), Hz.
    harmonic_psd : np.ndarray
        Periodogram value at each harmonic bin, shape (n_harm, n_axes), unit²/Hz.
    """

    freq_hz: np.ndarray
    psd: np.ndarray
    harmonic_number: np.ndarray
    harmonic_freq_hz: np.ndarray
    harmonic_psd: np.ndarray


def error_psd(error: np.ndarray, dt: float, period_s: float | None = None) -> ErrorSpectrum:
    """Power spectral density of a tracking error, with its values at the harmonics.

    With ``period_s`` the record must hold an integer number ``m`` of periods; a
    one-sided periodogram over the whole record with a rectangular window
    (``scipy.signal.periodogram``, ``window='boxcar'``, ``scaling='density'``) is then
    used, whose bin spacing ``1/(n·dt) = f0/m`` puts every harmonic ``k·f0`` exactly on
    bin ``k·m`` (no leakage). Without a period, Welch's method is used
    (``scipy.signal.welch``, Hann window, ``nperseg=min(n, 4096)``) and no harmonics
    are reported. No detrending is applied, so ``sum(psd) · df`` equals the mean square
    of the error (Parseval) for the periodogram.

    Parameters
    ----------
    error : np.ndarray
        Tracking error, shape (n_samples,) or (n_samples, n_axes), any unit.
    dt : float
        Sample period in s, > 0.
    period_s : float or None, optional
        Period of the trajectory in s, > 0 (seed 000: 1/rate, e.g. 2.5 ms at 400
        features/s).

    Returns
    -------
    ErrorSpectrum
        Frequency grid, PSD of shape (n_freq, n_axes), and the harmonic values.

    Raises
    ------
    ValueError
        If ``dt`` or ``period_s`` is not positive, or if ``n_samples·dt`` is not an
        integer multiple of ``period_s`` within 1e-6 relative.

    References
    ----------
    Seed 000 §4.1, Fig. 5 (PSD of the error at the harmonic frequencies).
    """
    e = _as_2d(error, "error")
    check_positive("dt", dt, "s")
    n = e.shape[0]
    fs = 1.0 / dt
    if period_s is None:
        freq, pxx = scipy.signal.welch(
            e, fs=fs, nperseg=min(n, _WELCH_MAX_NPERSEG), detrend=False, axis=0
        )
        n_axes = e.shape[1]
        return ErrorSpectrum(
            freq_hz=freq,
            psd=pxx,
            harmonic_number=np.zeros(0, dtype=int),
            harmonic_freq_hz=np.zeros(0),
            harmonic_psd=np.zeros((0, n_axes)),
        )
    check_positive("period_s", period_s, "s")
    n_periods_f = n * dt / period_s
    n_periods = round(n_periods_f)
    if n_periods < 1 or abs(n_periods_f - n_periods) > _PERIOD_REL_TOL * n_periods_f:
        raise ValueError(
            f"record length n_samples·dt = {n * dt} s holds {n_periods_f} periods of "
            f"period_s = {period_s} s; an integer number of periods is required"
        )
    freq, pxx = scipy.signal.periodogram(
        e, fs=fs, window="boxcar", scaling="density", detrend=False, axis=0
    )
    n_harm = (len(freq) - 1) // n_periods
    harmonic_number = np.arange(1, n_harm + 1)
    bins = harmonic_number * n_periods
    return ErrorSpectrum(
        freq_hz=freq,
        psd=pxx,
        harmonic_number=harmonic_number,
        harmonic_freq_hz=freq[bins],
        harmonic_psd=pxx[bins, :],
    )


@dataclass(frozen=True)
class LearningTransient:
    """Per-iteration RMS error of an iterative learning controller.

    Attributes
    ----------
    iterations : np.ndarray
        Iteration numbers 1, 2, ..., n_iter, shape (n_iter,), int.
    rms : np.ndarray
        RMS error per iteration, shape (n_iter, n_axes), unit of the error.
    final : np.ndarray
        RMS error at the last iteration, shape (n_axes,).
    reduction : np.ndarray
        ``rms[0] / rms[-1]`` per axis, shape (n_axes,), dimensionless (``inf`` where
        the final RMS is 0).

    References
    ----------
    Seed 000 §4.1, Fig. 6 and Table 1 (reduction factor up to 25.9).
    """

    iterations: np.ndarray
    rms: np.ndarray
    final: np.ndarray
    reduction: np.ndarray

    def _axes(self, axis: int | None) -> np.ndarray:
        if axis is None:
            return self.rms
        n_axes = self.rms.shape[1]
        if not -n_axes <= axis < n_axes:
            raise ValueError(f"axis must be in [{-n_axes}, {n_axes}), got {axis}")
        return self.rms[:, [axis]]

    def converged_within(self, k: int, rel_tol: float = 0.1, axis: int | None = None) -> bool:
        """Whether the RMS error has settled at its minimum from iteration ``k`` on.

        True when, for every axis considered, ``rms[i] <= (1 + rel_tol) · min(rms)``
        for all 1-based iterations ``i >= k``, the minimum being taken over all
        iterations of that axis.

        Parameters
        ----------
        k : int
            1-based iteration number, ``1 <= k <= n_iter``.
        rel_tol : float, optional
            Relative tolerance above the minimum, >= 0 (default 0.1).
        axis : int or None, optional
            Axis to test; ``None`` (default) requires all axes to have converged.
        """
        n_iter = self.rms.shape[0]
        if not 1 <= k <= n_iter:
            raise ValueError(f"k must be an iteration number in [1, {n_iter}], got {k}")
        if not rel_tol >= 0:
            raise ValueError(f"rel_tol must be >= 0, got {rel_tol}")
        r = self._axes(axis)
        bound = (1.0 + rel_tol) * r.min(axis=0)
        return bool(np.all(r[k - 1 :] <= bound))

    def convergence_iteration(self, rel_tol: float = 0.1) -> np.ndarray:
        """Smallest ``k`` with ``converged_within(k, rel_tol, axis)``, shape (n_axes,), int.

        ``n_iter + 1`` where the last iteration is still outside the band (not converged).
        """
        if not rel_tol >= 0:
            raise ValueError(f"rel_tol must be >= 0, got {rel_tol}")
        outside = self.rms > (1.0 + rel_tol) * self.rms.min(axis=0)
        n_iter = self.rms.shape[0]
        # Last iteration outside the band, +1 -> first 1-based iteration of the tail.
        last_out = np.where(outside.any(axis=0), n_iter - np.argmax(outside[::-1], axis=0), 0)
        return (last_out + 1).astype(int)

    def is_monotonic(self, noise_tol: float = 0.1, axis: int | None = None) -> bool:
        """Whether the RMS error decreases monotonically up to noise.

        True when, for every axis considered and every iteration ``i``,
        ``rms[i+1] <= rms[i] · (1 + noise_tol) + noise_floor`` with
        ``noise_floor = noise_tol · min(rms)`` of that axis.

        Parameters
        ----------
        noise_tol : float, optional
            Relative noise tolerance, >= 0 (default 0.1).
        axis : int or None, optional
            Axis to test; ``None`` (default) requires all axes to be monotonic.
        """
        if not noise_tol >= 0:
            raise ValueError(f"noise_tol must be >= 0, got {noise_tol}")
        r = self._axes(axis)
        floor = noise_tol * r.min(axis=0)
        return bool(np.all(r[1:] <= r[:-1] * (1.0 + noise_tol) + floor))


def learning_transient(rms_history: Sequence[float] | np.ndarray) -> LearningTransient:
    """Summarise the learning transient of an iterative learning controller.

    Parameters
    ----------
    rms_history : sequence of float or np.ndarray
        RMS error per iteration, shape (n_iter,) or (n_iter, n_axes), >= 0, any unit.

    Returns
    -------
    LearningTransient
        Iterations, RMS history of shape (n_iter, n_axes), final value and reduction.

    References
    ----------
    Seed 000 §4.1, Fig. 6 (RMS error over 30 iterations).
    """
    r = _as_2d(np.asarray(rms_history, dtype=float), "rms_history")
    if np.any(r < 0):
        raise ValueError(f"rms_history must be >= 0, got minimum {r.min()}")
    with np.errstate(divide="ignore", invalid="ignore"):
        reduction = r[0] / r[-1]
    return LearningTransient(
        iterations=np.arange(1, r.shape[0] + 1),
        rms=r,
        final=r[-1].copy(),
        reduction=reduction,
    )
