"""Parameters of the seed 002 black-box XY stage twin: dataclass, data file, gains, packing.

`XYStageParams` holds Table I of seed 002 (speed, acceleration, workspace, loop rate,
repeatability) and every assumed value of the stand-in physics that
`microfab.plants.xy_stage` states in its module docstring (moving masses, motors, the
built-in controller's design targets, friction, cogging, cable carrier, carriage
resonance, reaction coupling, encoder); `load_params` reads them from
``data/xy_stage_twin.toml`` (every value with its ``<key>_source``). Derived here:

* `XYStageParams.gains`: the built-in PID's gains (``Kp``, ``Ki``, ``Kd`` per axis) placed on
  the rigid moving mass of each axis so that the closed loop has the slow real pole
  ``1 / slow_time_constant_s`` and a pair at ``bandwidth_hz`` with ``damping_ratio``;
* `XYStageParams.mechanics`: the continuous linear mechanics (both axes, the y -> x reaction
  coupling, the carriage resonance) and its ZOH discretisations;
* `XYStageParams.pack`: the flat ``float64`` parameters of the numba kernels.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import scipy.linalg

from microfab.core.limits import MachineLimits
from microfab.core.validate import (
    check_axis_pair,
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    replace_known,
)
from microfab.plants.friction import FRICTION_FIELDS, N_FRICTION, StageFriction
from microfab.plants.sourced_toml import read_sourced

__all__ = [
    "AXES",
    "NONLINEAR",
    "N_MECH",
    "SWITCHES",
    "PIDGains",
    "XYStageParams",
    "load_params",
]

AXES = ("x", "y")
NONLINEAR = ("friction", "cogging", "cable", "saturation", "quantisation")
SWITCHES = (*NONLINEAR, "resonance", "coupling")

# Mechanical states (both axes in one linear system, the coupling joins them):
# [x, vx, Fx, yc, vyc, yh, vyh, Fy]: x carriage position and speed, x motor force, y carriage
# (motor forcer, encoder) position and speed, y head position and speed, y motor force.
N_MECH = 8
MECH_POS = (0, 3)  # carriage (encoder) position of each axis
MECH_VEL = (1, 4)
MECH_FORCE = (2, 7)

# flat params of the kernels: a header, one block per axis (the built-in controller, then the
# axis's `StageFriction` block, whose cable is y's), then the matrices
(
    _H_DT,
    _H_NSUB,
    _H_FRIC,
    _H_COG,
    _H_CAB,
    _H_SAT,
    _H_QUANT,
    _H_RES,
    _H_WLO,
    _H_WHI,
    _H_VMAX,
    _H_AMAX,
    _H_DIST,
    _H_TOL,
    _H_RES,
) = range(15)
_HEADER = 15
_KP, _KI_DT, _KD_B, _AD, _MFF, _CFF, _FPK = range(7)
_FRIC = 7  # the axis's `StageFriction` block (`microfab.plants.friction`)
_BLOCK = _FRIC + N_FRICTION
_PHI_DT = _HEADER + 2 * _BLOCK
_GU_DT = _PHI_DT + N_MECH * N_MECH
_PHI_H = _GU_DT + N_MECH * 2
_GU_H = _PHI_H + N_MECH * N_MECH
_GD_H = _GU_H + N_MECH * 2
_N_PARAMS = _GD_H + N_MECH * 2

# relative slack of the set-point guard's speed and acceleration tests, so that a command
# sampled exactly at a Table I limit passes despite rounding of its differences
GUARD_TOLERANCE = 1e-9

_PER_AXIS: dict[str, tuple[str, Any]] = {
    "mass_kg": ("kg", check_positive),
    "peak_force_n": ("N", check_positive),
    "current_bandwidth_hz": ("Hz", check_positive),
    "feedforward_mass_kg": ("kg", check_nonnegative),
    "feedforward_viscous_n_s_per_m": ("N s/m", check_nonnegative),
}
# the y cable carrier's fields (scalars, y only), checked by y's `StageFriction`
_CABLE_FIELDS = (
    "cable_stiffness_n_per_m",
    "cable_rest_m",
    "cable_link_force_n",
    "cable_link_pitch_m",
    "cable_link_phase_rad",
)
# the keys of each [axes.<name>] table of the data file
_FILE_PER_AXIS = (*tuple(_PER_AXIS)[:3], *FRICTION_FIELDS, *tuple(_PER_AXIS)[3:])


@dataclass(frozen=True)
class PIDGains:
    """Gains of the built-in PID of one axis (force out, position error in).

    Attributes
    ----------
    kp : float
        Proportional gain, N/m.
    ki : float
        Integral gain, N/(m s).
    kd : float
        Derivative gain, N s/m (filtered at ``derivative_filter_hz``).
    """

    kp: float
    ki: float
    kd: float


@dataclass(frozen=True, kw_only=True)
class XYStageParams:
    """Parameters of the black-box XY stage twin (seed 002 Table I and assumed values).

    Values and their sources: ``data/xy_stage_twin.toml`` (`load_params`). Per-axis values
    are pairs ``(x, y)``. Units SI: m, s, kg, N.

    Parameters
    ----------
    sample_rate_hz : float
        Rate of the built-in loop and of the set-point input, Hz (Table I: 10 kHz).
    substeps : int
        Sub-steps per sample over which the friction, cogging and cable forces are held
        (>= 1); the motor force and the linear mechanics are exact over each.
    workspace_m : tuple of float
        ``(min, max)`` set-point position of both axes, m (Table I: ±0.19 m).
    velocity_limit_m_s, acceleration_limit_m_s2 : float
        Largest set-point speed and acceleration per axis, m/s and m/s² (Table I).
    noise_rms_m : float
        Output noise rms per axis, m (eq. (3): 2 µm); drawn by `XYStagePlant.noise`.
    encoder_resolution_m : float
        Encoder count, m.
    slow_time_constant_s : float
        The built-in loop's slow real closed-loop pole ``-1 / slow_time_constant_s``, s.
    bandwidth_hz, damping_ratio : float
        The built-in loop's closed-loop pole pair: natural frequency (Hz, below the
        Nyquist frequency) and damping ratio in (0, 2].
    derivative_filter_hz : float
        First-order filter of the PID's derivative term, Hz (below Nyquist).
    head_mass_kg : float
        Mass on the y carriage's compliant mount (the head), kg.
    resonance_hz, resonance_damping : float
        The y carriage resonance (head against carriage), Hz and damping ratio in (0, 1).
    cable_stiffness_n_per_m, cable_rest_m : float
        y cable carrier spring ``k (y - y_rest)``: N/m, m.
    cable_link_force_n, cable_link_pitch_m, cable_link_phase_rad : float
        y cable carrier link ripple ``A sin(2π y / p + φ)``: N, m, rad.
    reaction_coupling : float
        Fraction of the y motor force that reacts on the x carriage (guide skew), in
        [-0.1, 0.1].
    friction, cogging, cable, saturation, quantisation, resonance, coupling : bool
        Switches. `NONLINEAR` off gives the linear twin of `XYStagePlant.linear_model`;
        ``resonance`` and ``coupling`` are linear and stay in that model when on.
    mass_kg : tuple of float
        Moving mass of each axis's own carriage, kg: x without the y axis it carries, y
        the carriage with the motor forcer and the encoder, without the head.
    peak_force_n : tuple of float
        Motor force limit per axis, N.
    current_bandwidth_hz : tuple of float
        First-order lag of the motor force (current loop) per axis, Hz, below Nyquist.
    coulomb_n, static_n, stribeck_m_s : tuple of float
        LuGre ``F_c``, ``F_s`` (>= ``F_c``), ``v_s`` per axis: N, N, m/s. These
        and the friction, cogging and cable values below make each axis's `StageFriction`
        (`friction_laws`), which checks them: the law of `microfab.plants.friction`.
    bristle_stiffness_n_per_m, bristle_damping_n_s_per_m, viscous_n_s_per_m : tuple
        LuGre ``σ0``, ``σ1``, ``σ2`` per axis: N/m, N s/m, N s/m.
    cogging_n, cogging_pitch_m, cogging_phase_rad : tuple of float
        Cogging ``A sin(2π x / p + φ)`` at the motor pitch per axis: N, m, rad.
    feedforward_mass_kg, feedforward_viscous_n_s_per_m : tuple of float
        The built-in feedforward ``m_ff r̈ + c_ff ṙ`` per axis: kg, N s/m.

    Raises
    ------
    ValueError
        On a value out of range, naming it, its value, unit and the fix.
    """

    sample_rate_hz: float
    substeps: int
    workspace_m: tuple[float, float]
    velocity_limit_m_s: float
    acceleration_limit_m_s2: float
    noise_rms_m: float
    encoder_resolution_m: float
    slow_time_constant_s: float
    bandwidth_hz: float
    damping_ratio: float
    derivative_filter_hz: float
    head_mass_kg: float
    resonance_hz: float
    resonance_damping: float
    cable_stiffness_n_per_m: float
    cable_rest_m: float
    cable_link_force_n: float
    cable_link_pitch_m: float
    cable_link_phase_rad: float
    reaction_coupling: float
    friction: bool
    cogging: bool
    cable: bool
    saturation: bool
    quantisation: bool
    resonance: bool
    coupling: bool
    mass_kg: tuple[float, float]
    peak_force_n: tuple[float, float]
    current_bandwidth_hz: tuple[float, float]
    coulomb_n: tuple[float, float]
    static_n: tuple[float, float]
    stribeck_m_s: tuple[float, float]
    bristle_stiffness_n_per_m: tuple[float, float]
    bristle_damping_n_s_per_m: tuple[float, float]
    viscous_n_s_per_m: tuple[float, float]
    cogging_n: tuple[float, float]
    cogging_pitch_m: tuple[float, float]
    cogging_phase_rad: tuple[float, float]
    feedforward_mass_kg: tuple[float, float]
    feedforward_viscous_n_s_per_m: tuple[float, float]

    def __post_init__(self) -> None:
        fs = check_positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        nyq = fs / 2
        check_int("substeps", self.substeps, 1)
        ws = check_axis_pair("workspace_m", self.workspace_m, "m", check_finite)
        if not ws[0] < ws[1]:
            raise ValueError(
                f"workspace_m = {ws} m must be (min, max) with min < max; swap or widen it"
            )
        object.__setattr__(self, "workspace_m", ws)
        check_positive("velocity_limit_m_s", self.velocity_limit_m_s, "m/s")
        check_positive("acceleration_limit_m_s2", self.acceleration_limit_m_s2, "m/s^2")
        check_nonnegative("noise_rms_m", self.noise_rms_m, "m")
        check_positive("encoder_resolution_m", self.encoder_resolution_m, "m")
        check_positive("slow_time_constant_s", self.slow_time_constant_s, "s")
        for name in ("bandwidth_hz", "derivative_filter_hz", "resonance_hz"):
            check_in_range(name, getattr(self, name), 0.0, nyq, "Hz", low_closed=False,
                           high_closed=False)  # fmt: skip
        check_in_range("damping_ratio", self.damping_ratio, 0.0, 2.0, low_closed=False)
        check_positive("head_mass_kg", self.head_mass_kg, "kg")
        check_in_range(
            "resonance_damping", self.resonance_damping, 0.0, 1.0, low_closed=False,
            high_closed=False,
        )  # fmt: skip
        check_in_range("reaction_coupling", self.reaction_coupling, -0.1, 0.1)
        for name in SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"switch {name} must be true or false, got {getattr(self, name)!r}"
                )
        for name, (unit, check) in _PER_AXIS.items():
            object.__setattr__(self, name, check_axis_pair(name, getattr(self, name), unit, check))
        laws = self.friction_laws  # checks the friction, cogging and cable values
        for name in FRICTION_FIELDS:
            object.__setattr__(self, name, tuple(getattr(law, name) for law in laws))
        for name in _CABLE_FIELDS:
            object.__setattr__(self, name, getattr(laws[1], name))
        for i, ax in enumerate(AXES):
            fa = self.current_bandwidth_hz[i]
            if fa >= nyq:
                raise ValueError(
                    f"current_bandwidth_hz[{ax}] = {fa} Hz must lie below the Nyquist "
                    f"frequency {nyq:g} Hz; lower it or raise sample_rate_hz"
                )

    # --- derived values --------------------------------------------------------------------

    @cached_property
    def friction_laws(self) -> tuple[StageFriction, StageFriction]:
        """The validated `StageFriction` of each axis ``(x, y)``: LuGre, cogging, cable (y).

        Built from the per-axis fields, the cable carrier's (on y only) and the
        ``friction``, ``cogging`` and ``cable`` switches.
        """
        return StageFriction.per_axis(
            {name: getattr(self, name) for name in FRICTION_FIELDS},
            each=(
                {"cable": False},
                {"cable": self.cable, **{name: getattr(self, name) for name in _CABLE_FIELDS}},
            ),
            friction=self.friction,
            cogging=self.cogging,
        )

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return 1.0 / self.sample_rate_hz

    def rigid_mass_kg(self) -> tuple[float, float]:
        """Mass each motor moves as a rigid body, kg: x carries all of y (carriage + head)."""
        my = self.mass_kg[1] + self.head_mass_kg
        return (self.mass_kg[0] + my, my)

    def current_time_constant_s(self) -> tuple[float, float]:
        """``τ = 1 / (2π f_i)`` of the motor force lag per axis, s."""
        return tuple(1.0 / (2 * math.pi * f) for f in self.current_bandwidth_hz)  # type: ignore[return-value]

    def gains(self) -> tuple[PIDGains, PIDGains]:
        """The built-in PID's gains per axis, placed on the rigid mass ``m`` of the axis.

        ``m s³ + Kd s² + Kp s + Ki = m (s + p)(s² + 2ζω s + ω²)`` with
        ``p = 1 / slow_time_constant_s``, ``ω = 2π bandwidth_hz``, ``ζ = damping_ratio``:
        the closed loop of the rigid axis (no force lag, derivative filter or sampling) has
        these poles; the twin's actual ones are those of `XYStagePlant.linear_model`.
        """
        p = 1.0 / self.slow_time_constant_s
        w = 2 * math.pi * self.bandwidth_hz
        z = self.damping_ratio
        return tuple(  # type: ignore[return-value]
            PIDGains(kp=m * (w * w + 2 * z * w * p), ki=m * p * w * w, kd=m * (2 * z * w + p))
            for m in self.rigid_mass_kg()
        )

    def derivative_filter(self) -> tuple[float, float]:
        """``(a, b)`` of the filtered derivative ``D_k = a D_k-1 + b Kd (e_k - e_k-1)``.

        ``a = exp(-ω_d dt)``, ``b = (1 - a) / dt``: at low frequency ``Kd ė``.
        """
        a = math.exp(-2 * math.pi * self.derivative_filter_hz * self.dt)
        return a, (1.0 - a) / self.dt

    def machine_limits(self) -> MachineLimits:
        """Table I as `microfab.core.limits.MachineLimits` (what the guard enforces)."""
        return MachineLimits(
            workspace=(self.workspace_m, self.workspace_m),
            velocity=(self.velocity_limit_m_s,) * 2,
            acceleration=(self.acceleration_limit_m_s2,) * 2,
        )

    def mechanics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous linear mechanics ``ṡ = A s + Bu F_cmd + Bd F_d`` of both axes.

        States `N_MECH`: ``[x, vx, Fx, yc, vyc, yh, vyh, Fy]``; ``F_cmd`` the commanded motor
        forces (into the force lags), ``F_d`` the disturbance forces opposing each carriage
        (friction, cogging, cable). With ``resonance`` off the head moves with the carriage
        (its rows copy the carriage's); with ``coupling`` on the x carriage feels
        ``-reaction_coupling Fy``.

        Returns
        -------
        A, Bu, Bd : numpy.ndarray
            Shapes (8, 8), (8, 2), (8, 2).
        """
        mx, my = self.rigid_mass_kg()
        mc, mh = self.mass_kg[1], self.head_mass_kg
        tx, ty = self.current_time_constant_s()
        A = np.zeros((N_MECH, N_MECH))
        Bu = np.zeros((N_MECH, 2))
        Bd = np.zeros((N_MECH, 2))
        A[0, 1] = 1.0
        A[1, 2] = 1.0 / mx
        if self.coupling:
            A[1, 7] = -self.reaction_coupling / mx
        Bd[1, 0] = -1.0 / mx
        A[2, 2] = -1.0 / tx
        Bu[2, 0] = 1.0 / tx
        A[3, 4] = 1.0
        A[5, 6] = 1.0
        if self.resonance:
            mu = mc * mh / (mc + mh)
            wr = 2 * math.pi * self.resonance_hz
            k = wr * wr * mu
            c = 2 * self.resonance_damping * wr * mu
            A[4, [3, 4, 5, 6, 7]] = [-k / mc, -c / mc, k / mc, c / mc, 1.0 / mc]
            A[6, [3, 4, 5, 6]] = [k / mh, c / mh, -k / mh, -c / mh]
            Bd[4, 1] = -1.0 / mc
        else:
            A[4, 7] = A[6, 7] = 1.0 / my
            Bd[4, 1] = Bd[6, 1] = -1.0 / my
        A[7, 7] = -1.0 / ty
        Bu[7, 1] = 1.0 / ty
        return A, Bu, Bd

    def discrete_mechanics(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ZOH of `mechanics` over ``h`` s: ``(Φ, Γu, Γd)``, shapes (8, 8), (8, 2), (8, 2)."""
        A, Bu, Bd = self.mechanics()
        n = N_MECH
        M = np.zeros((n + 4, n + 4))
        M[:n, :n] = A
        M[:n, n : n + 2] = Bu
        M[:n, n + 2 :] = Bd
        E = scipy.linalg.expm(M * h)
        return E[:n, :n].copy(), E[:n, n : n + 2].copy(), E[:n, n + 2 :].copy()

    def closed_loop(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B, C)`` of the discrete closed loop with the nonlinear parts off (ZOH).

        The built-in controller (guard passing, PID, feedforward) around the exact ZOH of
        `mechanics` over one sample. States: the 8 mechanical ones, ``[I, D, e_prev]`` per
        axis, ``[g, w]`` per axis (18); inputs the set-points, outputs the carriage
        positions. `microfab.plants.xy_stage.XYStagePlant.linear_model` drops the head's
        states when the resonance is off (they then copy the carriage's).
        """
        c = self
        dt = self.dt
        n = N_MECH + 10  # full layout: mechanics, controller (6), guard g, w (4)
        i_ctrl, i_guard = N_MECH, N_MECH + 6
        phi, gu, _gd = self.discrete_mechanics(dt)
        ad, bd = self.derivative_filter()
        A = np.zeros((n, n))
        B = np.zeros((n, 2))
        fA = np.zeros((2, n))  # commanded force = fA @ state + fB @ r
        fB = np.zeros((2, 2))
        for a, g in enumerate(self.gains()):
            o, q = i_ctrl + 3 * a, i_guard + 2 * a
            # e = r - y ; w = (r - g_prev) / dt ; aff = (w - w_prev) / dt
            eA = np.zeros(n)
            eA[MECH_POS[a]] = -1.0
            eB = np.zeros(2)
            eB[a] = 1.0
            wA = np.zeros(n)
            wA[q] = -1.0 / dt
            wB = eB / dt
            affA = wA / dt
            affA[q + 1] -= 1.0 / dt
            affB = wB / dt
            ki_e = g.ki * dt
            iA = np.zeros(n)
            iA[o] = 1.0
            iA += ki_e * eA
            iB = ki_e * eB
            dA = np.zeros(n)
            dA[o + 1] = ad
            dA += g.kd * bd * eA
            dA[o + 2] -= g.kd * bd
            dB = g.kd * bd * eB
            mff, cff = c.feedforward_mass_kg[a], c.feedforward_viscous_n_s_per_m[a]
            fA[a] = g.kp * eA + iA + dA + mff * affA + cff * wA
            fB[a] = g.kp * eB + iB + dB + mff * affB + cff * wB
            A[o], B[o] = iA, iB
            A[o + 1], B[o + 1] = dA, dB
            A[o + 2], B[o + 2] = eA, eB
            B[q, a] = 1.0
            A[q + 1], B[q + 1] = wA, wB
        A[:N_MECH] = gu @ fA
        A[:N_MECH, :N_MECH] += phi
        B[:N_MECH] = gu @ fB
        C = np.zeros((2, n))
        C[0, MECH_POS[0]] = C[1, MECH_POS[1]] = 1.0
        return A, B, C

    def any_disturbance(self) -> bool:
        """Whether a force is held over sub-steps (friction, cogging or cable on)."""
        return self.friction or self.cogging or self.cable

    # --- kernels ---------------------------------------------------------------------------

    def pack(self) -> np.ndarray:
        """The flat ``float64`` params of the kernels (layout in the module source)."""
        p = np.zeros(_N_PARAMS)
        p[_H_DT] = self.dt
        p[_H_NSUB] = float(self.substeps)
        for idx, name in (
            (_H_FRIC, "friction"),
            (_H_COG, "cogging"),
            (_H_CAB, "cable"),
            (_H_SAT, "saturation"),
            (_H_QUANT, "quantisation"),
            (_H_RES, "resonance"),
        ):
            p[idx] = float(getattr(self, name))
        p[_H_WLO], p[_H_WHI] = self.workspace_m
        p[_H_VMAX] = self.velocity_limit_m_s
        p[_H_AMAX] = self.acceleration_limit_m_s2
        p[_H_DIST] = float(self.any_disturbance())
        p[_H_TOL] = GUARD_TOLERANCE
        p[_H_RES] = self.encoder_resolution_m
        ad, bd = self.derivative_filter()
        for i, g in enumerate(self.gains()):
            b = _HEADER + i * _BLOCK
            p[b : b + _BLOCK] = [
                g.kp,
                g.ki * self.dt,
                g.kd * bd,
                ad,
                self.feedforward_mass_kg[i],
                self.feedforward_viscous_n_s_per_m[i],
                self.peak_force_n[i],
                *self.friction_laws[i].pack(),
            ]
        phi, gu, _gd = self.discrete_mechanics(self.dt)
        p[_PHI_DT:_GU_DT] = phi.ravel()
        p[_GU_DT:_PHI_H] = gu.ravel()
        phi, gu, gd = self.discrete_mechanics(self.dt / self.substeps)
        p[_PHI_H:_GU_H] = phi.ravel()
        p[_GU_H:_GD_H] = gu.ravel()
        p[_GD_H:_N_PARAMS] = gd.ravel()
        return p

    # --- copies ----------------------------------------------------------------------------

    def with_(self, **changes: Any) -> XYStageParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        return replace_known(self, "XY stage", **changes)

    def linear(self) -> XYStageParams:
        """A copy with every `NONLINEAR` part off (resonance and coupling as they are)."""
        return self.with_(**dict.fromkeys(NONLINEAR, False))


_SECTIONS = {  # TOML section -> the fields it holds (per-axis fields under [axes.x], [axes.y])
    "sampling": ("sample_rate_hz", "substeps"),
    "limits": ("workspace_m", "velocity_limit_m_s", "acceleration_limit_m_s2"),
    "output": ("noise_rms_m", "encoder_resolution_m"),
    "controller": ("slow_time_constant_s", "bandwidth_hz", "damping_ratio", "derivative_filter_hz"),
    "carriage": ("head_mass_kg", "resonance_hz", "resonance_damping"),
    "cable": (
        "cable_stiffness_n_per_m",
        "cable_rest_m",
        "cable_link_force_n",
        "cable_link_pitch_m",
        "cable_link_phase_rad",
    ),
    "coupling": ("reaction_coupling",),
    "switches": SWITCHES,
}


def load_params(path: str | os.PathLike[str] | None = None) -> XYStageParams:
    """Read the XY stage twin's parameters (default ``data/xy_stage_twin.toml``).

    Every value needs a ``<key>_source`` string; unknown sections and keys are refused.

    Raises
    ------
    ValueError
        Naming the file, the section and the key (layout), or the parameter (value).
    """
    values = read_sourced(path, "xy_stage_twin.toml", _SECTIONS, _FILE_PER_AXIS, AXES)
    return XYStageParams(**values)
