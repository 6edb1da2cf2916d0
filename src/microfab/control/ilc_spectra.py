"""Spectral helpers of the frequency-domain ILC's update (`microfab.control.ilc`).

The lag of the first trial's output behind its input (the default time advance of the
P-type law, `_lag_s`), the noise floor of an output spectrum with content in every bin
(`_noise_from_top`), and the message refusing an update that overflows
(`_overflow_message`). Small array functions kept apart from the learner
`~microfab.control.ilc.FrequencyILC`, which uses them.
"""

from __future__ import annotations

import numpy as np

__all__: list[str] = []


def _lag_s(u: np.ndarray, Y: np.ndarray, dt: float) -> float:
    """Lag of the output behind the input, s (circular cross-correlation, all axes)."""
    U = np.fft.rfft(np.asarray(u, dtype=float) - np.mean(u, axis=0), axis=0)
    Yc = Y.copy()
    Yc[0] = 0.0
    xc = np.fft.irfft(np.sum(Yc * np.conj(U), axis=1), n=u.shape[0])
    lag = int(np.argmax(xc))
    if lag > u.shape[0] // 2:  # a lead is not a lag of a causal machine
        lag = 0
    return lag * dt


def _noise_from_top(y1: np.ndarray, band: np.ndarray) -> float | None:
    """RMS noise magnitude of one axis's output bins, from the top quarter of the spectrum.

    Used when the input has content in (nearly) every bin, so that no empty bin shows the
    noise. Far above the loop's bandwidth a closed loop passes almost nothing of its
    input, so the output there is mostly noise; the median magnitude of those bins, times
    ``1 / sqrt(ln 2)`` (median to RMS of a Rayleigh magnitude), estimates the noise RMS and
    is robust to a resonance peak. Signal left there only raises the estimate, which
    learns fewer harmonics, never more. None when there are fewer than 8 such bins.
    """
    n = y1.size
    top = np.zeros(n, bool)
    top[(3 * n) // 4 :] = True
    top &= ~band
    top[-1] = False  # the Nyquist bin of an even length is real-valued
    if top.sum() < 8:
        return None
    return float(np.median(np.abs(y1[top])) / np.sqrt(np.log(2.0)))


def _overflow_message(u: np.ndarray, y: np.ndarray) -> str:
    with np.errstate(over="ignore", invalid="ignore"):
        scale = max(float(np.max(np.abs(u))), float(np.max(np.abs(y))))
    return (
        f"the learning update overflows: the trial's signals reach {scale:.3g}, too large "
        "to learn from (wrong unit or a corrupt value?)"
    )
