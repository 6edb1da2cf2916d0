"""Digital twin of the XY compliant nanomanipulator of seed 001 (§2, §3.1, §4.1).

Each axis obeys seed 001 eq. (1), ``d²x1/dt² = alpha(x, x̄) + beta(x, x̄) u + d(t)``, with the
linear part of eq. (9), ``P(s) = K / (s² + a1 s + a0)``, and the §4.1 nonlinear terms:

``alpha = -a0 x1 - a1 x2 + a0 L (g_aa ξ² + g_ax ξ ξ̄')``,
``beta  =  K             + a0 L (g_bv ξ'² - g_bx ξ² ξ̄')``,

where ``x = (x1, x2)`` is the axis's position (mm) and velocity (mm/s), ``x̄`` the other
axis's. Units (assumed, issue 14 contract): mm, V at the amplifier input, s; eq. (9) in mm/V.

**Scaling.** The seed gives the §4.1 terms ``alpha = x1² + x1 x̄2``,
``beta = beta_l + x2² - x1² x̄2`` without units, and the units decide everything: read in mm
and s, ``x1²`` is ``x1 / a0`` ~ 1e-5 of the stiffness term (negligible); in µm, beta changes
sign on a 1 Hz, 0.15 mm circle 0.25 mm off-centre. We apply them to the *scaled* equation of
each axis, ``ξ = x1 / L``, ``ξ' = x2 / (w_n L)``, ``ξ̄' = x̄2 / (w_n L)`` (``L`` =
``length_scale_mm``, 1 mm; time in ``1 / w_n``, ``w_n = sqrt(a0)`` of the axis itself), in
which eq. (9) reads ``ξ'' = -ξ - 2 ζ ξ' + beta_l u`` with ``beta_l = K / (a0 L)`` (mm/V per
``L``), and convert back (the factor ``a0 L``). The ``g_*`` are per-term gains (1 = the
seed). Then ``x1²`` is ``x1 / L`` of the stiffness term (1 % at 10 µm, 50 % at 0.5 mm: the
seed's "over 0.5 mm the nonlinearity cannot be neglected", §3.1) and the beta terms stay
below 1e-3 of ``beta_l`` at contour speeds (`term_share_table`). With the default gains the
restoring stiffness ``1 - 2 ξ`` vanishes at ``x1 = L / 2`` and the unforced stage has a
saddle at ``x1 = L``: beyond +0.5 mm only the feedback holds it (the seed's terms, kept).

**beta_min.** Twins whose ``beta`` falls below ``beta_min = beta_min_fraction * K`` anywhere in
the declared workspace are refused (`check_beta`, on a 41³ grid).

The parameters (`NanomanipulatorParams`, `load_params`, the beta check and `term_shares`)
live in `microfab.plants.nanomanipulator_params` and are re-exported here.

**Fig. 5 option** (off by default, coefficients assumed): a stiffening flexure
``k(x) = a0 (1 + κ (x1/W)²)`` adds ``-a0 κ x1³ / W²`` to alpha, and a voice-coil force
constant falling with stroke multiplies beta by ``1 - η (x1/W)²`` (``W = workspace_mm``).

**Disturbance** ``d(t) = d0 Σ_j w_j sin(2π f_j t + φ_j)`` per axis (mm/s²), ``Σ w_j = 1``, so
``|d| <= d0`` as eq. (1) requires; seeded random phases. ``d`` is sampled at ``t_k = k dt``
and held over the sample (assumed: its components lie 100x below the 10 kHz rate); its phasors
``(cos, sin)`` are rotated once per sample and kept in the state, so a run resumes
bit-identically. Sensor noise is not in the plant: the simulators add it (``noise_rms_mm``).

**Sensor noise colour** (``noise_time_constant_s`` per axis, assumed: seed 001 names no
sensor): `NanomanipulatorPlant.noise` draws the seeded white noise of `NoisyOutputs` and, on
an axis with ``τ > 0``, passes it through the first-order low-pass
``n_k = a n_{k-1} + sqrt(1 - a²) w_k``, ``a = exp(-dt/τ)`` (corner ``1/(2π τ)``), started
stationary (``n_0 = w_0``), so its rms stays ``noise_rms_mm``. ``τ = 0`` (the default)
leaves the white draw untouched, bit for bit (`colour_noise`).

**Integration**: classical RK4, command held over the sample (ZOH), ``rk4_substeps`` (6)
sub-steps; with the nonlinearity and ``d`` off the sampled response equals the exact ZOH
discretisation of eq. (9) to 2.8e-10 of the response amplitude over 1 s, driven at resonance.

Seed points (eq. (1), §3.1, §4.1):

* No units for eq. (1) or the §4.1 terms (hence the scaling above).
* §3.1 "the stiffness ... is a nonlinear function of acceleration" reads as displacement (Fig. 5
  plots stiffness against stroke); the Fig. 5 option implements that reading.
* §3.1 only bounds ``|beta| <= beta0``; the proof of Theorem 1 needs ``beta >= beta_min > 0``
  (in A2-A3 the μ-term needs β², and the step to A3 needs ``beta >= 1``), hence ``beta_min``.
* §4.1 "``beta_l`` can be obtained from (9)": the numerator ``K`` (``K / (a0 L)`` scaled).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from numba import njit
from scipy.signal import lfilter

import control
from microfab.plants.base import CompiledPlant, LTIPlant, NoiseLevel, NoisyOutputs
from microfab.plants.lti import DiscreteLTI, block_diag, discretize
from microfab.plants.nanomanipulator_params import (
    _AXIS_FIXED,
    _H_DT,
    _H_NDIST,
    _H_NSUB,
    AXES,
    NanomanipulatorParams,
    _alpha_beta,
    _block,
    beta_minimum,
    check_beta,
    load_params,
    term_share_table,
    term_shares,
)

__all__ = [
    "AXES",
    "NanomanipulatorParams",
    "NanomanipulatorPlant",
    "beta_minimum",
    "check_beta",
    "colour_noise",
    "drift_and_gain",
    "load_params",
    "nanomanipulator_twin",
    "term_share_table",
    "term_shares",
]


_N_STATE = 5  # x1, x2, y1, y2 (mm, mm/s), sample counter k; then the phasors of d


def colour_noise(white: np.ndarray, time_constant_s: np.ndarray, dt: float) -> np.ndarray:
    """First-order low-pass colour of white noise per column, rms kept (module notes).

    Parameters
    ----------
    white : numpy.ndarray
        White noise, any unit, shape (n_samples, n_columns).
    time_constant_s : numpy.ndarray
        ``τ`` per column, s, shape (n_columns,); 0 leaves that column as it is.
    dt : float
        Sample time, s.

    Returns
    -------
    numpy.ndarray
        ``white`` itself when every ``τ`` is 0, else a new array of its shape:
        ``n_k = a n_{k-1} + sqrt(1 - a²) w_k``, ``a = exp(-dt/τ)``, ``n_0 = w_0``.
    """
    tau = np.asarray(time_constant_s, dtype=np.float64)
    if not np.any(tau > 0.0) or white.shape[0] == 0:
        return white
    out = np.array(white, dtype=np.float64, copy=True)
    for j, t in enumerate(tau):
        if t > 0.0:
            a = math.exp(-dt / t)
            w = out[:, j]
            tail, _ = lfilter([math.sqrt(1.0 - a * a)], [1.0, -a], w[1:], zi=[a * w[0]])
            out[1:, j] = tail
    return out


@njit(cache=True)
def drift_and_gain(p: np.ndarray, axis: int, x: np.ndarray) -> tuple[float, float]:
    """``(alpha, beta)`` of seed 001 eq. (1) for one axis, in physical units.

    Parameters
    ----------
    p : numpy.ndarray
        The plant's flat ``params``.
    axis : int
        0 for x, 1 for y.
    x : numpy.ndarray
        ``[x1, x2, y1, y2]``: positions (mm) and velocities (mm/s) of both axes, shape (4,).

    Returns
    -------
    tuple of float
        ``alpha`` in mm/s² (linear part of eq. (9) plus the §4.1 terms) and ``beta`` in
        mm/(V s²) (``K`` of eq. (9) plus the §4.1 terms), so that the axis obeys
        ``d²x1/dt² = alpha + beta u + d(t)``.
    """
    own = 2 * axis
    return _alpha_beta(p, _block(p, axis), x[own], x[own + 1], x[3 - own])


@njit(cache=True, inline="always")
def _disturbance(p: np.ndarray, o: int, s: np.ndarray, q: int) -> float:
    """``d`` of the axis at block ``o`` (mm/s²) from the phasors at ``s[q:]``; rotates them."""
    acc = 0.0
    for j in range(int(p[_H_NDIST])):
        r = o + _AXIS_FIXED + 3 * j
        c, sn = s[q + 2 * j], s[q + 2 * j + 1]
        acc += p[r] * sn
        s[q + 2 * j] = c * p[r + 1] - sn * p[r + 2]
        s[q + 2 * j + 1] = sn * p[r + 1] + c * p[r + 2]
    return acc


@njit(cache=True)
def kernel_output(p: np.ndarray, s: np.ndarray, y: np.ndarray) -> None:
    """Write the measured positions ``(x1, y1)`` (mm) into ``y``, shape (2,)."""
    y[0] = s[0]
    y[1] = s[2]


@njit(cache=True, inline="always")
def _rates(
    p: np.ndarray, o: tuple[int, int], z: tuple[float, ...], u: np.ndarray, d: tuple[float, float]
) -> tuple[float, float, float, float]:
    """``dz/dt`` of ``z = (x1, x2, y1, y2)``: eq. (1) of both axes (blocks ``o``)."""
    ax, bx = _alpha_beta(p, o[0], z[0], z[1], z[3])
    ay, by = _alpha_beta(p, o[1], z[2], z[3], z[1])
    return z[1], ax + bx * u[0] + d[0], z[3], ay + by * u[1] + d[1]


@njit(cache=True, inline="always")
def _axpy(
    z: tuple[float, ...], c: float, k: tuple[float, ...]
) -> tuple[float, float, float, float]:
    """``z + c k`` for 4-tuples."""
    return z[0] + c * k[0], z[1] + c * k[1], z[2] + c * k[2], z[3] + c * k[3]


@njit(cache=True)
def kernel_update(p: np.ndarray, s: np.ndarray, u: np.ndarray) -> None:
    """Advance ``s`` one sample in place: RK4 sub-steps, command and ``d`` held."""
    n = int(p[_H_NSUB])
    h = p[_H_DT] / n
    o = (_block(p, 0), _block(p, 1))
    d = (
        _disturbance(p, o[0], s, _N_STATE),
        _disturbance(p, o[1], s, _N_STATE + 2 * int(p[_H_NDIST])),
    )
    z = (s[0], s[1], s[2], s[3])
    for _ in range(n):
        k1 = _rates(p, o, z, u, d)
        k2 = _rates(p, o, _axpy(z, 0.5 * h, k1), u, d)
        k3 = _rates(p, o, _axpy(z, 0.5 * h, k2), u, d)
        k4 = _rates(p, o, _axpy(z, h, k3), u, d)
        inc = _axpy(_axpy(k1, 2.0, k2), 2.0, k3)
        z = _axpy(z, h / 6.0, _axpy(inc, 1.0, k4))
    s[0], s[1], s[2], s[3] = z
    s[4] += 1.0


class NanomanipulatorPlant(CompiledPlant, NoisyOutputs):
    """The two-axis nonlinear twin as a compiled plant (commands in V, outputs in mm).

    Parameters
    ----------
    config : NanomanipulatorParams
        The twin's parameters.

    Attributes
    ----------
    noise_level : NoiseLevel
        Encoder noise per axis, mm (``noise_rms_mm``); `noise` draws it, seeded.

    Notes
    -----
    State: ``[x1, x2, y1, y2, k]`` (mm, mm/s, mm, mm/s, sample counter), then ``(cos, sin)``
    of each sinusoid of ``d`` (x's, then y's): shape (5 + 4 n_sinusoids,). ``output`` and
    ``update`` are plain Python written from ``config`` (not from the packed kernels), for the
    Python loop and as an independent check of the kernels; both agree to rounding.
    """

    kernel_output: Any = kernel_output
    kernel_update: Any = kernel_update
    n_inputs = 2
    n_outputs = 2

    def __init__(self, config: NanomanipulatorParams) -> None:
        self.config = config
        self.params = config.pack()
        self.dt = config.dt
        self.noise_level = NoiseLevel(config.noise_rms_mm, "mm")
        self._phases = config.disturbance_phases()

    def noise(self, n_samples: int, seed: int = 0) -> np.ndarray:
        """Seeded sensor noise, mm, shape (n_samples, 2): white, coloured per axis.

        `NoisyOutputs.noise` (``default_rng(seed).standard_normal((n, 2)) * rms``) passed
        through `colour_noise` with ``noise_time_constant_s``; white (the same array) when
        both time constants are 0.
        """
        white = super().noise(n_samples, seed)
        return colour_noise(white, np.array(self.config.noise_time_constant_s), self.dt)

    def init(self) -> np.ndarray:
        """At rest at the origin, sample 0, the phasors of ``d`` at ``t = 0``."""
        ph = self._phases.ravel()
        phasors = np.column_stack([np.cos(ph), np.sin(ph)]).ravel()
        return np.concatenate([np.zeros(_N_STATE), phasors])

    def output(self, state: np.ndarray) -> np.ndarray:
        """Measured positions ``(x1, y1)``, mm, shape (2,)."""
        return np.array([state[0], state[2]])

    def drift_and_gain(self, axis: int, x: Any) -> tuple[float, float]:
        """Python twin of `drift_and_gain`: ``(alpha, beta)`` in mm/s² and mm/(V s²)."""
        c = self.config
        own = 2 * axis
        x1, x2, v = float(x[own]), float(x[own + 1]), float(x[3 - own])
        a0, a1 = c.stiffness_per_s2[axis], c.damping_per_s[axis]
        K, L, r = c.numerator_mm_per_v_s2[axis], c.length_scale_mm, x1 / c.workspace_mm
        wn = math.sqrt(a0)
        xi, xid, vb = x1 / L, x2 / (wn * L), v / (wn * L)  # the scaled equation's states
        alpha = -a0 * x1 - a1 * x2
        alpha += a0 * L * (c.alpha_square_gain * xi * xi + c.alpha_cross_gain * xi * vb)
        alpha -= a0 * c.fig5_stiffening * r * r * x1
        beta = K + a0 * L * (c.beta_velocity_gain * xid * xid - c.beta_cross_gain * xi * xi * vb)
        return alpha, beta * (1.0 - c.fig5_force_drop * r * r)

    def disturbance(self, t: float) -> np.ndarray:
        """``d(t)`` per axis from ``t`` directly, mm/s², shape (2,); ``|d| <= d0``.

        The plant holds ``d(k dt)`` over sample ``k`` (its phasors agree with this to rounding).
        """
        c = self.config
        out = np.zeros(2)
        for i in range(2):
            for j, (f, w) in enumerate(
                zip(c.disturbance_frequencies_hz, c.disturbance_weights, strict=True)
            ):
                phase = 2 * math.pi * f * t + float(self._phases[i, j])
                out[i] += c.disturbance_mm_s2[i] * w * math.sin(phase)
        return out

    def _rate(self, z: list[float], u: list[float], d: list[float]) -> list[float]:
        ax, bx = self.drift_and_gain(0, z)
        ay, by = self.drift_and_gain(1, z)
        return [z[1], ax + bx * u[0] + d[0], z[3], ay + by * u[1] + d[1]]

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """State one sample later (a new array): RK4 sub-steps, command and ``d`` held."""
        c = self.config
        u = [float(v) for v in command]
        nd = len(c.disturbance_frequencies_hz)
        ph = [float(v) for v in state[_N_STATE:]]
        d = [0.0, 0.0]
        for i in range(2):
            for j in range(nd):
                q = 2 * (i * nd + j)
                cj, sj = ph[q], ph[q + 1]
                d[i] += c.disturbance_mm_s2[i] * c.disturbance_weights[j] * sj
                th = 2 * math.pi * c.disturbance_frequencies_hz[j] * self.dt
                ph[q] = cj * math.cos(th) - sj * math.sin(th)
                ph[q + 1] = sj * math.cos(th) + cj * math.sin(th)
        h = self.dt / c.rk4_substeps
        z = [float(v) for v in state[:4]]
        for _ in range(c.rk4_substeps):
            k1 = self._rate(z, u, d)
            k2 = self._rate([z[i] + 0.5 * h * k1[i] for i in range(4)], u, d)
            k3 = self._rate([z[i] + 0.5 * h * k2[i] for i in range(4)], u, d)
            k4 = self._rate([z[i] + h * k3[i] for i in range(4)], u, d)
            z = [z[i] + h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]) for i in range(4)]
        return np.array([*z, float(state[4]) + 1.0, *ph])

    def noise_rms_mm(self) -> np.ndarray:
        """``noise_level.array()``: encoder noise rms per axis (x, y), mm, shape (2,).

        Kept for callers of the former noise fit; new code reads `noise_level`.
        """
        return self.noise_level.array()

    def continuous_models(self) -> list[control.TransferFunction]:
        """Eq. (9) per axis as python-control transfer functions, mm/V."""
        c = self.config
        return [
            control.tf(
                [c.numerator_mm_per_v_s2[i]], [1.0, c.damping_per_s[i], c.stiffness_per_s2[i]]
            )
            for i in range(2)
        ]

    def linear_model(self) -> DiscreteLTI:
        """Exact ZOH discretisation of eq. (9), both axes block-diagonal (4 states, mm/V).

        States per axis ``(x1, x2)`` in mm and mm/s, as in the twin's state.
        """
        c = self.config
        parts = []
        for i in range(2):
            A = [[0.0, 1.0], [-c.stiffness_per_s2[i], -c.damping_per_s[i]]]
            sys = control.ss(A, [[0.0], [c.numerator_mm_per_v_s2[i]]], [[1.0, 0.0]], [[0.0]])
            parts.append(discretize(sys, self.dt, "zoh"))
        return block_diag(*parts)

    def linear_plant(self) -> LTIPlant:
        """The ZOH model of eq. (9) as an `LTIPlant` (the twin's linear baseline)."""
        return LTIPlant(self.linear_model())


def nanomanipulator_twin(
    seed: int = 0,
    nonlinear: bool = True,
    disturbance: bool = True,
    path: str | os.PathLike[str] | None = None,
    params: NanomanipulatorParams | None = None,
    **overrides: Any,
) -> NanomanipulatorPlant:
    """The twin from the data file, with validated ``overrides``.

    Parameters
    ----------
    seed : int
        Seed of the disturbance phases (``disturbance_seed``).
    nonlinear : bool
        False turns the §4.1 terms and the Fig. 5 physics off (eq. (9) only).
    disturbance : bool
        False sets ``d(t) = 0``.
    path : path-like, optional
        Another parameter file (default ``data/nanomanipulator_twin.toml``).
    params : NanomanipulatorParams, optional
        Parameters already read (then ``path`` is not read); the machine module passes
        the ones it parsed once (`microfab.machines.twins`).
    **overrides
        `NanomanipulatorParams` fields to replace (before ``nonlinear``, ``disturbance``).
    """
    cfg = (load_params(path) if params is None else params).with_(
        disturbance_seed=seed, **overrides
    )
    if not nonlinear:
        cfg = cfg.linear()
    if not disturbance:
        cfg = cfg.with_(disturbance_mm_s2=(0.0, 0.0))
    return NanomanipulatorPlant(cfg)
