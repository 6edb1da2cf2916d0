"""Parameters of the seed 001 nanomanipulator twin: dataclass, data file, beta_min check.

`NanomanipulatorParams` holds the values of seed 001 eqs. (1), (9) and the §4.1 terms in
the scaling that `microfab.plants.nanomanipulator` states (its module docstring has the
physics, the units and the seed points); `load_params` reads them from
``data/nanomanipulator_twin.toml`` (every value with its ``<key>_source``);
`NanomanipulatorParams.pack` lays them out flat for the numba kernels, and `_alpha_beta`
(eq. (1)'s ``alpha`` and ``beta`` of one axis on that layout) is shared by the plant's
kernels and by the checks here.

**beta_min.** Twins whose ``beta`` falls below ``beta_min = beta_min_fraction * K`` anywhere in
the declared workspace (``|x1| <= workspace_mm``, ``|x2|, |x̄2| <= velocity_limit_mm_s``) are
refused, checked on a 41³ grid of ``(x1, x2, x̄2)`` that holds the corners and zero (the
terms are polynomials whose extremes over a box lie at the corners or where ``x2 = 0``).
Seed 001 §3.1 only bounds ``|beta| <= beta0``; the proof of Theorem 1 needs
``beta >= beta_min > 0`` (in A2-A3 the μ-term needs β², and the step to A3 needs
``beta >= 1``), hence ``beta_min``.

`term_shares` / `term_share_table` size each §4.1 term against the linear term it adds to.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from microfab.core.validate import (
    check_axis_pair,
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    replace_known,
)
from microfab.plants.sourced_toml import read_sourced

__all__ = [
    "AXES",
    "NanomanipulatorParams",
    "beta_minimum",
    "check_beta",
    "load_params",
    "term_share_table",
    "term_shares",
]

AXES = ("x", "y")
_GRID = 41  # points per dimension of the beta_min check (odd: holds zero and the corners)
# flat params: [dt, rk4_substeps, n_sinusoids], then per axis a block of
# a0, a1, K, c_aa, c_ax, c_bv, c_bx, k3, eta (see `NanomanipulatorParams.pack`) and
# (amplitude mm/s², cos(w dt), sin(w dt)) per sinusoid of d
_H_DT, _H_NSUB, _H_NDIST, _HEADER = 0, 1, 2, 3
_A0, _A1, _K, _CAA, _CAX, _CBV, _CBX, _K3, _ETA = range(9)
_AXIS_FIXED = 9


@njit(cache=True, inline="always")
def _block(p: np.ndarray, axis: int) -> int:
    """Offset of the parameter block of ``axis`` in the flat params."""
    return _HEADER + axis * (_AXIS_FIXED + 3 * int(p[_H_NDIST]))


@njit(cache=True, inline="always")
def _alpha_beta(p: np.ndarray, o: int, x1: float, x2: float, v: float) -> tuple[float, float]:
    """Alpha (mm/s²), beta (mm/(V s²)) of the axis at block ``o``; ``v`` the other's x2."""
    x1s = x1 * x1
    alpha = -p[o + _A0] * x1 - p[o + _A1] * x2 + p[o + _CAA] * x1s + p[o + _CAX] * x1 * v
    alpha -= p[o + _K3] * x1s * x1
    beta = p[o + _K] + p[o + _CBV] * x2 * x2 - p[o + _CBX] * x1s * v
    beta *= 1.0 - p[o + _ETA] * x1s
    return alpha, beta


@njit(cache=True)
def _beta_grid_min(
    p: np.ndarray, axis: int, w_mm: float, v_mm_s: float, n: int
) -> tuple[float, float, float, float]:
    """Smallest beta of ``axis`` on an n³ grid of ``(x1, x2, x̄2)``, and where it is."""
    o = _block(p, axis)
    best, bx1, bx2, bv = np.inf, 0.0, 0.0, 0.0
    for i in range(n):
        x1 = -w_mm + 2.0 * w_mm * i / (n - 1)
        for j in range(n):
            x2 = -v_mm_s + 2.0 * v_mm_s * j / (n - 1)
            for k in range(n):
                v = -v_mm_s + 2.0 * v_mm_s * k / (n - 1)
                b = _alpha_beta(p, o, x1, x2, v)[1]
                if not b >= best:  # NaN is the smallest
                    best, bx1, bx2, bv = b, x1, x2, v
    return best, bx1, bx2, bv


