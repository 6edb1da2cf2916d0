"""Frequency response (FRF) from an input and output record: per-period FFT and H1.

Two estimators of ``H(f) = Y(f) / U(f)`` from uniformly sampled records ``u``, ``y``
(sample time ``dt``):

* `frf_periodic` (periodic excitation such as a repeated chirp, seed 003 part 2 §1): the
  record is cut into whole periods of ``samples_per_period``; the first ``n_dropped`` are
  left out (start-up transient). On each kept period ``p`` the FFT gives ``U_p``, ``Y_p``
  on bins ``1 / period`` apart; ``H = mean_p(Y_p / U_p)`` on the excited bins. The signal
  is periodic in samples, so there is no leakage and no window. The coherence is
  ``|sum_p Y_p conj(U_p)|^2 / (sum_p |U_p|^2 sum_p |Y_p|^2)``: 1 when every period gives
  the same response, lower where noise varies from period to period.
* `frf_h1` (any record): ``H1 = P_yu / P_uu`` with ``P_yu = E[Y conj(U)]`` from
  `scipy.signal.csd` and ``P_uu`` from `scipy.signal.welch` (segments of ``nperseg``,
  a window, ``noverlap``), and the coherence ``|P_yu|^2 / (P_uu P_yy)``.

With a single period (or segment) the coherence says nothing (it is 1 by construction)
and is stored as NaN; a fit then weights every bin alike.

An estimate keeps only the excited band: the chirp's ``(f0, f1)`` when it is known
(`estimate_frf`, or ``excited_hz=``), else the range of bins whose input amplitude is at
least 5 % of the largest (``_EXCITED_REL``); inside it, bins with almost no input
(below 0.1 % of the largest, ``_USABLE_REL``) are left out rather than divided by.
`FRF.band` selects a band for a fit and refuses a band outside the excitation or above
Nyquist, and one where the coherence falls below a threshold (0.8 by default, issue 16)
over some range, naming the range.

The record `FRF` (with `CoherenceRange` and `LowCoherenceError`) is in
:mod:`.frf_response`, re-exported here.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.signal

from microfab.core.signals import check_samples
from microfab.core.validate import check_in_range, check_int, check_positive
from microfab.identify.chirp import Chirp
from microfab.identify.frf_response import _MERGE_REL as _MERGE_REL
from microfab.identify.frf_response import _METHODS as _METHODS
from microfab.identify.frf_response import FRF
from microfab.identify.frf_response import CoherenceRange as CoherenceRange
from microfab.identify.frf_response import FRFMethod as FRFMethod
from microfab.identify.frf_response import LowCoherenceError as LowCoherenceError

__all__ = [
    "FRF",
    "CoherenceRange",
    "LowCoherenceError",
    "estimate_frf",
    "frf_h1",
    "frf_periodic",
]

_EXCITED_REL = 0.05  # input amplitude (relative to the largest bin) that marks "excited"
_USABLE_REL = 1e-3  # inside the excited band, bins with less input are left out


# ------------------------------------------------------------------ estimators
def _records(u: np.ndarray, y: np.ndarray, unit: str) -> tuple[np.ndarray, np.ndarray]:
    """``u``, ``y`` as float 1-D arrays of one length, every sample finite."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    check_samples("input record", u, None)
    check_samples("output record", y, None, unit=unit)
    if u.shape != y.shape:
        raise ValueError(
            f"input and output records must have the same length, got {u.size} and {y.size}"
        )
    return u, y


def _excited(
    f: np.ndarray, amp: np.ndarray, excited_hz: tuple[float, float] | None, dt: float, rel: float
) -> tuple[np.ndarray, tuple[float, float]]:
    """Mask of the bins to keep and the excited band (given, or found from ``amp``)."""
    nyq = 0.5 / dt
    if excited_hz is not None:
        lo, hi = (float(v) for v in excited_hz)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise ValueError(f"excited_hz must be (low, high) with 0 < low < high, got {lo, hi}")
        if hi > nyq:
            raise ValueError(
                f"excited_hz upper edge {hi:g} Hz lies above the Nyquist frequency {nyq:g} Hz"
            )
        band = (f >= lo - 1e-9 * hi) & (f <= hi + 1e-9 * hi)
    else:
        big = amp[1:].max() if amp.size > 1 else 0.0
        on = np.nonzero(amp >= rel * big)[0]
        on = on[on > 0]
        if big <= 1e-9 * amp.max() or on.size == 0:  # rounding only: a constant input
            raise ValueError("the input record excites no frequency (it is constant)")
        band = np.zeros(f.size, bool)
        band[on[0] : on[-1] + 1] = True
        lo, hi = float(f[on[0]]), float(f[on[-1]])
    band[0] = False  # the mean is never a response
    ref = amp[band].max() if band.any() else 0.0
    keep = band & (amp > _USABLE_REL * ref)
    if not keep.any():
        raise ValueError(
            f"no frequency between {lo:g} and {hi:g} Hz is excited by the input record "
            f"(bins {f[1] - f[0]:g} Hz apart)"
        )
    return keep, (lo, hi)


