"""Laser autofocus by sliding-mode optimisation (seed 004 §III-B, eqs. 16-17).

The focus search moves the z stage (command: velocity, m/s) so that a detector output
``y`` that is smallest at focus reaches its minimum, with no model of ``y(z)``. Seed 004
builds it on the sliding-mode optimisation of Utkin [24] as used in [23], and replaces
the discontinuous sign and relay functions by continuous ones (eqs. 16-17) to end the
chattering about the minimum. The seed gives neither the law nor its constants; ours:

* a reference ``r`` on the output falls at the rate ``ρ`` (``ṙ = −ρ``); ``σ = y − r``;
* while the output falls at least as fast as ``r`` (``σ < 0``) the stage keeps its
  direction ``d``; where it does not (``σ > 0``) the motion reverses:

  ``u = V d (2 v(σ) − 1)``,

  with ``v`` the relay of eq. 17. In the continuous law ``v`` is eq. 17 with the line
  ``m σ + b`` on ``[−h, h]``; continuity at ``±h`` (``v(−h) = 1``, ``v(h) = 0``) fixes
  ``m = −1/(2h)``, ``b = 1/2``, and then ``2 v(σ) − 1 = χ(−σ)``, the continuous sign of
  eq. 16: the speed falls linearly to zero as ``σ`` rises to 0 and the reverse speed
  grows to ``V`` at ``σ = h``. In the discontinuous law (the baseline) ``v`` is the bare
  relay, 1 for ``σ < 0`` and 0 for ``σ >= 0``: ``u = V d sgn(−σ)``;
* the direction register ``d`` is a relay with hysteresis ``h``: when ``σ`` reaches
  ``+h`` (the output has stopped falling with ``r`` by ``h``) ``d`` takes the reversed
  direction, and ``r`` is pulled up to ``y + h`` (``σ = −h``), which re-arms it. The
  command is unchanged by the switch (``V d χ(−h) = V (−d) χ(h)``), so the continuous
  law stays continuous;
* ``r`` is also pulled down to ``y + h`` whenever the output falls faster than it
  (``σ < −h``), so that a stall is noticed within ``2h / ρ`` whatever the descent before.

Far from focus the output falls much faster than ``ρ`` and the stage runs at ``V``
towards focus; near the minimum the output cannot keep up with ``r`` and the search
keeps oscillating in a band about the minimum, reversing each time the output has
risen relative to the falling reference. The discontinuous law reverses at the full
speed ``±V``, and a stage with a velocity lag ``τ`` runs on by about ``V τ`` each time:
a limit cycle of some ``2 V τ`` peak to peak about focus (plus the switching of
``sgn(−σ)`` whenever noise moves ``σ`` across 0, chattering). The continuous law slows
down through ``|σ| < h`` and reverses smoothly.

Defaults (assumed, for a detector whose output rises by 1 unit from focus to one
Rayleigh length, e.g. ``y = offset + gain (1 + ((z − z_f)/z_R)²)`` with gain 1): ``V``
= 5 mm/s (500 µm off focus in ~0.1 s), ``ρ`` = 4 units/s, ``h`` = 4e-3 units;
`SlidingModeFocusConfig.for_gain` scales ``ρ`` and ``h`` to another gain. On such a
quadratic stand-in (z_R = 86 µm, a 5 ms velocity lag, detector noise 5e-5 units RMS;
the unit tests) both laws reach and keep ±27 µm (half the 54 µm depth of focus of seed
004 §II-A): the discontinuous law's steady oscillation is ~40 µm peak to peak (the lag's
overrun at 5 mm/s), the continuous law's 1.5-4.5 µm. Without noise the continuous law
can settle into a fast small dither anywhere in a band of about ±24 µm; the detector
noise is what walks it to the centre.

A real detector saturates: the project's focus twin (`microfab.plants.lmw_focus`) reads
the beam with a dark-field photodiode whose output flattens far from focus, where the
reference must still fall slower than the output. There the law runs on the log spot area
(`dark_field_area`, option ``dark_field``), whose rate of change is of one order over the
whole range, with constants from a design rule (`SlidingModeFocusConfig.for_dark_field`:
``ρ`` half the slowest fall over the capture range, ``h = ρ τ``). Measured on that twin
(2 mm/s stage, 5 ms lag, 500 µm start; `microfab.machines.laser_stage.focus.play_focus`):
both laws reach ±27 µm (0.25 s and 0.89 s); steady peak to peak 5.9 µm (continuous) against
9.0 µm (discontinuous). The detector's noise (63 µV) lies far below ``h``, so the relay
seldom chatters and both laws keep one stall-reversal cycle; the gap is 1.5x, not the 5x
seen on the stand-in at 5 mm/s. From 1.5 mm (17 z_R) one converter count is worth
~14x more ``ln q`` than from 500 µm; the rule's resolution floor then sets ``h`` and the
search still ends within ±DOF/2, but one ``h`` for both ends leaves a ~40 µm
peak-to-peak band at focus (a resolution-scaled ``h`` would be the next step).

`SlidingModeFocus` is a `microfab.control.base.CompiledController` with one input: it
reads ``measurement[0]``, the detector output, and ignores any further entries (the
focus plant's measurement is ``(y, z)``, the z encoder is not used); its command has
shape (1,) (z velocity, m/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.core.validate import check_finite, check_nonnegative, check_positive

if TYPE_CHECKING:
    from microfab.plants.lmw_focus import LMWFocus

__all__ = [
    "SlidingModeFocus",
    "SlidingModeFocusConfig",
    "chi",
    "chi_scalar",
    "dark_field_area",
    "dark_field_area_scalar",
    "focus_law",
    "focus_step",
    "relay",
    "relay_scalar",
]


def _h(h: float) -> float:
    return check_positive("h (hysteresis / boundary layer)", h)


def chi(sigma: np.ndarray | float, h: float) -> np.ndarray:
    """Continuous sign, seed 004 eq. (16): ``σ/h`` for ``|σ| < h``, ``sign σ`` beyond.

    Parameters
    ----------
    sigma : numpy.ndarray or float
        Switching variable, any shape.
    h : float
        Boundary layer (> 0), the unit of ``sigma``.

    Returns
    -------
    numpy.ndarray
        Same shape, in ``[−1, 1]``.
    """
    hh = _h(h)
    return np.clip(np.asarray(sigma, dtype=float) / hh, -1.0, 1.0)


def relay(sigma: np.ndarray | float, h: float) -> np.ndarray:
    """Continuous relay, seed 004 eq. (17): 1 below ``−h``, 0 from ``h``, ``mσ + b`` between.

    ``m = −1/(2h)``, ``b = 1/2`` (continuity at ``±h``).

    Parameters
    ----------
    sigma : numpy.ndarray or float
        Switching variable, any shape.
    h : float
        Hysteresis (> 0), the unit of ``sigma``.

    Returns
    -------
    numpy.ndarray
        Same shape, in ``[0, 1]``.
    """
    hh = _h(h)
    return np.clip(0.5 - np.asarray(sigma, dtype=float) / (2.0 * hh), 0.0, 1.0)


@njit(cache=True, inline="always")
def chi_scalar(sigma: float, h: float) -> float:
    """`chi` for one value (numba)."""
    if sigma >= h:
        return 1.0
    if sigma <= -h:
        return -1.0
    return sigma / h


@njit(cache=True, inline="always")
def relay_scalar(sigma: float, h: float) -> float:
    """`relay` for one value (numba): ``m σ + b`` with ``m = −1/(2h)``, ``b = 1/2``."""
    if sigma < -h:
        return 1.0
    if sigma >= h:
        return 0.0
    return -sigma / (2.0 * h) + 0.5


_RATIO_MAX = 1.0 - 1e-12  # keeps −ln(ratio) > 0: a reading at or above full scale maps to ~1e12


@njit(cache=True, inline="always")
def dark_field_area_scalar(y: float, dark: float, full: float) -> float:
    """`dark_field_area` for one value (numba)."""
    r = (y - dark) / full
    if r < 1e-300:
        r = 1e-300
    if r > _RATIO_MAX:
        r = _RATIO_MAX
    return -math.log(-math.log(r))


def dark_field_area(y: np.ndarray | float, dark_v: float, full_scale_v: float) -> np.ndarray:
    """Log spot area from a dark-field detector: ``ln q = −ln(−ln((y − dark) / full_scale))``.

    A photodiode with an opaque disc of radius ``a`` reads
    ``y = dark + full_scale exp(−2a² / w²)`` for a Gaussian spot of radius ``w``, so
    ``q = w² / (2a²)``: the spot area in units of ``2a²``, a parabola in the defocus,
    ``q = (1 + (Δz/z_R)²) w0² / (2a²)``, and its log ``ln q`` (returned) changes at a
    rate ``2 ζ ζ̇ / (1 + ζ²)``, ``ζ = Δz/z_R``, that stays of one order from near focus
    out to where ``y`` meets its full scale, and near focus ``ln q ≈ ζ² + ln(w0²/2a²)``.
    The focus law can therefore run on ``ln q`` with one set of constants over the whole
    range; on ``y`` itself its reference would have to fall slower than ``y`` does far
    from focus, where ``y`` flattens (there a count of the converter is worth some 400
    counts near focus). The ratio is clipped to ``(0, 1 − 1e-12)``.

    Parameters
    ----------
    y : numpy.ndarray or float
        Detector output, V, any shape.
    dark_v, full_scale_v : float
        Dark level and full-scale rise of the detector, V.

    Returns
    -------
    numpy.ndarray
        ``ln q``, same shape (dimensionless).
    """
    full = check_positive("full_scale_v", full_scale_v, "V")
    r = np.clip((np.asarray(y, dtype=float) - dark_v) / full, 1e-300, _RATIO_MAX)
    return -np.log(-np.log(r))


@dataclass(frozen=True, kw_only=True)
class SlidingModeFocusConfig:
    """Settings of the sliding-mode focus search (module docstring for the law).

    Parameters
    ----------
    speed_m_s : float
        Search speed ``V``, m/s (assumed 5 mm/s).
    fall_rate : float
        ``ρ``, rate at which the reference on the detector output falls, detector
        units/s (assumed 4 for a unit detector gain).
    h : float
        Hysteresis of the direction relay and boundary layer of eqs. 16-17, detector
        units (assumed 4e-3 for a unit gain).
    continuous : bool
        The continuous law (eqs. 16-17, default) or the discontinuous baseline.
    initial_direction : int
        Direction of the first move, +1 (z up) or −1.
    dt : float
        Sample time, s (assumed 100 µs, as the stage loop).
    dark_field : tuple of float, optional
        ``(dark_v, full_scale_v)`` of a dark-field detector, V: the law then works on the
        log spot area ``ln q`` (`dark_field_area`) instead of ``y``, and
        ``ρ``, ``h`` are in its unit. Both levels are measured once (beam blocked; far out
        of focus). None (default): the law works on ``y`` itself.
    """

    speed_m_s: float = 5e-3  # assumed
    fall_rate: float = 4.0  # assumed, unit detector gain
    h: float = 4e-3  # assumed, unit detector gain
    continuous: bool = True
    initial_direction: int = 1
    dt: float = 1e-4  # assumed: 10 kHz
    dark_field: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        check_positive("speed_m_s (search speed V)", self.speed_m_s, "m/s")
        check_positive("fall_rate (ρ, reference fall rate)", self.fall_rate, "detector units/s")
        check_positive("h (hysteresis)", self.h, "detector units")
        check_positive("dt", self.dt, "s")
        if not isinstance(self.continuous, bool):
            raise ValueError(f"continuous must be true or false, got {self.continuous!r}")
        if self.initial_direction not in (1, -1) or isinstance(self.initial_direction, bool):
            raise ValueError(f"initial_direction must be +1 or -1, got {self.initial_direction!r}")
        if self.dark_field is not None:
            try:
                dark, full = (float(v) for v in self.dark_field)
            except (TypeError, ValueError):
                raise ValueError(
                    f"dark_field must be (dark_v, full_scale_v) in V, got {self.dark_field!r}"
                ) from None
            check_finite("dark_field[0] (dark level)", dark, "V")
            check_positive("dark_field[1] (full scale above the dark level)", full, "V")
            object.__setattr__(self, "dark_field", (dark, full))
        if self.fall_rate * self.dt >= self.h:
            raise ValueError(
                f"fall_rate * dt = {self.fall_rate * self.dt:g} detector units must stay below "
                f"h = {self.h:g}: the reference would cross the hysteresis band in one "
                "sample; lower fall_rate or raise h"
            )

    @classmethod
    def for_gain(cls, gain: float, **kwargs: Any) -> SlidingModeFocusConfig:
        """The defaults with ``ρ`` and ``h`` scaled to a detector gain (units per z_R²)."""
        g = check_positive("gain (detector output from focus to one Rayleigh length)", gain)
        kwargs.setdefault("fall_rate", 4.0 * g)
        kwargs.setdefault("h", 4e-3 * g)
        return cls(**kwargs)

    @classmethod
    def for_dark_field(
        cls,
        *,
        rayleigh_range_m: float,
        capture_m: float,
        speed_m_s: float,
        lag_s: float,
        dark_v: float,
        full_scale_v: float,
        resolution_v: float = 0.0,
        stop_radius_ratio: float = math.sqrt(0.5),
        **kwargs: Any,
    ) -> SlidingModeFocusConfig:
        """The law on a dark-field detector's log spot area, constants by a design rule.

        On ``ln q`` (`dark_field_area`, any disc radius) the output falls at
        ``2 ζ V / (z_R (1 + ζ²))`` when the stage runs at ``V`` towards focus from
        ``ζ = Δz / z_R``; over ``|Δz| <= capture_m`` (beyond ``z_R``) the slowest fall
        is at the far end. The rule:

        * ``ρ`` = half that slowest fall, so that the output can keep ahead of the
          reference everywhere in the capture range (margin 2 for the stage's
          acceleration);
        * ``h = ρ τ``: a stall is noticed (``σ`` from ``−h`` to 0) no sooner than the
          stage's velocity lag ``τ``, so that the law does not reverse before the stage
          has answered its last command;
        * but ``h`` at least twice the detector's resolution (``resolution_v``: converter
          count plus noise) seen on ``ln q`` at the far end, where ``y`` is flattest and
          one volt is worth the most ``ln q``; below that the law reverses on the
          converter's steps and noise and never leaves the start.

        Parameters
        ----------
        rayleigh_range_m : float
            ``z_R`` of the beam, m.
        capture_m : float
            Largest defocus the search must start from, m (>= ``z_R``).
        speed_m_s : float
            Search speed ``V``, m/s.
        lag_s : float
            Velocity lag ``τ`` of the z stage, s.
        dark_v, full_scale_v : float
            Dark level and full-scale rise of the detector, V.
        resolution_v : float
            Smallest change of ``y`` the law can trust, V (e.g. one converter count plus
            three noise rms; 0: no floor on ``h``).
        stop_radius_ratio : float
            Disc radius over ``w0`` (default ``1/sqrt 2``), for the far-end slope.
        **kwargs
            Other settings (``continuous``, ``dt``, ``initial_direction``).
        """
        zr = check_positive("rayleigh_range_m", rayleigh_range_m, "m")
        cap = check_positive("capture_m", capture_m, "m")
        if cap < zr:
            raise ValueError(
                f"capture_m ({cap:g} m) must be at least the Rayleigh range ({zr:g} m): "
                "the rule takes the slowest fall of ln q at the far end of the range"
            )
        v = check_positive("speed_m_s", speed_m_s, "m/s")
        tau = check_positive("lag_s", lag_s, "s")
        res = check_nonnegative("resolution_v", resolution_v, "V")
        full = check_positive("full_scale_v", full_scale_v, "V")
        zeta = cap / zr
        rho = 0.5 * 2.0 * zeta / (1.0 + zeta * zeta) * v / zr
        # d ln q / dy at the far end, 1/V, with y_n = exp(−2 (a/w0)² / (1 + ζ²))
        a2 = 2.0 * check_positive("stop_radius_ratio", stop_radius_ratio) ** 2
        yn = math.exp(-a2 / (1.0 + zeta * zeta))
        slope = 1.0 / (yn * -math.log(yn) * full)
        return cls(
            speed_m_s=v,
            fall_rate=rho,
            h=max(rho * tau, 2.0 * res * slope),
            dark_field=(dark_v, full_scale_v),
            **kwargs,
        )

    def with_(self, **changes: Any) -> SlidingModeFocusConfig:
        """A copy with some settings changed (validated again)."""
        return replace(self, **changes)


@njit(cache=True)
def focus_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Kernel of `SlidingModeFocus`: one sample of the law, state advanced in place.

    ``p = [V, ρ dt, h, continuous, initial direction, dark-field on, dark, full scale]``;
    ``x = [r, d, initialised, σ]``.
    """
    y = ym[0]
    if p[5] != 0.0:
        y = dark_field_area_scalar(y, p[6], p[7])
    h = p[2]
    if x[2] == 0.0:
        x[0] = y + h
        x[1] = p[4]
        x[2] = 1.0
    sig = y - x[0]
    if sig < -h:
        x[0] = y + h
        sig = -h
    if sig >= h:
        x[1] = -x[1]
        x[0] = y + h
        sig = -h
    if p[3] != 0.0:
        s = 2.0 * relay_scalar(sig, h) - 1.0
    else:
        s = 1.0 if sig < 0.0 else -1.0
    u[0] = p[0] * x[1] * s
    x[3] = sig
    x[0] -= p[1]