_GAINS = ("alpha_square_gain", "alpha_cross_gain", "beta_velocity_gain", "beta_cross_gain")
_PER_AXIS = {
    "numerator_mm_per_v_s2": ("mm/(V s^2)", check_positive),
    "damping_per_s": ("1/s", check_positive),
    "stiffness_per_s2": ("1/s^2", check_positive),
    "disturbance_mm_s2": ("mm/s^2", check_nonnegative),
    "noise_rms_mm": ("mm", check_nonnegative),
    "noise_time_constant_s": ("s", check_nonnegative),
}


@dataclass(frozen=True, kw_only=True)
class NanomanipulatorParams:
    """Parameters of the two-axis nonlinear twin (seed 001 eqs. (1), (9), §4.1).

    Values and their sources: ``data/nanomanipulator_twin.toml`` (`load_params`). Per-axis
    values are pairs ``(x, y)``.

    Parameters
    ----------
    sample_rate_hz : float
        Sample rate, Hz.
    rk4_substeps : int
        RK4 sub-steps per sample (>= 1).
    numerator_mm_per_v_s2, damping_per_s, stiffness_per_s2 : tuple of float
        ``K``, ``a1``, ``a0`` of eq. (9) per axis: mm/(V s²), 1/s, 1/s².
    length_scale_mm : float
        ``L`` of the scaled equation in which the §4.1 terms act, mm.
    alpha_square_gain, alpha_cross_gain, beta_velocity_gain, beta_cross_gain : float
        Gains of the §4.1 terms ``x1²``, ``x1 x̄2``, ``x2²``, ``-x1² x̄2`` (1 = seed, 0 = off).
    fig5_stiffening : float
        Relative stiffness rise at full stroke (Fig. 5 option), > -1; 0 = off.
    fig5_force_drop : float
        Relative fall of the force constant at full stroke, in [0, 1); 0 = off.
    workspace_mm : float
        Half range of each axis, mm.
    velocity_limit_mm_s : float
        Largest speed per axis the beta check covers, mm/s.
    beta_min_fraction : float
        ``beta_min / K`` in (0, 1].
    disturbance_mm_s2 : tuple of float
        Bound ``d0`` of ``d(t)`` per axis, mm/s² (0 = none).
    disturbance_frequencies_hz, disturbance_weights : tuple of float
        Sinusoids of ``d``: frequencies (Hz, below Nyquist), shares of ``d0`` (sum 1).
    disturbance_seed : int
        Seed of the sinusoids' random phases.
    noise_rms_mm : tuple of float
        Encoder noise rms per axis, mm (added by the simulators, not by the plant).
    noise_time_constant_s : tuple of float
        Colour of the encoder noise per axis: time constant ``τ`` of a first-order
        low-pass (corner ``1/(2π τ)``), s; 0 = white (the neutral value).

    Raises
    ------
    ValueError
        On a value out of range (naming it, its value and unit) or when beta falls below
        ``beta_min`` in the workspace (`check_beta`).
    """

    sample_rate_hz: float
    rk4_substeps: int
    numerator_mm_per_v_s2: tuple[float, float]
    damping_per_s: tuple[float, float]
    stiffness_per_s2: tuple[float, float]
    length_scale_mm: float
    alpha_square_gain: float
    alpha_cross_gain: float
    beta_velocity_gain: float
    beta_cross_gain: float
    fig5_stiffening: float
    fig5_force_drop: float
    workspace_mm: float
    velocity_limit_mm_s: float
    beta_min_fraction: float
    disturbance_mm_s2: tuple[float, float]
    disturbance_frequencies_hz: tuple[float, ...]
    disturbance_weights: tuple[float, ...]
    disturbance_seed: int
    noise_rms_mm: tuple[float, float]
    noise_time_constant_s: tuple[float, float]

    def __post_init__(self) -> None:
        fs = check_positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        check_int("rk4_substeps", self.rk4_substeps, 1)
        for name, (unit, check) in _PER_AXIS.items():
            object.__setattr__(self, name, check_axis_pair(name, getattr(self, name), unit, check))
        for name in _GAINS:
            check_finite(name, getattr(self, name))
        check_positive("length_scale_mm", self.length_scale_mm, "mm")
        check_positive("workspace_mm", self.workspace_mm, "mm")
        check_positive("velocity_limit_mm_s", self.velocity_limit_mm_s, "mm/s")
        check_in_range("fig5_stiffening", self.fig5_stiffening, -1.0, 1e3, low_closed=False)
        check_in_range("fig5_force_drop", self.fig5_force_drop, 0.0, 1.0, high_closed=False)
        check_in_range("beta_min_fraction", self.beta_min_fraction, 0.0, 1.0, low_closed=False)
        check_int("disturbance_seed", self.disturbance_seed, 0)
        freqs = tuple(self.disturbance_frequencies_hz)
        weights = tuple(self.disturbance_weights)
        if len(freqs) != len(weights) or not freqs:
            raise ValueError(
                f"disturbance_frequencies_hz ({len(freqs)} values) and disturbance_weights "
                f"({len(weights)}) need the same non-zero length: one weight per frequency"
            )
        for j, (f, w) in enumerate(zip(freqs, weights, strict=True)):
            check_in_range(
                f"disturbance_frequencies_hz[{j}]", f, 0.0, fs / 2, "Hz", low_closed=False
            )
            check_nonnegative(f"disturbance_weights[{j}]", w)
        if abs(sum(weights) - 1.0) > 1e-9:
            raise ValueError(
                f"disturbance_weights must sum to 1 so that |d(t)| <= d0, got sum {sum(weights)}; "
                "rescale them"
            )
        object.__setattr__(self, "disturbance_frequencies_hz", tuple(float(f) for f in freqs))
        object.__setattr__(self, "disturbance_weights", tuple(float(w) for w in weights))
        check_beta(self)

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return 1.0 / self.sample_rate_hz

    def natural_frequency_hz(self) -> tuple[float, ...]:
        """Undamped natural frequency of eq. (9) per axis, Hz (seed: 50.78, 50.24)."""
        return tuple(math.sqrt(a0) / (2 * math.pi) for a0 in self.stiffness_per_s2)

    def damping_ratio(self) -> tuple[float, ...]:
        """Damping ratio of eq. (9) per axis (seed: 0.0233, 0.0293)."""
        pairs = zip(self.damping_per_s, self.stiffness_per_s2, strict=True)
        return tuple(a1 / (2 * math.sqrt(a0)) for a1, a0 in pairs)

    def dc_gain_mm_per_v(self) -> tuple[float, ...]:
        """DC gain ``K / a0`` of eq. (9) per axis, mm/V (seed: 5.386, 3.209)."""
        pairs = zip(self.numerator_mm_per_v_s2, self.stiffness_per_s2, strict=True)
        return tuple(k / a0 for k, a0 in pairs)

    def disturbance_phases(self) -> np.ndarray:
        """Random phases of the sinusoids of ``d(t)``, rad, shape (2, n_sinusoids)."""
        rng = np.random.default_rng(self.disturbance_seed)
        return rng.uniform(0.0, 2 * np.pi, size=(2, len(self.disturbance_frequencies_hz)))

    def pack(self) -> np.ndarray:
        """The flat ``float64`` params of the kernels (layout in the module source)."""
        nd = len(self.disturbance_frequencies_hz)
        L, w2 = self.length_scale_mm, self.workspace_mm**2
        out = [self.dt, float(self.rk4_substeps), float(nd)]
        for i in range(2):
            a0 = self.stiffness_per_s2[i]
            wn = math.sqrt(a0)
            # a0 L ξ² = (a0/L) x1², a0 L ξ ξ̄' = a0/(wn L) x1 x̄2,
            # a0 L ξ'² = x2²/L,     a0 L ξ² ξ̄' = a0/(wn L²) x1² x̄2
            out += [
                a0,
                self.damping_per_s[i],
                self.numerator_mm_per_v_s2[i],
                a0 / L * self.alpha_square_gain,
                a0 / (wn * L) * self.alpha_cross_gain,
                self.beta_velocity_gain / L,
                a0 / (wn * L * L) * self.beta_cross_gain,
                a0 * self.fig5_stiffening / w2,
                self.fig5_force_drop / w2,
            ]
            for f, w in zip(self.disturbance_frequencies_hz, self.disturbance_weights, strict=True):
                theta = 2 * math.pi * f * self.dt
                out += [self.disturbance_mm_s2[i] * w, math.cos(theta), math.sin(theta)]
        return np.array(out, dtype=np.float64)

    def with_(self, **changes: Any) -> NanomanipulatorParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        return replace_known(self, "twin", **changes)

    def linear(self) -> NanomanipulatorParams:
        """A copy with the §4.1 terms and the Fig. 5 physics off (eq. (9) only)."""
        off = dict.fromkeys((*_GAINS, "fig5_stiffening", "fig5_force_drop"), 0.0)
        return self.with_(**off)