def frf_periodic(
    u: np.ndarray,
    y: np.ndarray,
    *,
    dt: float,
    samples_per_period: int,
    n_dropped: int = 1,
    excited_hz: tuple[float, float] | None = None,
    unit: str = "",
) -> FRF:
    """FRF of a periodically excited record: FFT ratio per period, averaged (module doc).

    Parameters
    ----------
    u, y : numpy.ndarray
        Input and output records, shape (n_samples,), sampled every ``dt``. Only whole
        periods are read; samples after the last whole period are ignored.
    dt : float
        Sample time, s.
    samples_per_period : int
        Samples in one period of the excitation (>= 2).
    n_dropped : int
        Leading periods left out (start-up transient), >= 0.
    excited_hz : (float, float), optional
        The band the excitation covers, Hz (the chirp's ``f0``, ``f1``); by default
        found from the input's spectrum.
    unit : str
        Unit of the response, for labels.

    Returns
    -------
    FRF
        Method "periodic" on the excited bins (``1 / (samples_per_period dt)`` Hz
        apart), ``n_averages`` the kept periods; coherence NaN with one kept period.

    Raises
    ------
    ValueError
        NaN/inf samples (the message names the record and the sample), records of
        different lengths, a record shorter than ``n_dropped + 1`` periods, an excited
        band above Nyquist or without excitation.
    """
    dt = check_positive("dt", dt, "s")
    n = check_int("samples_per_period", samples_per_period, 2)
    n_drop = check_int("n_dropped", n_dropped, 0)
    u, y = _records(u, y, unit)
    n_whole = u.size // n
    if n_whole - n_drop < 1:
        what = "shorter than one period" if n_whole == 0 else f"{n_whole} whole periods"
        raise ValueError(
            f"the record of {u.size} samples ({u.size * dt:g} s) is {what} of {n} samples "
            f"({n * dt:g} s); with n_dropped = {n_drop} nothing is left: record at least "
            f"{(n_drop + 1) * n} samples"
        )
    rows = slice(n_drop * n, n_whole * n)
    U = np.fft.rfft(u[rows].reshape(-1, n), axis=1)
    Y = np.fft.rfft(y[rows].reshape(-1, n), axis=1)
    f = np.fft.rfftfreq(n, dt)
    amp = np.abs(U).mean(axis=0)
    keep, band = _excited(f, amp, excited_hz, dt, _EXCITED_REL)
    U, Y = U[:, keep], Y[:, keep]
    # a period that leaves an excited bin at zero gives inf/NaN there: the callers refuse
    # a response that holds them, naming the frequency, so no warning is printed first
    with np.errstate(divide="ignore", invalid="ignore"):
        h = (Y / U).mean(axis=0)
        n_avg = U.shape[0]
        if n_avg > 1:
            syu = (Y * U.conj()).sum(axis=0)
            power = (np.abs(U) ** 2).sum(axis=0) * (np.abs(Y) ** 2).sum(axis=0)
            coh = np.minimum(np.abs(syu) ** 2 / power, 1.0)
        else:
            coh = np.full(h.size, np.nan)
    return FRF(
        freq_hz=f[keep],
        response=h,
        coherence=coh,
        method="periodic",
        dt=dt,
        excited_hz=band,
        n_averages=n_avg,
        unit=unit,
    )


