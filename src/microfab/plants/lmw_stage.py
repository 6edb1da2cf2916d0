"""Digital twin of the precise planar XY stage of seed 004 (§II.C, §III.A, Table I).

Each axis (x lower, y upper; no coupling between them) obeys seed 004 eq. (2) with the true
mass and force constant (the controllers get the nominal ones, `LMWStageParams.nominal`):

``M ẍ + F_l(x, ẋ, z) = K_f i``,  ``τ i̇ = i_r - i``,  ``i_r = clip(i_ref, ±F_peak / K_f)``,

in SI units (m, s, kg, A, N). The command is the current reference ``i_ref`` (A) of each
axis, held over the sample (ZOH); the amplifier is a first-order lag ``τ = 1 / (2π f_a)``
(2 kHz assumed) with a current limit at ``F_peak / K_f``, so the motor force ``K_f i``
saturates at Table I's 12 N peak (``saturation`` switch). The output is the encoder
position of each axis (m), rounded to the nearest 10 nm count (Table I; ``quantisation``
switch). Interpolation noise (``noise_rms_m``, 6.2 nm rms calibrated) is *not* added here:
the experiment draws it as the simulator's noise array, so it is added after the
quantiser (hardware quantises the noisy interpolated signal; per sample the two differ by
at most one count).

**Disturbance** ``F_l = s (F_f + F_cog + F_cab)`` with ``s = disturbance_scale`` (1.0 by
default; a free magnitude to be fitted to a seed number by a calibration step):

* LuGre friction (``friction`` switch): ``ż = ẋ - σ0 |ẋ| z / g(ẋ)``,
  ``g(v) = F_c + (F_s - F_c) exp(-(v / v_s)²)``, ``F_f = σ0 z + σ1 ż + σ2 ẋ``; the bristle
  deflection ``z`` (m) gives pre-sliding and the quadrant glitch at a velocity reversal;
* cogging ripple of the ironless motor (``cogging``): ``F_cog = A sin(2π x / p + φ)``;
* cable carrier (``cable``): ``F_cab = k (x - x_rest)``.

The friction part scales as a whole (``σ0``, ``σ1``, ``σ2``, ``F_c``, ``F_s`` together), so
``s`` leaves the bristle dynamics (``σ0 / g``) unchanged. With the default values, an 80 Hz
PID with the nominal acceleration feedforward tracking a 1 mm circle at 10 mm/s shows the
quadrant glitch as a 1.9 µm (x) / 2.2 µm (y) error peak some 14 ms after each velocity
reversal, against 0.02 µm before it and 0.007 µm with friction off (measured, not fitted).
``disturbance(state)`` is the mean
``F_l`` over the last sample (N), kept in the state for the "estimated vs true disturbance"
figure; ``force(state)`` is the motor force ``K_f i`` now (N).

**Integration.** Over a sample the amplifier current is exact,
``i(t) = i_r + (i_k - i_r) e^{-t/τ}``, and so is the motion it alone would cause (the
"motor flow" ``x_m(t)``, ``v_m(t)``, double integrals of ``i``: the ZOH model of
`linear_model`). The departure from it, ``(p, q) = (x - x_m, ẋ - v_m)``, and the bristle
deflection ``z`` obey ``ṗ = q``, ``q̇ = -F_l / M``, ``ż`` as above, integrated by classical
RK4 with ``n`` sub-steps, ``x_m``, ``v_m`` evaluated exactly at the stage times. With the
nonlinear parts off ``F_l = 0`` and the twin *is* the ZOH model (to rounding, ~1e-16
relative per sample). The bristle relaxation rate ``σ0 |ẋ| / g(ẋ)`` (1e5 1/s at 0.1 m/s)
makes the problem stiff, so ``n`` rises with the speed:
``n = clip(ceil(dt σ0 v_b / (c F_c)), n_min, n_max)`` with ``v_b`` the larger of the
speeds at the start and end of the motor flow, ``c = relaxation_per_substep`` (0.5: well
inside RK4's stability bound 2.79 for a decaying mode), ``n_min = 4``, ``n_max = 4000``
(stable to about 1.6 m/s with the calibrated bristles, σ0 / F_c = 7e7 1/m).
Measured against a 10x finer integration (``n_min``, ``n_max`` x10, ``c`` / 10; encoder
unquantised, PID loop at 80 Hz) with the bristles assumed before issue 45's calibration
(σ0 / F_c = 1e6 1/m); with the calibrated ones, 1.2e-10 m on the 30 µm circle at 10 mm/s
and 1.2e-11 m on the 5 mm move): 1.5e-11 m in position on a 30 µm
circle at 10 mm/s with quadrant reversals, 1.0e-12 m on a 1 mm circle at 10 mm/s, 4.0e-12 m
on a 5 mm move at 0.1 m/s (1/700 of the 10 nm count or less; the 10x finer run is itself
within 2e-13 m of a 100x finer one); the mean ``F_l`` to 2e-7 N. Cost about 2 µs per
sample at 10 mm/s, 12 µs at 0.1 m/s (the count rises to about 20). Checked by
``test_integration_converged`` in ``tests/plants/test_lmw_stage.py``.

State (flat, 11): ``[x, ẋ, i, z]`` of x, the same of y (m, m/s, A, m), the mean ``F_l`` of
the last sample for x and y (N), the sample counter.

Seed points: eq. (2) writes ``M_n`` and ``K_fn`` (nominal) with ``F_l`` holding everything
else; the plant uses true values 10 % off (assumed) so that the difference lands in the
observer's disturbance as it would on hardware. Table I gives no moving masses per axis:
the stacking (x carries y) and the payload are assumed (data file).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from numba import njit

import control
from microfab.plants import friction as _f
from microfab.plants.base import CompiledPlant, LTIPlant, NoiseLevel, NoisyOutputs
from microfab.plants.friction import friction_force
from microfab.plants.lmw_stage_params import (
    _BLOCK,
    _FRIC,
    _H_DT,
    _H_FRIC,
    _H_NMAX,
    _H_NMIN,
    _H_QUANT,
    _H_RELAX,
    _H_RES,
    _H_SAT,
    _H_SCALE,
    _HEADER,
    _IPK,
    _K,
    _M,
    _TAU,
    AXES,
    SWITCHES,
    LMWStageParams,
    StageNominal,
    load_params,
)
from microfab.plants.lti import DiscreteLTI, block_diag, discretize

__all__ = [
    "AXES",
    "SWITCHES",
    "LMWStage",
    "LMWStageParams",
    "StageNominal",
    "kernel_output",
    "kernel_update",
    "lmw_stage_twin",
    "load_params",
]

_N_AXIS = 4  # x, v, i, z per axis
_I_FL = 2 * _N_AXIS  # mean F_l of the last sample, x then y
_I_K = _I_FL + 2  # sample counter
_N_STATE = _I_K + 1


@njit(cache=True, inline="always")
def _motor_flow(
    t: float, x0: float, v0: float, ir: float, c: float, tau: float, km: float
) -> tuple[float, float]:
    """``(x_m, v_m)`` at ``t`` of the motion the amplifier current alone causes (exact)."""
    em = -math.expm1(-t / tau)  # 1 - e^{-t/τ}
    j1 = ir * t + c * tau * em
    j2 = ir * t * t * 0.5 + c * tau * (t - tau * em)
    return x0 + v0 * t + km * j2, v0 + km * j1


@njit(cache=True, inline="always")
def _rates(p: np.ndarray, b: int, x: float, v: float, z: float) -> tuple[float, float]:
    """``(ż, F_l)`` of the axis at block ``b``: bristle rate (m/s) and disturbance (N)."""
    f, zd, _g = friction_force(p, b + _FRIC, x, v, z)
    return zd, p[_H_SCALE] * f


@njit(cache=True, inline="always")
def _substeps(p: np.ndarray, b: int, v_bound: float) -> int:
    """Sub-steps of one sample for an axis moving at up to ``v_bound`` (m/s)."""
    nmin = p[_H_NMIN]
    if p[_H_FRIC] == 0.0:
        return int(nmin)
    nf = p[_H_DT] * p[b + _FRIC + _f._S0] * v_bound / (p[_H_RELAX] * p[b + _FRIC + _f._FC])
    if nf <= nmin:
        return int(nmin)
    if not nf < p[_H_NMAX]:  # NaN too
        return int(p[_H_NMAX])
    return math.ceil(nf)


@njit(cache=True, inline="always")
def _axis_update(p: np.ndarray, s: np.ndarray, axis: int, i_ref: float) -> None:
    """Advance the axis's ``[x, v, i, z]`` one sample in place; store its mean ``F_l``."""
    b = _HEADER + axis * _BLOCK
    o = axis * _N_AXIS
    dt = p[_H_DT]
    tau = p[b + _TAU]
    km = p[b + _K] / p[b + _M]
    ir = i_ref
    if p[_H_SAT] != 0.0:
        ipk = p[b + _IPK]
        ir = min(max(ir, -ipk), ipk)
    x0, v0, i0, z = s[o], s[o + 1], s[o + 2], s[o + 3]
    c = i0 - ir
    xe, ve = _motor_flow(dt, x0, v0, ir, c, tau, km)
    n = _substeps(p, b, max(abs(v0), abs(ve)))
    h = dt / n
    inv_m = 1.0 / p[b + _M]
    pp = 0.0  # x - x_m
    qq = 0.0  # v - v_m
    fsum = 0.0
    for j in range(n):
        t = j * h
        xm, vm = _motor_flow(t, x0, v0, ir, c, tau, km)
        z1, f1 = _rates(p, b, xm + pp, vm + qq, z)
        p1, q1 = qq, -f1 * inv_m
        xm, vm = _motor_flow(t + 0.5 * h, x0, v0, ir, c, tau, km)
        z2, f2 = _rates(p, b, xm + pp + 0.5 * h * p1, vm + qq + 0.5 * h * q1, z + 0.5 * h * z1)
        p2, q2 = qq + 0.5 * h * q1, -f2 * inv_m
        z3, f3 = _rates(p, b, xm + pp + 0.5 * h * p2, vm + qq + 0.5 * h * q2, z + 0.5 * h * z2)
        p3, q3 = qq + 0.5 * h * q2, -f3 * inv_m
        xm, vm = _motor_flow(t + h, x0, v0, ir, c, tau, km)
        z4, f4 = _rates(p, b, xm + pp + h * p3, vm + qq + h * q3, z + h * z3)
        p4, q4 = qq + h * q3, -f4 * inv_m
        pp += h / 6.0 * (p1 + 2.0 * p2 + 2.0 * p3 + p4)
        qq += h / 6.0 * (q1 + 2.0 * q2 + 2.0 * q3 + q4)
        z += h / 6.0 * (z1 + 2.0 * z2 + 2.0 * z3 + z4)
        fsum += h / 6.0 * (f1 + 2.0 * f2 + 2.0 * f3 + f4)
    s[o] = xe + pp
    s[o + 1] = ve + qq
    s[o + 2] = ir + c * math.exp(-dt / tau)
    s[o + 3] = z
    s[_I_FL + axis] = fsum / dt


