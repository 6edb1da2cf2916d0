"""Discrete PID with a filtered derivative: the baseline of seed 001 Fig. 8.

Per axis, on the error ``e = r - y`` (mm) the command (V) is

``u = kp e + I + D + ff``,

discretised by Tustin (the trapezoidal rule) at the controller's sample time ``dt``:

* integral: ``I_k = I_{k-1} + ki dt/2 (e_k + e_{k-1})``;
* derivative on the error through the filter ``kd s / (tf s + 1)``:
  ``D_k = a D_{k-1} + b (e_k - e_{k-1})`` with ``a = (2 tf - dt) / (2 tf + dt)`` and
  ``b = 2 kd / (2 tf + dt)``;
* reference feedforward (off by default): ``ff = f0 r + f1 r' + f2 r''`` from the
  reference window's position, velocity and acceleration (a term whose derivative the
  window does not carry is left out). `PIDGains.design` sets ``(f0, f1, f2)`` to the inverse
  of the axis model ``K / (s^2 + a1 s + a0)``: ``(a0, a1, 1) / K``.

The seed gives no PID (Fig. 8 shows its error only). `PIDGains.design` is our stated
rule, loop shaping on the discrete loop: the integral zero a decade below the crossover
(``ki = kp wc / integral_ratio``), the derivative filter pole a decade above
(``tf = 1 / (filter_ratio wc)``), and ``kd``, ``kp`` solved so that the loop of the Tustin
PID and the ZOH plant crosses 0 dB at ``bandwidth_hz`` with ``phase_margin_deg`` there.

`PID` is a two-axis (any number of axes) `microfab.control.base.CompiledController`:
measurement (n_axes,) in mm, command (n_axes,) in V; its numba kernel and its Python
``step`` perform the same operations.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
from numba import njit

import control
from microfab.control.base import CompiledController, ReferenceWindow
from microfab.core.validate import check_finite, check_nonnegative, check_positive

__all__ = ["PID", "PIDGains", "pid_frequency_response", "pid_step"]

_N_AX_PARAMS = 7  # kp, ki dt/2, a, b, f0, f1, f2
_N_AX_STATE = 3  # I, D, e_prev


@dataclass(frozen=True, kw_only=True)
class PIDGains:
    """Gains of one axis's PID.

    Parameters
    ----------
    kp : float
        Proportional gain, V/mm (>= 0).
    ki : float
        Integral gain, V/(mm s) (>= 0).
    kd : float
        Derivative gain, V s/mm (>= 0).
    tf : float
        Time constant of the derivative filter, s (> 0).
    ff : tuple of 3 float
        Reference feedforward ``(f0, f1, f2)`` on position, velocity, acceleration: V/mm,
        V s/mm, V s²/mm (used only when the `PID` is built with ``feedforward=True``).
    """

    kp: float
    ki: float
    kd: float
    tf: float
    ff: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        check_nonnegative("kp", self.kp, "V/mm")
        check_nonnegative("ki", self.ki, "V/(mm s)")
        check_nonnegative("kd", self.kd, "V s/mm")
        check_positive("tf (derivative filter time constant)", self.tf, "s")
        if len(self.ff) != 3:
            raise ValueError(
                f"ff must hold 3 feedforward gains (position, velocity, acceleration), "
                f"got {len(self.ff)}"
            )
        for name, v, unit in zip(
            ("f0", "f1", "f2"), self.ff, ("V/mm", "V s/mm", "V s²/mm"), strict=True
        ):
            check_finite(f"feedforward gain {name}", v, unit)
        object.__setattr__(self, "ff", tuple(float(v) for v in self.ff))

    @classmethod
    def design(
        cls,
        plant: control.TransferFunction | tuple[Sequence[float], Sequence[float]],
        *,
        bandwidth_hz: float,
        phase_margin_deg: float = 45.0,
        dt: float = 1e-4,
        integral_ratio: float = 10.0,
        filter_ratio: float = 10.0,
    ) -> PIDGains:
        """Gains by loop shaping the discrete loop at ``bandwidth_hz`` (our rule, see module).

        Parameters
        ----------
        plant : control.TransferFunction or (num, den)
            Continuous axis model, mm/V (seed 001 eq. 9: ``(548248.13,), (1, 14.88,
            101793.23)`` for x). Discretised by ZOH at ``dt`` for the design.
        bandwidth_hz : float
            Gain crossover of the loop, Hz.
        phase_margin_deg : float
            Phase margin at the crossover, deg, in (0, 90).
        dt : float
            Sample time, s (10 kHz assumed in the twin's data file).
        integral_ratio : float
            Crossover over the integral zero, ``wc / (ki / kp)`` (> 1; assumed 10).
        filter_ratio : float
            Derivative filter pole over the crossover, ``1 / (tf wc)`` (> 1; assumed 10).

        Returns
        -------
        PIDGains
            With ``ff`` set to the model inverse ``(a0, a1, 1) / K`` when the model is
            ``K / (s^2 + a1 s + a0)``, else zeros.

        Raises
        ------
        ValueError
            When the phase margin cannot be reached with these ratios at this bandwidth
            (the message gives the largest one that can).
        """
        check_positive("bandwidth_hz", bandwidth_hz, "Hz")
        check_positive("dt", dt, "s")
        if bandwidth_hz >= 0.25 / dt:
            raise ValueError(
                f"bandwidth_hz must lie below a quarter of the sample rate ({0.25 / dt:g} Hz), "
                f"got {bandwidth_hz} Hz"
            )
        pm = check_positive("phase_margin_deg", phase_margin_deg, "deg")
        if pm >= 90.0:
            raise ValueError(f"phase_margin_deg must lie in (0, 90) deg, got {pm} deg")
        check_positive("integral_ratio", integral_ratio)
        check_positive("filter_ratio", filter_ratio)
        if integral_ratio <= 1.0 or filter_ratio <= 1.0:
            raise ValueError(
                f"integral_ratio and filter_ratio must exceed 1 (integral zero below, "
                f"derivative filter above the crossover), got {integral_ratio}, {filter_ratio}"
            )
        tf_model = plant if isinstance(plant, control.TransferFunction) else control.tf(*plant)
        wc = 2 * np.pi * bandwidth_hz
        z = np.exp(1j * wc * dt)
        pd = control.c2d(control.ss(tf_model), dt, method="zoh")
        P = complex(np.squeeze(control.evalfr(pd, z)))
        if not (np.isfinite(P) and abs(P) > 0):
            raise ValueError(f"the plant's response at {bandwidth_hz} Hz is {P}: cannot design")
        tf = 1.0 / (filter_ratio * wc)
        ki_over_kp = wc / integral_ratio
        # bracket: C / kp = 1 + (ki/kp) * I(z) + Td * D(z) with Td = kd / kp
        base = 1.0 + ki_over_kp * dt / 2 * (z + 1) / (z - 1)
        dterm = 2 * (z - 1) / ((2 * tf + dt) * z - (2 * tf - dt))
        target = np.deg2rad(-180.0 + pm) - np.angle(P)
        target = (target + np.pi) % (2 * np.pi) - np.pi  # wrapped to [-pi, pi)

        def phase(td: float) -> float:
            return float(np.angle(base + td * dterm))

        # the phase rises monotonically from angle(base) towards angle(dterm) as Td grows
        lo, hi = phase(0.0), phase(1e6 / wc)
        if not lo <= target <= hi:
            best = np.rad2deg(hi + np.angle(P)) + 180.0
            raise ValueError(
                f"phase_margin_deg = {pm} deg cannot be reached at bandwidth_hz = "
                f"{bandwidth_hz} Hz with integral_ratio {integral_ratio} and filter_ratio "
                f"{filter_ratio} (at most {best:.1f} deg): lower the margin or change the ratios"
            )
        td = scipy.optimize.brentq(lambda t: phase(t) - target, 0.0, 1e6 / wc, xtol=1e-15)
        kp = 1.0 / abs(P * (base + td * dterm))
        num = np.atleast_1d(np.squeeze(tf_model.num[0][0]))
        den = np.atleast_1d(np.squeeze(tf_model.den[0][0]))
        ff: tuple[float, float, float] = (0.0, 0.0, 0.0)
        if den.size == 3 and num.size == 1 and den[0] != 0:
            k_gain = num[0] / den[0]
            ff = (
                float(den[2] / den[0] / k_gain),
                float(den[1] / den[0] / k_gain),
                float(1.0 / k_gain),
            )
        return cls(kp=float(kp), ki=float(kp * ki_over_kp), kd=float(kp * td), tf=tf, ff=ff)


def pid_frequency_response(gains: PIDGains, freq_hz: np.ndarray, dt: float) -> np.ndarray:
    """Frequency response of the discrete (Tustin) PID from error to command, V/mm.

    Parameters
    ----------
    gains : PIDGains
        One axis's gains.
    freq_hz : numpy.ndarray
        Frequencies, Hz, shape (n,).
    dt : float
        Sample time, s.

    Returns
    -------
    numpy.ndarray
        Complex response, shape (n,).
    """
    z = np.exp(2j * np.pi * np.asarray(freq_hz, dtype=float) * dt)
    g = gains
    return (
        g.kp
        + g.ki * dt / 2 * (z + 1) / (z - 1)
        + g.kd * 2 * (z - 1) / ((2 * g.tf + dt) * z - (2 * g.tf - dt))
    )


@njit(cache=True)
def pid_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Kernel of `PID`: one sample for every axis, state advanced in place.

    ``p = [n_axes, feedforward, (kp, ki dt/2, a, b, f0, f1, f2) per axis]``;
    ``x = [(I, D, e_prev) per axis]``.
    """
    na = int(p[0])
    ff_on = p[1] != 0.0
    n_orders = ref.shape[1]
    for i in range(na):
        o = 2 + _N_AX_PARAMS * i
        s = _N_AX_STATE * i
        e = ref[k, 0, i] - ym[i]
        de = e - x[s + 2]
        integ = x[s] + p[o + 1] * (e + x[s + 2])
        deriv = p[o + 2] * x[s + 1] + p[o + 3] * de
        out = p[o] * e + integ + deriv
        if ff_on:
            out += p[o + 4] * ref[k, 0, i]
            if n_orders > 1:
                out += p[o + 5] * ref[k, 1, i]
            if n_orders > 2:
                out += p[o + 6] * ref[k, 2, i]
        u[i] = out
        x[s] = integ
        x[s + 1] = deriv
        x[s + 2] = e


class PID(CompiledController):
    """Per-axis discrete PID with filtered derivative (Tustin), preview 1.

    Parameters
    ----------
    gains : sequence of PIDGains
        One per axis (x, y).
    dt : float
        Sample time, s.
    feedforward : bool
        Add the reference feedforward ``f0 r + f1 r' + f2 r''`` (default off).

    Notes
    -----
    State: ``(I, D, e_prev)`` per axis, zero at rest (the error before the first sample is
    taken as 0). No anti-windup and no output limit: the limits of the command are checked
    by the machine (`microfab.core.limits`).
    """

    kernel_step: Any = pid_step

    def __init__(self, *, gains: Sequence[PIDGains], dt: float, feedforward: bool = False) -> None:
        gains = tuple(gains)
        if not gains or not all(isinstance(g, PIDGains) for g in gains):
            raise ValueError("gains must be a non-empty sequence of PIDGains, one per axis")
        self.dt = check_positive("dt", dt, "s")
        if not isinstance(feedforward, bool):
            raise ValueError(f"feedforward must be true or false, got {feedforward!r}")
        self.gains = gains
        self.feedforward = feedforward
        self.n_axes = len(gains)
        self.preview = 1
        rows = []
        for g in gains:
            a = (2 * g.tf - dt) / (2 * g.tf + dt)
            b = 2 * g.kd / (2 * g.tf + dt)
            rows += [g.kp, g.ki * dt / 2, a, b, *g.ff]
        self.params = np.array([self.n_axes, float(feedforward), *rows], dtype=np.float64)

    @classmethod
    def tuned(
        cls,
        plants: Sequence[control.TransferFunction | tuple[Sequence[float], Sequence[float]]],
        *,
        bandwidth_hz: float | Sequence[float],
        phase_margin_deg: float = 45.0,
        dt: float = 1e-4,
        feedforward: bool = False,
        integral_ratio: float = 10.0,
        filter_ratio: float = 10.0,
    ) -> PID:
        """A PID whose every axis is designed by `PIDGains.design`.

        Parameters
        ----------
        plants : sequence of control.TransferFunction or (num, den)
            Continuous model of each axis, mm/V.
        bandwidth_hz : float or sequence of float
            Crossover, Hz (one for all axes, or one per axis).
        phase_margin_deg, dt, integral_ratio, filter_ratio
            As for `PIDGains.design`.
        feedforward : bool
            Turn on the model-inverse reference feedforward.
        """
        plants = list(plants)
        bw = (
            [bandwidth_hz] * len(plants) if np.isscalar(bandwidth_hz) else list(bandwidth_hz)  # type: ignore[arg-type]
        )
        if len(bw) != len(plants):
            raise ValueError(
                f"bandwidth_hz must give one value or one per axis ({len(plants)}), got {len(bw)}"
            )
        gains = [
            PIDGains.design(
                pl,
                bandwidth_hz=b,
                phase_margin_deg=phase_margin_deg,
                dt=dt,
                integral_ratio=integral_ratio,
                filter_ratio=filter_ratio,
            )
            for pl, b in zip(plants, bw, strict=True)
        ]
        return cls(gains=gains, dt=dt, feedforward=feedforward)

    def init(self) -> np.ndarray:
        """Zero state, shape (3 n_axes,)."""
        return np.zeros(_N_AX_STATE * self.n_axes)

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample (the kernel's arithmetic in Python); ``state`` is not modified."""
        p = self.params
        new = np.array(state, dtype=float, copy=True)
        ym = np.asarray(measurement, dtype=float)
        u = np.empty(self.n_axes)
        for i in range(self.n_axes):
            o = 2 + _N_AX_PARAMS * i
            s = _N_AX_STATE * i
            r = float(window.position[0, i])
            e = r - float(ym[i])
            de = e - new[s + 2]
            integ = new[s] + p[o + 1] * (e + new[s + 2])
            deriv = p[o + 2] * new[s + 1] + p[o + 3] * de
            out = p[o] * e + integ + deriv
            if self.feedforward:
                out += p[o + 4] * r
                if window.velocity is not None:
                    out += p[o + 5] * float(window.velocity[0, i])
                if window.acceleration is not None:
                    out += p[o + 6] * float(window.acceleration[0, i])
            u[i] = out
            new[s], new[s + 1], new[s + 2] = integ, deriv, e
        return u, new
