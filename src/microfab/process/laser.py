"""Switch-on of the writing laser diode: dead time plus first-order warm-up, and its compensation.

Seed 001 §2 writes the light source of its MSL prototype as a 405 nm laser diode module
with an APC and an ACC circuit and a focused spot of about 3 µm (the abstract and §5 call
it an "LED"; §2 describes a laser diode with automatic power and current control). §4.2
blames the open circles of Fig. 14 on the warm-up of that module: it "needs a few
microseconds to warm up until its power reaches the threshold for the lithography", and
leaves the fix for later ("can be compensated by software in the future").

A few microseconds cannot open the gaps of Fig. 14: on the seed's 0.15 mm circle at an
assumed 1 Hz (issue 14; the seed gives no period) the spot moves about 0.47 mm/s, so
5 µs opens 2.4 nm, far below the 3 µm spot. A visible gap needs a millisecond-scale
warm-up (or a much faster contour); the default here is 5 ms, as issue 14 assumes.

Model (all values ASSUMED, the seed gives none): after a switch-on command at ``t_on``
the optical power is::

    P(t) = 0                                              t - t_on <  delay_s
    P(t) = power_w * (1 - exp(-(t - t_on - delay_s) / rise_s))   t - t_on >= delay_s

while the command stays on; a switch-off command cuts the power at once (the diode stops
emitting within nanoseconds of its current; only the warm-up to the APC set point is
slow), and the next switch-on starts again from zero (a cold restart, the conservative
reading). Compared with an ideal laser the ramp lacks exactly ``power_w * rise_s`` of
energy after the dead time, the energy of an ideal laser switched on ``rise_s`` later:
``warmup_s = delay_s + rise_s`` is therefore the dose-equivalent dead time, and advancing
the switch-on command by it (:func:`advance_gate`) delivers, away from the ramp itself,
the dose of an ideal laser switched on at the original instant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import erfcinv, log_ndtr, ndtr

from microfab.core.signals import check_time_base
from microfab.core.validate import check_in_range, check_nonnegative, check_positive

__all__ = [
    "LaserDiode",
    "StraightClosing",
    "advance_gate",
    "as_gate",
    "straight_line_closing",
    "tail_length_m",
]


@dataclass(frozen=True, kw_only=True)
class LaserDiode:
    """Laser diode with a dead time and a first-order warm-up after each switch-on.

    Parameters
    ----------
    power_w : float
        Steady optical power at the resin in W, > 0. Default 1 mW: ASSUMED (the seed
        gives no power; a low-cost 405 nm module behind the seed's adjustable ND filter,
        §2). The cured width does not depend on it once the cure threshold is calibrated
        (:func:`microfab.process.dose.calibrate_threshold`).
    delay_s : float
        Dead time between the switch-on command and the first light in s, >= 0.
        Default 4 ms: ASSUMED (see the module notes: the seed's "few microseconds" cannot
        open the gaps of its Fig. 14).
    rise_s : float
        Time constant of the first-order rise to ``power_w`` in s, >= 0 (0: a step).
        Default 1 ms: ASSUMED, so that ``warmup_s`` is the 5 ms of issue 14.
    wavelength_m : float
        Wavelength in m, > 0 (informational). Seed 001 §2: 405 nm.

    Notes
    -----
    ``warmup_s = delay_s + rise_s`` is the dose-equivalent dead time (module notes).
    How the split between dead time and rise matters for the compensated closing point
    is measured in ``tests/process/test_dose.py``.
    """

    power_w: float = 1e-3  # assumed: the seed gives no power (module notes)
    delay_s: float = 4e-3  # assumed: ms scale implied by the gaps of seed 001 Fig. 14
    rise_s: float = 1e-3  # assumed: warm-up delay + rise = 5 ms (issue 14)
    wavelength_m: float = 405e-9  # seed 001 §2: 405 nm laser diode

    def __post_init__(self) -> None:
        check_positive("power_w", self.power_w, "W")
        check_nonnegative("delay_s", self.delay_s, "s")
        check_nonnegative("rise_s", self.rise_s, "s")
        check_positive("wavelength_m", self.wavelength_m, "m")

    @property
    def warmup_s(self) -> float:
        """Dose-equivalent dead time ``delay_s + rise_s`` in s (module notes)."""
        return self.delay_s + self.rise_s

    def time_to_fraction(self, fraction: float) -> float:
        """Time from the switch-on command until the power reaches ``fraction · power_w``.

        Parameters
        ----------
        fraction : float
            Fraction of the steady power, in (0, 1) (dimensionless).

        Returns
        -------
        float
            ``delay_s + rise_s · ln(1 / (1 - fraction))`` in s.
        """
        f = check_in_range("fraction", fraction, 0.0, 1.0, low_closed=False, high_closed=False)
        return self.delay_s + self.rise_s * math.log(1.0 / (1.0 - f))

    def power(self, t: np.ndarray, gate: np.ndarray, *, average: bool = False) -> np.ndarray:
        """Optical power for a switch command sampled with the path.

        Parameters
        ----------
        t : numpy.ndarray, shape (n_samples,)
            Sample times in s, uniform (at least 2 samples).
        gate : numpy.ndarray, shape (n_samples,)
            Switch command, bool or 0/1, held over each sample interval
            ``[t[k], t[k] + dt)`` (zero-order hold). The laser is taken as off before
            ``t[0]``: a gate already on at sample 0 switches on at ``t[0]``.
        average : bool, optional
            False (default): the power at the instants ``t[k]``. True: the mean power
            over each interval ``[t[k], t[k] + dt)``, exact for the model (what the dose
            map integrates).

        Returns
        -------
        numpy.ndarray, shape (n_samples,)
            Power in W.

        Raises
        ------
        ValueError
            If ``t`` is not a uniform time base or ``gate`` is not a 0/1 signal of the
            same length.
        """
        _, dt = check_time_base(t)
        on = as_gate(gate, int(np.size(t)))
        since = _time_since_switch_on(on, dt)  # s, from the interval start; nan where off
        p0, d, tau = self.power_w, self.delay_s, self.rise_s
        out = np.zeros(on.size)
        idx = np.flatnonzero(on)
        if idx.size == 0:
            return out
        a = since[idx]
        if not average:
            out[idx] = p0 * _ramp(a - d, tau)
            return out
        lo = np.maximum(a, d)  # lit part of the interval [a, a + dt)
        hi = a + dt
        lit = hi > lo
        energy = np.where(lit, _ramp_integral(hi - d, tau) - _ramp_integral(lo - d, tau), 0.0)
        out[idx] = p0 * energy / dt
        return out


def _ramp(s: np.ndarray, tau: float) -> np.ndarray:
    """``1 - exp(-s / tau)`` for ``s >= 0`` (1 when ``tau == 0``), 0 for ``s < 0``."""
    s = np.asarray(s, dtype=float)
    if tau == 0.0:
        return (s >= 0).astype(float)
    return np.where(s >= 0, -np.expm1(-np.maximum(s, 0.0) / tau), 0.0)


def _ramp_integral(s: np.ndarray, tau: float) -> np.ndarray:
    """``∫_0^s (1 - exp(-u / tau)) du = s - tau (1 - exp(-s / tau))`` for ``s >= 0``, in s."""
    s = np.maximum(np.asarray(s, dtype=float), 0.0)
    if tau == 0.0:
        return s
    return s + tau * np.expm1(-s / tau)


def _time_since_switch_on(on: np.ndarray, dt: float) -> np.ndarray:
    """Time in s from the last switch-on to the start of each on-interval (nan where off)."""
    k = np.arange(on.size)
    prev = np.concatenate(([False], on[:-1]))
    rise_at = np.where(on & ~prev, k, -1)
    last = np.maximum.accumulate(rise_at)
    return np.where(on, (k - last) * dt, np.nan)


def as_gate(gate: np.ndarray, n_samples: int) -> np.ndarray:
    """A switch command as a bool array, checked.

    Parameters
    ----------
    gate : numpy.ndarray, shape (n_samples,)
        bool, or numbers each 0 or 1.
    n_samples : int
        Expected length.

    Returns
    -------
    numpy.ndarray of bool, shape (n_samples,)

    Raises
    ------
    ValueError
        If the shape differs or a value is not 0/1 (NaN included); names the sample.
    """
    g = np.asarray(gate)
    if g.shape != (n_samples,):
        raise ValueError(f"gate must have shape ({n_samples},) like the time base, got {g.shape}")
    if g.dtype == bool:
        return g.copy()
    if not np.issubdtype(g.dtype, np.number):
        raise ValueError(f"gate must be bool or 0/1 numbers, got dtype {g.dtype}")
    bad = np.flatnonzero(~((g == 0) | (g == 1)))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"gate must be 0 or 1; sample {i} is {g[i]} ({bad.size} such sample(s))")
    return g == 1


def advance_gate(
    gate: np.ndarray,
    dt_s: float,
    laser: LaserDiode,
    *,
    period_s: float,
    rise_multiple: float = 1.0,
) -> np.ndarray:
    """Switch the laser on earlier by its warm-up, keeping every switch-off where it was.

    The warm-up compensation that seed 001 §4.2 leaves "to software in the future". Each
    rising edge of ``gate`` moves earlier by ``delay_s + rise_multiple · rise_s``, rounded
    to the nearest sample; falling edges stay. With ``rise_multiple = 1`` (default) the
    advance is the dose-equivalent dead time ``laser.warmup_s``: away from the ramp the
    exposure equals that of an ideal laser switched on at the original edge (module
    notes); a larger multiple over-exposes the closing point, a smaller one leaves a thin
    neck.

    The advanced part exposes the path the stage follows before the original edge. The
    gate of seed 001 opens at a contour start after a converged period (the stage is
    already on the circle), so that path is the end of the same circle; a gate that opens
    after a pause would print a dot at the pause position instead, which this function
    cannot see.

    Parameters
    ----------
    gate : numpy.ndarray, shape (n_samples,)
        Switch command, bool or 0/1, one value per sample.
    dt_s : float
        Sample time in s, > 0.
    laser : LaserDiode
        The laser whose warm-up is compensated.
    period_s : float
        Period of the contour in s, > 0. The advance must be shorter.
    rise_multiple : float, optional
        ``k`` in ``delay_s + k · rise_s``, >= 0 (dimensionless); default 1.

    Returns
    -------
    numpy.ndarray of bool, shape (n_samples,)
        The advanced switch command.

    Raises
    ------
    ValueError
        "warm-up longer than a period" if the advance is not shorter than ``period_s``;
        if an advanced switch-on would fall before sample 0 (start the trace earlier);
        on a malformed gate or a non-positive/non-finite ``dt_s`` or ``period_s``.
    """
    dt = check_positive("dt_s", dt_s, "s")
    period = check_positive("period_s", period_s, "s")
    k_rise = check_nonnegative("rise_multiple", rise_multiple)
    advance_s = laser.delay_s + k_rise * laser.rise_s
    if advance_s >= period:
        raise ValueError(
            f"warm-up longer than a period: the advance delay_s + rise_multiple*rise_s = "
            f"{advance_s:g} s is not shorter than period_s = {period:g} s; shorten the "
            f"laser's warm-up or use a longer period"
        )
    on = as_gate(gate, int(np.size(gate)))
    n_adv = round(advance_s / dt)
    out = on.copy()
    prev = np.concatenate(([False], on[:-1]))
    for i in np.flatnonzero(on & ~prev):
        start = int(i) - n_adv
        if start < 0:
            raise ValueError(
                f"advanced switch-on falls before the trace: the edge at sample {int(i)} "
                f"moves {n_adv} samples ({advance_s:g} s) earlier; start the trace at "
                f"least {advance_s:g} s before the first switch-on"
            )
        out[start:i] = True
    return out


def tail_length_m(threshold_ratio: float, spot_radius_m: float) -> float:
    """How far a cured line runs past the point where an ideal laser switches off.

    Parameters
    ----------
    threshold_ratio : float
        ``E_th / E_max`` of the line, in (0, 0.5) (dimensionless; at 0.5 or more the
        switch-off point itself is uncured).
    spot_radius_m : float
        1/e² intensity radius ``w`` of the Gaussian spot in m, > 0.

    Returns
    -------
    float
        ``δ = w / √2 · erfcinv(2 · threshold_ratio)`` in m: after a switch-off at 0 the
        centre-line dose is ``E_max · erfc(√2 x / w) / 2``. The same length is cured
        before a switch-on.
    """
    r = check_in_range(
        "threshold_ratio", threshold_ratio, 0.0, 0.5, low_closed=False, high_closed=False
    )
    w = check_positive("spot_radius_m", spot_radius_m, "m")
    return float(w / math.sqrt(2.0) * erfcinv(2.0 * r))


@dataclass(frozen=True)
class StraightClosing:
    """Cured line where a straight, constant-speed loop closes (1-D model).

    Attributes
    ----------
    x_m : numpy.ndarray, shape (n,)
        Position along the line in m; 0 is the closing point (switch-off of the loop's
        end and original switch-on of its start), the start runs towards +x.
    width_m : numpy.ndarray, shape (n,)
        Cured width in m (0 where uncured).
    gap_m : float
        Uncured length in m (0: closed).
    closing_width_m : float
        Width at ``x = 0`` in m.
    """

    x_m: np.ndarray
    width_m: np.ndarray
    gap_m: float
    closing_width_m: float


def straight_line_closing(
    laser: LaserDiode,
    *,
    speed_m_s: float,
    spot_radius_m: float,
    threshold_ratio: float,
    advance_s: float = 0.0,
) -> StraightClosing:
    """Gap and widths where a loop closes, for a straight line at constant speed.

    The loop's end (full power, switched off at ``x = 0``) and its start (switch-on
    command ``advance_s`` before the spot passes ``x = 0``, then the laser's dead time and
    rise) both lie on the line. With ``σ = w / 2`` and ``Φ`` the normal CDF, the
    centre-line dose relative to the nominal ``E_max`` is, in closed form::

        e(x) = Φ(-x/σ) + Φ((x - ξ0)/σ) - exp(-(x - ξ0)/λ + σ²/(2λ²)) Φ((x - ξ0 - σ²/λ)/σ)

    with ``ξ0 = v (delay_s - advance_s)`` where the light starts and ``λ = v · rise_s``
    (the last term is the energy the first-order rise lacks, an exponentially modified
    Gaussian; it vanishes for ``rise_s = 0``). The dose across a straight line is
    ``e(x) E_max exp(-2 y² / w²)``, so the width is ``w sqrt(2 ln(e(x) / r))`` with
    ``r = threshold_ratio``. This is the prediction the 2-D map of
    :mod:`microfab.process.dose` is checked against on a circle (curvature ``w / R``
    neglected).

    Parameters
    ----------
    laser : LaserDiode
        Dead time and rise (the power cancels).
    speed_m_s : float
        Writing speed in m/s, > 0.
    spot_radius_m : float
        1/e² radius ``w`` in m, > 0.
    threshold_ratio : float
        ``E_th / E_max`` of the nominal line, in (0, 0.5).
    advance_s : float, optional
        How much earlier the switch-on is commanded (:func:`advance_gate`), s, >= 0.

    Returns
    -------
    StraightClosing
        Widths on a grid of ``w / 400`` from ``-4 w`` to ``ξ0 + 8 (w + λ)``; the gap and
        the closing-point width.
    """
    v = check_positive("speed_m_s", speed_m_s, "m/s")
    w = check_positive("spot_radius_m", spot_radius_m, "m")
    r = check_in_range(
        "threshold_ratio", threshold_ratio, 0.0, 0.5, low_closed=False, high_closed=False
    )
    adv = check_nonnegative("advance_s", advance_s, "s")
    sigma = 0.5 * w
    xi0 = v * (laser.delay_s - adv)
    lam = v * laser.rise_s
    lo = min(-4.0 * w, xi0 - 4.0 * w)
    hi = max(xi0, 0.0) + 8.0 * (w + lam)
    h = w / 400.0
    x = lo + h * np.arange(math.ceil((hi - lo) / h) + 1)
    y = x - xi0
    e = ndtr(-x / sigma) + ndtr(y / sigma)
    if lam > 0:
        e -= np.exp(-y / lam + sigma**2 / (2 * lam**2) + log_ndtr((y - sigma**2 / lam) / sigma))
    with np.errstate(divide="ignore"):
        width = np.where(e > r, w * np.sqrt(2.0 * np.log(np.maximum(e, r) / r)), 0.0)
    i0 = int(np.argmin(np.abs(x)))
    return StraightClosing(
        x_m=x,
        width_m=width,
        gap_m=float(np.count_nonzero(e <= r) * h),
        closing_width_m=float(width[i0]),
    )