@njit(cache=True)
def kernel_output(p: np.ndarray, s: np.ndarray, y: np.ndarray) -> None:
    """Write the encoder positions ``(x, y)`` (m) into ``y``, shape (2,)."""
    q = p[_H_RES]
    for a in range(2):
        x = s[a * _N_AXIS]
        y[a] = math.floor(x / q + 0.5) * q if p[_H_QUANT] != 0.0 else x


@njit(cache=True)
def kernel_update(p: np.ndarray, s: np.ndarray, u: np.ndarray) -> None:
    """Advance ``s`` one sample in place under the current references ``u`` (A), held."""
    _axis_update(p, s, 0, u[0])
    _axis_update(p, s, 1, u[1])
    s[_I_K] += 1.0


class LMWStage(CompiledPlant, NoisyOutputs):
    """The two-axis stage twin as a compiled plant (commands i_ref in A, outputs in m).

    Parameters
    ----------
    config : LMWStageParams
        The twin's parameters.

    Attributes
    ----------
    noise_level : NoiseLevel
        Encoder interpolation noise per axis, m (``noise_rms_m``); `noise` draws it, seeded.

    Notes
    -----
    State: ``[x, ẋ, i, z]`` per axis (x then y; m, m/s, A, m), the mean ``F_l`` of the last
    sample per axis (N), the sample counter: shape (11,). ``output`` and ``update`` are plain
    Python written from ``config`` (not from the packed kernels), for the Python loop and as
    a check of the kernels (the disturbance through the same `StageFriction` kernel); both
    agree to rounding.
    """

    kernel_output: Any = kernel_output
    kernel_update: Any = kernel_update
    n_inputs = 2
    n_outputs = 2

    def __init__(self, config: LMWStageParams) -> None:
        self.config = config
        self.params = config.pack()
        self.params.setflags(write=False)
        self.dt = config.dt
        self.noise_level = NoiseLevel(config.noise_rms_m, "m")

    # --- state ---------------------------------------------------------------------------

    def init(self) -> np.ndarray:
        """At rest at the origin, bristles relaxed, no current, sample 0."""
        return self.state_at((0.0, 0.0))

    def state_at(self, position_m: tuple[float, float]) -> np.ndarray:
        """At rest at ``position_m`` (m, per axis), bristles relaxed, no current, sample 0.

        The stored ``F_l`` is its value there (cogging and cable; friction at rest is 0).
        """
        s = np.zeros(_N_STATE)
        for a in range(2):
            s[a * _N_AXIS] = float(position_m[a])
            s[_I_FL + a] = self._disturbance_force(a, float(position_m[a]), 0.0, 0.0)[1]
        return s

    def output(self, state: np.ndarray) -> np.ndarray:
        """Encoder positions ``(x, y)``, m, shape (2,): rounded to the nearest count."""
        c = self.config
        out = np.empty(2)
        for a in range(2):
            x = float(state[a * _N_AXIS])
            q = c.encoder_resolution_m
            out[a] = math.floor(x / q + 0.5) * q if c.quantisation else x
        return out

    def force(self, state: np.ndarray) -> np.ndarray:
        """Motor force ``K_f i`` per axis now, N: shape (2,), or (n, 2) for states (n, 11).

        Within ±F_peak when limited.
        """
        c = self.config
        s = np.asarray(state)
        return np.stack(
            [c.force_constant_n_per_a[a] * s[..., a * _N_AXIS + 2] for a in range(2)], axis=-1
        )

    def disturbance(self, state: np.ndarray) -> np.ndarray:
        """True ``F_l`` per axis (its mean over the last sample), N: shape (2,) or (n, 2)."""
        return np.array(np.asarray(state)[..., _I_FL : _I_FL + 2])

    def linear_state(self, state: np.ndarray) -> np.ndarray:
        """The states of `linear_model`, ``[x, ẋ, i]`` of x then y: shape (6,) or (n, 6)."""
        s = np.asarray(state)
        return np.concatenate([s[..., 0:3], s[..., _N_AXIS : _N_AXIS + 3]], axis=-1)

    def nominal(self) -> StageNominal:
        """The nominal model a controller is given (M_n, K_fn, amplifier, Table I)."""
        return self.config.nominal()

    # --- Python reference of the kernels ----------------------------------------------------

    def _disturbance_force(self, a: int, x: float, v: float, z: float) -> tuple[float, float]:
        """``(ż, F_l)`` of axis ``a`` at ``x``, ``v``, ``z`` (m/s, N): scaled `StageFriction`."""
        f, zdot, _g = self.config.friction_laws[a].force(x, v, z)
        return zdot, self.config.disturbance_scale * f

    def _axis(self, a: int, xs: list[float], i_ref: float) -> tuple[list[float], float]:
        """``([x, v, i, z], mean F_l)`` of axis ``a`` one sample after ``xs``."""
        c = self.config
        dt = self.dt
        m, kf = c.mass_kg[a], c.force_constant_n_per_a[a]
        tau = 1.0 / (2 * math.pi * c.amplifier_bandwidth_hz[a])
        ir = i_ref
        if c.saturation:
            ipk = c.peak_force_n[a] / kf
            ir = min(max(ir, -ipk), ipk)
        x0, v0, i0, z = xs
        d_i = i0 - ir

        def motor(t: float) -> tuple[float, float]:
            em = -math.expm1(-t / tau)
            vel = v0 + kf / m * (ir * t + d_i * tau * em)
            pos = x0 + v0 * t + kf / m * (ir * t * t * 0.5 + d_i * tau * (t - tau * em))
            return pos, vel

        def rate(t: float, y: list[float]) -> tuple[list[float], float]:
            xm, vm = motor(t)
            zd, f = self._disturbance_force(a, xm + y[0], vm + y[1], y[2])
            return [y[1], -f / m, zd], f

        xe, ve = motor(dt)
        n = c.substeps_min
        if c.friction:
            nf = dt * c.bristle_stiffness_n_per_m[a] * max(abs(v0), abs(ve))
            nf /= c.relaxation_per_substep * c.coulomb_n[a]
            n = c.substeps_max if not nf < c.substeps_max else max(n, math.ceil(nf))
        h = dt / n
        y = [0.0, 0.0, z]
        fsum = 0.0
        for j in range(n):
            t = j * h
            k1, f1 = rate(t, y)
            k2, f2 = rate(t + h / 2, [y[r] + h / 2 * k1[r] for r in range(3)])
            k3, f3 = rate(t + h / 2, [y[r] + h / 2 * k2[r] for r in range(3)])
            k4, f4 = rate(t + h, [y[r] + h * k3[r] for r in range(3)])
            y = [y[r] + h / 6 * (k1[r] + 2 * k2[r] + 2 * k3[r] + k4[r]) for r in range(3)]
            fsum += h / 6 * (f1 + 2 * f2 + 2 * f3 + f4)
        i_end = ir + d_i * math.exp(-dt / tau)
        return [xe + y[0], ve + y[1], i_end, y[2]], fsum / dt

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """State one sample later (a new array): current references ``command`` (A) held."""
        new = np.array(state, dtype=float, copy=True)
        for a in range(2):
            o = a * _N_AXIS
            xs = [float(v) for v in state[o : o + _N_AXIS]]
            axis, fmean = self._axis(a, xs, float(command[a]))
            new[o : o + _N_AXIS] = axis
            new[_I_FL + a] = fmean
        new[_I_K] = float(state[_I_K]) + 1.0
        return new

    # --- linear model ----------------------------------------------------------------------

    def continuous_models(self, nominal: bool = False) -> list[control.StateSpace]:
        """Per axis ``ẋ = v``, ``M v̇ = K_f i``, ``τ i̇ = i_ref - i`` (python-control, m/A).

        States ``(x, v, i)``; ``nominal`` uses ``M_n``, ``K_fn`` instead of the true values.
        """
        c = self.config
        mass = c.nominal_mass_kg if nominal else c.mass_kg
        kf = c.nominal_force_constant_n_per_a if nominal else c.force_constant_n_per_a
        tau = c.amplifier_time_constant_s()
        return [
            control.ss(
                [[0.0, 1.0, 0.0], [0.0, 0.0, kf[a] / mass[a]], [0.0, 0.0, -1.0 / tau[a]]],
                [[0.0], [0.0], [1.0 / tau[a]]],
                [[1.0, 0.0, 0.0]],
                [[0.0]],
            )
            for a in range(2)
        ]

    def linear_model(self, nominal: bool = False) -> DiscreteLTI:
        """ZOH of the stage with every nonlinear part off, both axes block-diagonal.

        Six states ``[x, ẋ, i]`` of x then y (`linear_state` reads them from a twin state),
        inputs ``i_ref`` (A), outputs positions (m). The true mass and force constant, or the
        nominal ones with ``nominal=True``.
        """
        return block_diag(*(discretize(m, self.dt, "zoh") for m in self.continuous_models(nominal)))

    def linear_plant(self, nominal: bool = False) -> LTIPlant:
        """`linear_model` as an `LTIPlant`."""
        return LTIPlant(self.linear_model(nominal))


def lmw_stage_twin(
    path: str | os.PathLike[str] | None = None,
    *,
    params: LMWStageParams | None = None,
    ideal: bool = False,
    **overrides: Any,
) -> LMWStage:
    """The stage twin from the data file, with validated ``overrides``.

    Parameters
    ----------
    path : path-like, optional
        Another parameter file (default ``data/lmw_stage.toml``).
    params : LMWStageParams, optional
        Parameters already read (then ``path`` is not read); the machine modules pass
        the ones they parsed once (`microfab.machines.twins`).
    ideal : bool
        True turns every nonlinear part off (friction, cogging, cable, saturation,
        quantisation): the twin is then `LMWStage.linear_model` (to rounding).
    **overrides
        `LMWStageParams` fields to replace (after ``ideal``, so a switch may be turned on
        again).
    """
    cfg = load_params(path) if params is None else params
    if ideal:
        cfg = cfg.linear()
    return LMWStage(cfg.with_(**overrides) if overrides else cfg)