def frf_h1(
    u: np.ndarray,
    y: np.ndarray,
    *,
    dt: float,
    nperseg: int,
    noverlap: int | None = None,
    window: str = "hann",
    n_dropped_samples: int = 0,
    excited_hz: tuple[float, float] | None = None,
    unit: str = "",
) -> FRF:
    """H1 estimate ``P_yu / P_uu`` with its coherence (Welch averaging, module doc).

    Parameters
    ----------
    u, y : numpy.ndarray
        Input and output records, shape (n_samples,), sampled every ``dt``.
    dt : float
        Sample time, s.
    nperseg : int
        Samples per segment (>= 2); for a periodic excitation, one period.
    noverlap : int, optional
        Samples shared by consecutive segments (default ``nperseg // 2``).
    window : str
        Window of `scipy.signal.get_window` (default "hann"; "boxcar" on whole periods
        gives the per-period estimate's H1).
    n_dropped_samples : int
        Leading samples left out (start-up transient), >= 0.
    excited_hz : (float, float), optional
        The band the excitation covers, Hz; by default found from ``P_uu``.
    unit : str
        Unit of the response, for labels.

    Returns
    -------
    FRF
        Method "h1" on the excited bins (``1 / (nperseg dt)`` Hz apart); coherence NaN
        when only one segment fits.

    Raises
    ------
    ValueError
        NaN/inf samples, records of different lengths, a record shorter than one segment
        after the dropped samples, ``noverlap >= nperseg``, an excited band above Nyquist
        or without excitation.
    """
    dt = check_positive("dt", dt, "s")
    nseg = check_int("nperseg", nperseg, 2)
    nov = nseg // 2 if noverlap is None else check_int("noverlap", noverlap, 0)
    if nov >= nseg:
        raise ValueError(f"noverlap must be below nperseg = {nseg}, got {nov}")
    n_drop = check_int("n_dropped_samples", n_dropped_samples, 0)
    u, y = _records(u, y, unit)
    u, y = u[n_drop:], y[n_drop:]
    if u.size < nseg:
        raise ValueError(
            f"the record holds {u.size} samples ({u.size * dt:g} s) after the {n_drop} dropped, "
            f"shorter than one period (segment) of {nseg} samples ({nseg * dt:g} s)"
        )
    kw = {"fs": 1.0 / dt, "window": window, "nperseg": nseg, "noverlap": nov}
    f, puu = scipy.signal.welch(u, **kw)
    _, pyy = scipy.signal.welch(y, **kw)
    _, puy = scipy.signal.csd(u, y, **kw)  # E[conj(U) Y] = P_yu
    keep, band = _excited(f, np.sqrt(puu), excited_hz, dt, _EXCITED_REL)
    h = puy[keep] / puu[keep]
    n_avg = 1 + (u.size - nseg) // (nseg - nov)
    if n_avg > 1:
        coh = np.minimum(np.abs(puy[keep]) ** 2 / (puu[keep] * pyy[keep]), 1.0)
    else:
        coh = np.full(h.size, np.nan)
    return FRF(
        freq_hz=f[keep],
        response=h,
        coherence=coh,
        method="h1",
        dt=dt,
        excited_hz=band,
        n_averages=n_avg,
        unit=unit,
    )


def estimate_frf(
    chirp: Chirp,
    y: np.ndarray,
    *,
    method: Literal["periodic", "h1"] = "periodic",
    u: np.ndarray | None = None,
    window: str = "hann",
    overlap: float = 0.5,
    unit: str | None = None,
) -> FRF:
    """FRF of a chirp experiment from its recorded output.

    Parameters
    ----------
    chirp : Chirp
        The experiment (its design gives ``dt``, the period, the periods dropped and the
        excited band ``(f0, f1)``).
    y : numpy.ndarray
        Recorded output, shape (n,) with ``n <= chirp.design.n_samples``; a record cut
        short is read in the whole periods (segments) it holds, with the input cut to
        its length.
    method : {"periodic", "h1"}
        Per-period FFT ratio (default) or H1 with one-period segments.
    u : numpy.ndarray, optional
        Recorded input, if it differs from the designed ``chirp.input``.
    window : str
        Window of the H1 estimate (default "hann").
    overlap : float
        Fraction of a segment shared by consecutive H1 segments, in [0, 1).
    unit : str, optional
        Unit of the response (default ``"<unit>/<unit>"`` of the design).

    Returns
    -------
    FRF
        On the bins inside ``(f0, f1)``.
    """
    d = chirp.design
    if u is None:
        u = chirp.input[: np.asarray(y).shape[0]] if np.ndim(y) == 1 else chirp.input
    unit = f"{d.unit}/{d.unit}" if unit is None else unit
    n = d.samples_per_period
    if method == "periodic":
        return frf_periodic(
            u,
            y,
            dt=d.dt,
            samples_per_period=n,
            n_dropped=d.n_dropped,
            excited_hz=d.band_hz,
            unit=unit,
        )
    if method == "h1":
        ov = check_in_range("overlap", overlap, 0.0, 1.0, "(fraction)", high_closed=False)
        return frf_h1(
            u,
            y,
            dt=d.dt,
            nperseg=n,
            noverlap=int(ov * n),
            window=window,
            n_dropped_samples=d.n_dropped * n,
            excited_hz=d.band_hz,
            unit=unit,
        )
    raise ValueError(f"method must be 'periodic' or 'h1', got {method!r}")