def beta_minimum(params: NanomanipulatorParams, axis: int) -> tuple[float, float, float, float]:
    """Smallest ``beta`` of one axis in the declared workspace and where it occurs.

    Parameters
    ----------
    params : NanomanipulatorParams
        The twin.
    axis : int
        0 for x, 1 for y.

    Returns
    -------
    tuple of float
        ``(beta, x1, x2, x̄2)`` in mm/(V s²), mm, mm/s, mm/s, on the 41³ grid of
        ``|x1| <= workspace_mm``, ``|x2|, |x̄2| <= velocity_limit_mm_s`` (corners, zero in it).
    """
    p = params.pack()
    return _beta_grid_min(p, axis, params.workspace_mm, params.velocity_limit_mm_s, _GRID)


def check_beta(params: NanomanipulatorParams) -> None:
    """Refuse (ValueError) a twin whose beta falls below ``beta_min`` in the workspace."""
    for i, ax in enumerate(AXES):
        b, x1, x2, v = beta_minimum(params, i)
        b_min = params.beta_min_fraction * params.numerator_mm_per_v_s2[i]
        if not b >= b_min:
            raise ValueError(
                f"beta of axis {ax} falls to {b:.6g} mm/(V s^2), below beta_min = {b_min:.6g} "
                f"mm/(V s^2) ({params.beta_min_fraction:g} K of eq. (9)) at x1 = {x1:.4g} mm, "
                f"x2 = {x2:.4g} mm/s, other axis x2 = {v:.4g} mm/s; reduce beta_velocity_gain, "
                "beta_cross_gain, fig5_force_drop or velocity_limit_mm_s"
            )


