"""Figures of merit of a shaped (or unshaped) positioning axis: lag, settling, speed, vibration.

Seed 003 part 2 (Buls et al., §3) judges its input shaper by the *position lag* on a
ramp, the *settling time* of a jump and the time in which the *nominal speed* is reached
(Figs. 6-7). This module computes those numbers, and the residual vibration of a linear
command filter at a mode, in two ways:

* **from a continuous model** ``H(s) = num(s) / den(s)`` (the shaper times the axis), exactly:
  the step response is evaluated in closed form (matrix exponential of the state-space
  model, time scaled by the fastest pole so that it is well conditioned), first on a fine
  grid (ZOH recursion, exact for a step) and then refined between the grid points by
  Brent's method. ``ramp_lag`` is ``a1/a0 - b1/b0``, the first moment of the impulse
  response; it equals the delay of the output behind a ramp in steady state.
* **from sampled signals** (a twin's simulated output): `settling_time` and
  `crossing_time` read a uniformly sampled array, interpolating linearly between samples.

The speed reached on a ramp is the derivative of the ramp response, i.e. the step response
(times the ramp's slope): "time to 95 % nominal speed" is the first time the step response
reaches 95 % of its final value (`ramp_speed_time`). Settling is relative to the final value
``H(0)`` (a band of ``band * |H(0)|``), not to the command: the seed's model has
``G(0) = 1.242e11 / 1.272e11 = 0.9764`` and never enters a 2 % band around the command.

Residual vibration of a linear command filter ``S`` at a mode of natural frequency ``f``
and damping ``zeta`` (pole ``s_p = -zeta w + j w sqrt(1 - zeta^2)``, ``w = 2 pi f``) is
``V = |S(s_p)| / |S(0)|``: the amplitude of the mode's free vibration after a shaped step
over that after the plain step, both compared at the same time (the mode's term of the
response is ``S(s_p)`` times the unshaped one). A discrete filter ``S_d(z)`` that drives a
ZOH gives ``|S_d(e^{s_p dt})| / |S_d(1)|``, exactly. `microfab.control.shapers` uses
Singer and Seering's convention for impulse trains instead, which compares with a plain
step issued at the *last* impulse (an extra factor ``exp(-zeta w t_n)``); for ``zeta``
of a few percent the two agree to within ``zeta w t_n``.

Functions
---------
as_tf, series, static_gain, ramp_lag, discrete_lag
    Models as ``(num, den)`` arrays, products, DC gain, ramp lag (continuous, discrete).
step_response, step_settling_time, ramp_speed_time, step_peak
    Exact step response and its figures, for a continuous model.
settling_time, crossing_time
    The same figures on a sampled signal.
filter_vibration, band_vibration
    Residual vibration of a linear filter at a mode; its maximum over a band of frequencies.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal

import control
from microfab.core.threads import one_blas_thread
from microfab.core.validate import check_in_range, check_positive

__all__ = [
    "TransferModel",
    "as_tf",
    "band_vibration",
    "crossing_time",
    "discrete_lag",
    "filter_vibration",
    "ramp_lag",
    "ramp_speed_time",
    "series",
    "settling_time",
    "static_gain",
    "step_peak",
    "step_response",
    "step_settling_time",
]

#: A continuous SISO model: a python-control ``TransferFunction`` or ``(num, den)``
#: coefficient sequences in descending powers of ``s``.
TransferModel: TypeAlias = control.TransferFunction | tuple[Sequence[float], Sequence[float]]

_GRID_PER_UNIT = 100  # grid points per time unit 1 / (fastest pole) for the step response
_DECAY_UNITS = 40.0  # horizon: 40 time constants of the slowest pole (e^-40 ~ 4e-18)


def _trim(c: np.ndarray) -> np.ndarray:
    """Coefficients without leading zeros (at least one value)."""
    nz = np.flatnonzero(c)
    return c[nz[0] :] if nz.size else c[-1:]


def as_tf(model: TransferModel, name: str = "model") -> tuple[np.ndarray, np.ndarray]:
    """A continuous SISO model as ``(num, den)`` float arrays, descending powers of ``s``.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Continuous single-input single-output model.
    name : str
        Name of the model for the messages.

    Returns
    -------
    num, den : numpy.ndarray
        Coefficients, leading zeros removed, shapes (m + 1,) and (n + 1,).

    Raises
    ------
    ValueError
        If the model is discrete, not SISO, has non-finite coefficients, a zero
        denominator or a zero numerator.
    """
    if isinstance(model, control.TransferFunction):
        if not model.isctime(strict=True):
            raise ValueError(f"{name} must be a continuous-time model, got dt = {model.dt}")
        if model.ninputs != 1 or model.noutputs != 1:
            raise ValueError(
                f"{name} must be single-input single-output, got {model.noutputs}x{model.ninputs}"
            )
        num_in, den_in = model.num[0][0], model.den[0][0]
    else:
        try:
            num_in, den_in = model
        except (TypeError, ValueError):
            raise ValueError(
                f"{name} must be a control.TransferFunction or a (num, den) pair of "
                f"coefficient sequences, got {type(model).__name__}"
            ) from None
    num = np.atleast_1d(np.asarray(num_in, dtype=float)).ravel()
    den = np.atleast_1d(np.asarray(den_in, dtype=float)).ravel()
    for part, c in (("numerator", num), ("denominator", den)):
        if c.size == 0 or not np.all(np.isfinite(c)):
            raise ValueError(f"{name}: the {part} coefficients must be finite, got {c.tolist()}")
        if not np.any(c):
            raise ValueError(f"{name}: the {part} is zero")
    return _trim(num), _trim(den)


def series(*models: TransferModel) -> tuple[np.ndarray, np.ndarray]:
    """The product of continuous SISO models (one after the other), as ``(num, den)``.

    Parameters
    ----------
    *models : control.TransferFunction or (num, den)
        At least one model.

    Returns
    -------
    num, den : numpy.ndarray
        Coefficients of the product, no cancellation.
    """
    if not models:
        raise ValueError("series needs at least one model")
    num, den = np.array([1.0]), np.array([1.0])
    for i, m in enumerate(models):
        n, d = as_tf(m, f"model {i}")
        num, den = np.polymul(num, n), np.polymul(den, d)
    return num, den


def static_gain(model: TransferModel) -> float:
    """``H(0) = b0 / a0``.

    Raises
    ------
    ValueError
        If ``a0 = 0`` (a pole at ``s = 0``: no finite static gain).
    """
    num, den = as_tf(model)
    if den[-1] == 0.0:
        raise ValueError("the model has a pole at s = 0: no finite static gain")
    return float(num[-1] / den[-1])


def ramp_lag(model: TransferModel) -> float:
    """Position lag of the output behind a ramp in steady state, s.

    For ``H(s) = (b0 + b1 s + ...) / (a0 + a1 s + ...)`` the lag is ``a1/a0 - b1/b0``
    (``-d ln H / ds`` at ``s = 0``, the centroid of the impulse response). For the
    seed 003 model ``G`` it is ``5.773e7 / 1.272e11 = 453.9 us``; with the model-inverse
    shaper, ``G S = G(0) p^n / (s + p)^n`` and the lag is ``n / p`` (159.2 us for
    ``n = 4``, ``p = 2 pi 4000``).

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Continuous model with ``b0 != 0`` and ``a0 != 0``.

    Returns
    -------
    float
        Lag, s (negative where the output leads).
    """
    num, den = as_tf(model)
    if num[-1] == 0.0 or den[-1] == 0.0:
        raise ValueError(
            "ramp_lag needs a finite, nonzero static gain (b0 != 0 and a0 != 0), got "
            f"b0 = {num[-1]}, a0 = {den[-1]}"
        )
    b1 = num[-2] if num.size > 1 else 0.0
    a1 = den[-2] if den.size > 1 else 0.0
    return float(a1 / den[-1] - b1 / num[-1])


def discrete_lag(num_d: Sequence[float], den_d: Sequence[float], dt: float) -> float:
    """Ramp lag of a discrete filter, s: its group delay at DC.

    Parameters
    ----------
    num_d, den_d : sequence of float
        Coefficients in powers of ``z^-1`` (``scipy.signal.lfilter``'s ``b``, ``a``).
    dt : float
        Sample time, s.

    Returns
    -------
    float
        ``dt (sum k b_k / sum b_k - sum k a_k / sum a_k)``, s.
    """
    check_positive("dt", dt, "s")
    b = np.asarray(num_d, dtype=float)
    a = np.asarray(den_d, dtype=float)
    if b.sum() == 0.0 or a.sum() == 0.0:
        raise ValueError("discrete_lag needs a nonzero static gain (sum of b and of a nonzero)")
    kb, ka = np.arange(b.size), np.arange(a.size)
    return float(dt * (kb @ b / b.sum() - ka @ a / a.sum()))


@dataclass(frozen=True, eq=False)
class _Step:
    """Exact step response of a stable, proper continuous model in scaled time.

    Time is scaled by ``w0`` (the largest pole or zero magnitude): ``tau = w0 t``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: float
    w0: float
    final: float
    slowest: float  # smallest |Re(pole)| in scaled time

    @classmethod
    def of(cls, model: TransferModel) -> _Step:
        num, den = as_tf(model)
        if num.size > den.size:
            raise ValueError(
                f"the model is improper (numerator degree {num.size - 1} > denominator "
                f"degree {den.size - 1}): no step response"
            )
        poles = np.roots(den)
        if poles.size and np.max(poles.real) >= 0.0:
            raise ValueError(
                f"the model is not stable (pole at {poles[np.argmax(poles.real)]:.6g} rad/s): "
                "no settled step response"
            )
        roots = np.concatenate([poles, np.roots(num)]) if num.size > 1 else poles
        w0 = float(np.max(np.abs(roots))) if roots.size else 1.0
        w0 = w0 if w0 > 0.0 else 1.0
        # H(w0 sigma): coefficient of sigma^k gets w0^k (descending powers)
        ns = num * w0 ** np.arange(num.size - 1, -1, -1)
        ds = den * w0 ** np.arange(den.size - 1, -1, -1)
        ns, ds = ns / ds[0], ds / ds[0]
        A, B, C, D = scipy.signal.tf2ss(ns, ds)
        slowest = float(np.min(-poles.real)) / w0 if poles.size else 1.0
        d = float(np.squeeze(D)) if np.size(D) else 0.0
        return cls(A, B, C, d, w0, float(num[-1] / den[-1]), slowest)

    def at(self, t: float) -> float:
        """Step response at time ``t`` (s)."""
        n = self.A.shape[0]
        if n == 0:
            return self.D
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = self.A * (t * self.w0)
        M[:n, n] = self.B[:, 0] * (t * self.w0)
        x = scipy.linalg.expm(M)[:n, n]
        return float(self.C[0] @ x + self.D)

    def grid(self, until_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Times (s) and the exact step response on a uniform grid up to the horizon."""
        h = 1.0 / _GRID_PER_UNIT
        tau_end = _DECAY_UNITS / self.slowest if until_s is None else until_s * self.w0
        n_pts = math.ceil(tau_end / h) + 1
        n = self.A.shape[0]
        tau = np.arange(n_pts) * h
        if n == 0:
            return tau / self.w0, np.full(n_pts, self.D)
        M = np.zeros((n + 1, n + 1))
        M[:n, :n], M[:n, n] = self.A * h, self.B[:, 0] * h
        E = scipy.linalg.expm(M)
        Phi, Gam = E[:n, :n], E[:n, n]
        # states under the held step (ZOH of a constant input, exact): x_k = sum_{j<k} Phi^j Gam;
        # the terms Phi^j Gam by doubling (log2(n_pts) products), then a cumulative sum
        terms = Gam[:, None]
        power = Phi
        while terms.shape[1] < n_pts - 1:
            terms = np.hstack([terms, power @ terms])
            power = power @ power
        x = np.zeros((n, n_pts))
        np.cumsum(terms[:, : n_pts - 1], axis=1, out=x[:, 1:])
        return tau / self.w0, self.C[0] @ x + self.D

    def refine(self, f: Callable[[float], float], t_lo: float, t_hi: float) -> float:
        """The root of ``f`` between two grid times where it changes sign."""
        if f(t_lo) * f(t_hi) > 0.0:  # pragma: no cover - guarded by the grid scan
            return t_hi
        return float(scipy.optimize.brentq(f, t_lo, t_hi, xtol=1e-15, rtol=1e-13))


def step_response(model: TransferModel, times_s: np.ndarray | Sequence[float]) -> np.ndarray:
    """Exact step response of a stable, proper continuous model at given times.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Stable, proper continuous model.
    times_s : array_like
        Times after the step, s (>= 0), shape (n,).

    Returns
    -------
    numpy.ndarray
        Response at those times, shape (n,) (matrix exponential of the time-scaled
        state-space model, no integration error).
    """
    with one_blas_thread():  # small matrices: BLAS threads only cost here
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        if not np.all(np.isfinite(t) & (t >= 0.0)):
            raise ValueError("times_s must be finite and >= 0 s")
        st = _Step.of(model)
        return np.array([st.at(float(ti)) for ti in t])


def step_settling_time(model: TransferModel, *, band: float = 0.02) -> float:
    """Time after which the step response stays within ``band * |H(0)|`` of ``H(0)``, s.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Stable, proper continuous model with ``H(0) != 0``.
    band : float
        Half-width of the band relative to the final value (0.02: the 2 % band).

    Returns
    -------
    float
        Settling time, s (exact to the root finder's tolerance). Seed 003's ``G``:
        869.9 us; ``G S`` with the default inverse shaper: 361.4 us.
    """
    with one_blas_thread():  # small matrices: BLAS threads only cost here
        check_in_range("band", band, 0.0, 1.0, "(fraction of the final value)", low_closed=False)
        st = _Step.of(model)
        if st.final == 0.0:
            raise ValueError("the model's static gain is 0: no settling band")
        tol = band * abs(st.final)
        t, y = st.grid()
        outside = np.flatnonzero(np.abs(y - st.final) > tol)
        if outside.size == 0:
            return 0.0
        k = int(outside[-1])
        return st.refine(lambda s: abs(st.at(s) - st.final) - tol, float(t[k]), float(t[k + 1]))


def ramp_speed_time(model: TransferModel, *, fraction: float = 0.95) -> float:
    """First time the output speed on a ramp reaches ``fraction`` of its final speed, s.

    The output speed on a unit ramp is the step response, so this is the first time the
    step response reaches ``fraction * H(0)``. Seed 003's ``G``: 787.8 us; ``G S`` with
    the default inverse shaper: 308.5 us.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        Stable, proper continuous model with ``H(0) != 0``.
    fraction : float
        Fraction of the final speed, in (0, 1].
    """
    with one_blas_thread():  # small matrices: BLAS threads only cost here
        check_in_range("fraction", fraction, 0.0, 1.0, "(of the final speed)", low_closed=False)
        st = _Step.of(model)
        if st.final == 0.0:
            raise ValueError(
                "the model's static gain is 0: the speed never reaches a fraction of it"
            )
        level = fraction * st.final
        sign = 1.0 if st.final > 0 else -1.0
        t, y = st.grid()
        above = np.flatnonzero(sign * (y - level) >= 0.0)
        if above.size == 0:  # pragma: no cover - a stable model reaches its final value
            raise ValueError(f"the step response never reaches {fraction:g} of its final value")
        k = int(above[0])
        if k == 0:
            return 0.0
        return st.refine(lambda s: sign * (st.at(s) - level), float(t[k - 1]), float(t[k]))


def step_peak(model: TransferModel) -> tuple[float, float]:
    """Largest ``|step response|`` and when it occurs: ``(peak, t_peak_s)``.

    For a command filter this is the command peak of a unit step (the seed's inverse
    shaper: 23.66 at 19.0 us, continuous).
    """
    with one_blas_thread():  # small matrices: BLAS threads only cost here
        st = _Step.of(model)
        t, y = st.grid()
        k = int(np.argmax(np.abs(y)))
        lo, hi = float(t[max(k - 1, 0)]), float(t[min(k + 1, t.size - 1)])
        if hi <= lo:
            return float(abs(y[k])), float(t[k])
        res = scipy.optimize.minimize_scalar(
            lambda s: -abs(st.at(s)), bounds=(lo, hi), method="bounded", options={"xatol": 1e-15}
        )
        if -res.fun >= abs(y[k]):
            return float(-res.fun), float(res.x)
        return float(abs(y[k])), float(t[k])


def _signal(y: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(y, dtype=float)
    if arr.ndim != 1 or arr.size < 2:
        raise ValueError(f"{name} must be a 1-D array of at least 2 samples, got {arr.shape}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"{name} holds {arr[bad[0]]} at sample {int(bad[0])}")
    return arr


def settling_time(
    signal: np.ndarray,
    dt: float,
    *,
    final: float | None = None,
    initial: float = 0.0,
    band: float = 0.02,
) -> float:
    """Time after which a sampled step response stays within the band, s.

    Parameters
    ----------
    signal : numpy.ndarray
        Response, shape (n,), sample ``k`` at time ``k dt`` (the step at ``t = 0``).
    dt : float
        Sample time, s.
    final : float, optional
        Final value; by default the last sample.
    initial : float
        Value before the step (default 0); the band is ``band * |final - initial|``.
    band : float
        Half-width of the band relative to the step (0.02: the 2 % band).

    Returns
    -------
    float
        The time where the response last enters the band, interpolated linearly between
        the samples around it; 0 if it never leaves the band.

    Raises
    ------
    ValueError
        If the last sample lies outside the band (the record ends before settling).
    """
    check_positive("dt", dt, "s")
    check_in_range("band", band, 0.0, 1.0, "(fraction of the step)", low_closed=False)
    y = _signal(signal, "signal")
    yf = float(y[-1]) if final is None else float(final)
    tol = band * abs(yf - float(initial))
    if tol == 0.0:
        raise ValueError("final and initial values are equal: no step to settle")
    err = np.abs(y - yf) - tol
    outside = np.flatnonzero(err > 0.0)
    if outside.size == 0:
        return 0.0
    k = int(outside[-1])
    if k == y.size - 1:
        raise ValueError(
            f"the signal is still outside the {band:g} band at its last sample "
            f"(t = {k * dt:.6g} s): record longer"
        )
    # linear interpolation of |y - yf| - tol between samples k (> 0) and k + 1 (<= 0)
    frac = err[k] / (err[k] - err[k + 1])
    return float((k + frac) * dt)


def crossing_time(signal: np.ndarray, dt: float, level: float) -> float:
    """First time a sampled signal reaches ``level`` (from below or above), s.

    Parameters
    ----------
    signal : numpy.ndarray
        Samples, shape (n,), sample ``k`` at ``k dt``.
    dt : float
        Sample time, s.
    level : float
        Level to reach; the direction is taken from the first sample.

    Returns
    -------
    float
        Linearly interpolated time of the first crossing.

    Raises
    ------
    ValueError
        If the signal never reaches the level.
    """
    check_positive("dt", dt, "s")
    y = _signal(signal, "signal")
    sign = 1.0 if y[0] <= level else -1.0
    d = sign * (y - level)
    hit = np.flatnonzero(d >= 0.0)
    if hit.size == 0:
        raise ValueError(f"the signal never reaches {level:g}")
    k = int(hit[0])
    if k == 0:
        return 0.0
    return float((k - 1 + d[k - 1] / (d[k - 1] - d[k])) * dt)


def _mode_pole(freq_hz: np.ndarray, damping: float) -> np.ndarray:
    w = 2.0 * np.pi * freq_hz
    return -damping * w + 1j * w * math.sqrt(1.0 - damping * damping)


def filter_vibration(
    model: TransferModel | tuple[Sequence[float], Sequence[float]],
    freq_hz: np.ndarray | float,
    damping: float,
    *,
    dt: float | None = None,
) -> np.ndarray:
    """Residual vibration of a mode after a step through a linear command filter.

    Parameters
    ----------
    model : control.TransferFunction or (num, den)
        The filter: continuous (``dt`` None), or discrete with ``num``, ``den`` in powers
        of ``z^-1`` (``scipy.signal.lfilter``'s ``b``, ``a``) driving a ZOH at ``dt``.
    freq_hz : float or numpy.ndarray
        Natural frequencies of the mode, Hz (> 0), shape (n,).
    damping : float
        Damping ratio of the mode, in [0, 1).
    dt : float, optional
        Sample time of a discrete filter, s.

    Returns
    -------
    numpy.ndarray
        ``|S(s_p)| / |S(0)|`` (continuous) or ``|S_d(e^{s_p dt})| / |S_d(1)|``, shape (n,).
    """
    check_in_range("damping", damping, 0.0, 1.0, high_closed=False)
    f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
    if f.size == 0 or not np.all(np.isfinite(f) & (f > 0)):
        raise ValueError(f"freq_hz must be positive and finite, got {f.tolist()[:5]} Hz")
    sp = _mode_pole(f, damping)
    if dt is None:
        num, den = as_tf(model, "filter")
        dc = num[-1] / den[-1] if den[-1] != 0 else np.inf
        return np.abs(np.polyval(num, sp) / np.polyval(den, sp) / dc)
    check_positive("dt", dt, "s")
    b, a = (np.asarray(c, dtype=float).ravel() for c in model)  # type: ignore[union-attr]
    zi = np.exp(-sp * dt)  # z^-1 at the mode's pole
    hb = np.polyval(b[::-1], zi)
    ha = np.polyval(a[::-1], zi)
    return np.abs(hb / ha / (b.sum() / a.sum()))


def band_vibration(
    vibration: Callable[[np.ndarray], np.ndarray],
    freq_hz: float,
    *,
    lo: float = 0.8,
    hi: float = 1.2,
    n: int = 401,
) -> float:
    """Largest residual vibration over ``[lo f, hi f]`` (robustness to a wrong ``f``).

    Parameters
    ----------
    vibration : callable
        ``V(freq_hz array) -> array``, e.g. ``lambda f: shaper.vibration(f)`` or
        ``lambda f: filter_vibration(model, f, zeta)``.
    freq_hz : float
        Nominal frequency of the mode, Hz.
    lo, hi : float
        Band as fractions of ``freq_hz`` (default 0.8-1.2).
    n : int
        Number of evenly spaced frequencies evaluated (ends included).

    Returns
    -------
    float
        ``max V`` over the band.
    """
    check_positive("freq_hz", freq_hz, "Hz")
    check_positive("lo", lo)
    if not hi > lo:
        raise ValueError(f"hi must exceed lo, got lo = {lo}, hi = {hi}")
    if n < 2:
        raise ValueError(f"n must be at least 2, got {n}")
    f = np.linspace(lo * freq_hz, hi * freq_hz, n)
    return float(np.max(vibration(f)))