class SlidingModeFocus(CompiledController):
    """The sliding-mode focus search (module docstring), continuous or discontinuous.

    Parameters
    ----------
    config : SlidingModeFocusConfig
        The settings.

    Notes
    -----
    Reads ``measurement[0]`` (detector output) only; command shape (1,), z velocity in
    m/s. The reference window is not used (any reference will do; the loop needs one
    of the run's length). State ``[r, d, initialised, σ]``: the reference, the direction,
    whether the first sample was seen, the last ``σ``.
    """

    kernel_step: Any = focus_step

    def __init__(self, config: SlidingModeFocusConfig | None = None) -> None:
        config = SlidingModeFocusConfig() if config is None else config
        if not isinstance(config, SlidingModeFocusConfig):
            raise TypeError(f"config must be a SlidingModeFocusConfig, got {type(config).__name__}")
        self.config = config
        self.dt = config.dt
        self.n_inputs = 1
        self.n_outputs = 1
        self.preview = 1
        self.params = np.array(
            [
                config.speed_m_s,
                config.fall_rate * config.dt,
                config.h,
                float(config.continuous),
                float(config.initial_direction),
                float(config.dark_field is not None),
                *(config.dark_field or (0.0, 1.0)),
            ],
            dtype=np.float64,
        )
        self.params.setflags(write=False)

    def init(self) -> np.ndarray:
        """Not started: the first sample sets ``r = y + h`` and ``d``."""
        return np.zeros(4)

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference of the kernel); ``state`` is not modified."""
        x = np.array(state, dtype=np.float64, copy=True)
        cfg = self.config
        y = float(np.asarray(measurement, dtype=float).ravel()[0])
        if cfg.dark_field is not None:
            y = float(dark_field_area(y, *cfg.dark_field))
        h = cfg.h
        if x[2] == 0.0:
            x[0], x[1], x[2] = y + h, float(cfg.initial_direction), 1.0
        sig = y - x[0]
        if sig < -h:
            x[0], sig = y + h, -h
        if sig >= h:
            x[1] = -x[1]
            x[0], sig = y + h, -h
        if cfg.continuous:  # relay_scalar's arithmetic: 2 v(σ) − 1
            s = 2.0 * (1.0 if sig < -h else 0.0 if sig >= h else -sig / (2.0 * h) + 0.5) - 1.0
        else:
            s = 1.0 if sig < 0.0 else -1.0
        u = np.array([cfg.speed_m_s * x[1] * s])
        x[3] = sig
        x[0] -= self.params[1]
        return u, x

    def sigma(self, state: np.ndarray) -> float:
        """``σ = y − r`` of the last sample (detector units)."""
        return float(np.asarray(state)[3])

    def reference(self, state: np.ndarray) -> float:
        """``r`` for the next sample (detector units)."""
        return float(np.asarray(state)[0])

    def direction(self, state: np.ndarray) -> int:
        """The direction register ``d`` (+1 or −1; 0 before the first sample)."""
        return int(np.asarray(state)[1])


def focus_law(
    plant: LMWFocus, *, continuous: bool = True, speed_m_s: float | None = None
) -> SlidingModeFocusConfig:
    """The focus law for a focus twin: `SlidingModeFocusConfig.for_dark_field` on its optics.

    The capture range is the start's defocus (at least ``z_R``); the speed the stage's
    limit unless given; the detector's resolution one converter count plus three noise
    rms; the first move is up (+z).

    Parameters
    ----------
    plant : LMWFocus
        The focus twin (`microfab.plants.lmw_focus`): its optics, stage lag and start.
    continuous : bool
        Continuous sign and relay (seed 004 eqs. 16-17) or the discontinuous baseline.
    speed_m_s : float or None
        Search speed V, m/s (default: the twin's speed limit).
    """
    c = plant.config
    return SlidingModeFocusConfig.for_dark_field(
        rayleigh_range_m=c.rayleigh_range_m,
        capture_m=max(abs(c.start_position_m - c.focus_position_m), c.rayleigh_range_m),
        speed_m_s=c.speed_limit_m_s if speed_m_s is None else speed_m_s,
        lag_s=c.velocity_lag_s,
        dark_v=c.offset_v,
        full_scale_v=c.full_scale_v,
        resolution_v=c.adc_count_v + 3.0 * c.noise_rms_v,
        stop_radius_ratio=c.stop_radius_ratio,
        continuous=continuous,
        dt=plant.dt,
        initial_direction=1,
    )