_SECTIONS = {  # TOML section -> the fields it holds (per-axis fields under [axes.x], [axes.y])
    "sampling": ("sample_rate_hz", "rk4_substeps"),
    "nonlinear": ("length_scale_mm", *_GAINS, "fig5_stiffening", "fig5_force_drop"),
    "workspace": ("workspace_mm", "velocity_limit_mm_s", "beta_min_fraction"),
    "disturbance": ("disturbance_frequencies_hz", "disturbance_weights", "disturbance_seed"),
}


def load_params(path: str | os.PathLike[str] | None = None) -> NanomanipulatorParams:
    """Read the twin's parameters from a TOML file (default ``data/nanomanipulator_twin.toml``).

    Every value needs a ``<key>_source`` string; unknown sections and keys are refused.

    Raises
    ------
    ValueError
        Naming the file, the section and the key.
    """
    values = read_sourced(
        path, "nanomanipulator_twin.toml", _SECTIONS, per_axis=tuple(_PER_AXIS), axes=AXES
    )
    return NanomanipulatorParams(**values)


_TERMS = ("alpha x1^2", "alpha x1*xbar2", "beta x2^2", "beta -x1^2*xbar2", "x1^2 in mm, s")


def term_shares(
    params: NanomanipulatorParams, amplitude_mm: float, frequency_hz: float = 1.0, axis: int = 0
) -> dict[str, float]:
    """Size of each §4.1 term relative to the linear term it adds to.

    Evaluated at ``x1 = A``, ``x2 = x̄2 = 2π f A`` (the peaks of a sine of amplitude ``A``
    taken together, an upper bound). Alpha terms are relative to the stiffness term ``a0 A``,
    beta terms to ``K``; the last entry is ``x1²`` read literally in mm and s (``A / a0``).

    Parameters
    ----------
    params : NanomanipulatorParams
        The twin.
    amplitude_mm : float
        ``A``, mm.
    frequency_hz : float
        ``f``, Hz.
    axis : int
        0 for x, 1 for y.

    Returns
    -------
    dict of str to float
        Absolute shares (dimensionless).
    """
    A = check_positive("amplitude_mm", amplitude_mm, "mm")
    v = 2 * math.pi * check_positive("frequency_hz", frequency_hz, "Hz") * A
    p = params.pack()
    o = _block(p, axis)
    a0, K = p[o + _A0], p[o + _K]
    return {
        _TERMS[0]: abs(p[o + _CAA] * A * A) / (a0 * A),
        _TERMS[1]: abs(p[o + _CAX] * A * v) / (a0 * A),
        _TERMS[2]: abs(p[o + _CBV] * v * v) / K,
        _TERMS[3]: abs(p[o + _CBX] * A * A * v) / K,
        _TERMS[4]: A / a0,
    }


def term_share_table(
    params: NanomanipulatorParams,
    amplitudes_mm: tuple[float, ...] = (0.01, 0.5),
    frequency_hz: float = 1.0,
) -> str:
    """A plain-text table of `term_shares` per axis and amplitude (for reports)."""
    cols = [(i, a) for i in range(2) for a in amplitudes_mm]
    head = f"{'term':<18}" + "".join(f"{AXES[i]} @ {a * 1e3:g} µm".rjust(15) for i, a in cols)
    shares = [term_shares(params, a, frequency_hz, i) for i, a in cols]
    rows = [f"§4.1 term shares at {frequency_hz:g} Hz (x1 = A, x2 = xbar2 = 2π f A)", head]
    rows += [f"{t:<18}" + "".join(f"{s[t]:15.3g}" for s in shares) for t in _TERMS]
    return "\n".join(rows)
