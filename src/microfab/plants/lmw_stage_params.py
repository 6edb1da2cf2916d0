"""Parameters of the seed 004 XY stage twin: dataclass, nominal values, data file, packing.

`LMWStageParams` holds the values of seed 004 eq. (2) per axis with Table I and the assumed
disturbance terms that `microfab.plants.lmw_stage` states (its module docstring has the
physics, the units and the integration); `load_params` reads them from
``data/lmw_stage.toml`` (every value with its ``<key>_source``); `LMWStageParams.pack`
lays them out flat for the numba kernels; `LMWStageParams.nominal` gives what a controller
may know (`StageNominal`: the nominal mass and force constant, the amplifier).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from microfab.core.validate import (
    check_axis_pair,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    replace_known,
)
from microfab.plants.friction import FRICTION_FIELDS, N_FRICTION, StageFriction
from microfab.plants.sourced_toml import read_sourced

__all__ = ["AXES", "SWITCHES", "LMWStageParams", "StageNominal", "load_params"]

AXES = ("x", "y")
SWITCHES = ("friction", "cogging", "cable", "saturation", "quantisation")

# flat params: a header, then one block per axis (see `LMWStageParams.pack`)
_H_DT, _H_NMIN, _H_NMAX, _H_RELAX, _H_SCALE = 0, 1, 2, 3, 4
_H_FRIC, _H_COG, _H_CAB, _H_SAT, _H_QUANT, _H_RES = 5, 6, 7, 8, 9, 10
_HEADER = 11
_M, _K, _TAU, _IPK = range(4)
_FRIC = 4  # the axis's `StageFriction` block (`microfab.plants.friction`)
_BLOCK = _FRIC + N_FRICTION

_PER_AXIS: dict[str, tuple[str, Any]] = {
    "nominal_mass_kg": ("kg", check_positive),
    "mass_kg": ("kg", check_positive),
    "nominal_force_constant_n_per_a": ("N/A", check_positive),
    "force_constant_n_per_a": ("N/A", check_positive),
    "amplifier_bandwidth_hz": ("Hz", check_positive),
    "peak_force_n": ("N", check_positive),
    "continuous_force_n": ("N", check_positive),
    "noise_rms_m": ("m", check_nonnegative),
}
# per-axis fields checked by the axis's `StageFriction` (`friction_laws`)
_LAW_FIELDS = (*FRICTION_FIELDS, "cable_stiffness_n_per_m", "cable_rest_m")
# the keys of each [axes.<name>] table of the data file
_FILE_PER_AXIS = (*tuple(_PER_AXIS)[:-1], *_LAW_FIELDS, "noise_rms_m")


@dataclass(frozen=True, kw_only=True)
class StageNominal:
    """What a controller of the stage may know: the nominal model of seed 004 eq. (2).

    Parameters
    ----------
    mass_kg : tuple of float
        Nominal moving mass ``M_n`` per axis (x, y), kg.
    force_constant_n_per_a : tuple of float
        Nominal motor force constant ``K_fn`` per axis, N/A.
    amplifier_bandwidth_hz : tuple of float
        Bandwidth of the current amplifier's first-order lag per axis, Hz.
    peak_force_n, continuous_force_n : tuple of float
        Table I force limits per axis, N.
    dt : float
        Sample time, s.
    """

    mass_kg: tuple[float, float]
    force_constant_n_per_a: tuple[float, float]
    amplifier_bandwidth_hz: tuple[float, float]
    peak_force_n: tuple[float, float]
    continuous_force_n: tuple[float, float]
    dt: float

    def current_per_acceleration(self) -> tuple[float, float]:
        """``M_n / K_fn`` per axis, A s²/m: the gain of eq. (4) from acceleration to current."""
        return tuple(m / k for m, k in zip(self.mass_kg, self.force_constant_n_per_a, strict=True))  # type: ignore[return-value]


@dataclass(frozen=True, kw_only=True)
class LMWStageParams:
    """Parameters of the two-axis stage twin (seed 004 eq. (2), Table I, assumed terms).

    Values and their sources: ``data/lmw_stage.toml`` (`load_params`). Per-axis values are
    pairs ``(x, y)``. Units SI: m, s, kg, A, N.

    Parameters
    ----------
    sample_rate_hz : float
        Sample rate, Hz.
    substeps_min, substeps_max : int
        Fewest and most RK4 sub-steps per sample (1 <= min <= max).
    relaxation_per_substep : float
        Largest ``h σ0 |v| / F_c`` (sub-step times the bristle relaxation rate) the sub-step
        count allows, in (0, 2]; the count rises with the speed up to ``substeps_max``.
    encoder_resolution_m : float
        Encoder count, m (Table I: 10 nm).
    disturbance_scale : float
        Multiplies friction + cogging + cable force (>= 0; 1 = the values below).
    friction, cogging, cable, saturation, quantisation : bool
        Switches of the nonlinear parts (all off: the LTI model of `linear_model`).
    nominal_mass_kg, mass_kg : tuple of float
        Nominal (controllers) and true (plant) moving mass per axis, kg.
    nominal_force_constant_n_per_a, force_constant_n_per_a : tuple of float
        Nominal and true motor force constant per axis, N/A.
    amplifier_bandwidth_hz : tuple of float
        First-order lag of the current amplifier per axis, Hz.
    peak_force_n, continuous_force_n : tuple of float
        Table I force limits per axis, N; the amplifier limits the current to
        ``peak_force_n / force_constant_n_per_a``.
    coulomb_n, static_n, stribeck_m_s : tuple of float
        LuGre ``F_c``, ``F_s`` (>= ``F_c``), ``v_s`` per axis: N, N, m/s. These
        and the friction, cogging and cable values below make each axis's `StageFriction`
        (`friction_laws`), which checks them: the law of `microfab.plants.friction`.
    bristle_stiffness_n_per_m, bristle_damping_n_s_per_m, viscous_n_s_per_m : tuple of float
        LuGre ``σ0``, ``σ1``, ``σ2`` per axis: N/m, N s/m, N s/m.
    cogging_n, cogging_pitch_m, cogging_phase_rad : tuple of float
        Cogging ripple ``A sin(2π x / p + φ)`` per axis: N, m, rad.
    cable_stiffness_n_per_m, cable_rest_m : tuple of float
        Cable carrier spring ``k (x - x_rest)`` per axis: N/m, m.
    noise_rms_m : tuple of float
        Encoder interpolation noise rms per axis, m (drawn by the experiment as the
        simulator's noise, not added by the plant).

    Raises
    ------
    ValueError
        On a value out of range, naming it, its value, unit and the fix.
    """

    sample_rate_hz: float
    substeps_min: int
    substeps_max: int
    relaxation_per_substep: float
    encoder_resolution_m: float
    disturbance_scale: float
    friction: bool
    cogging: bool
    cable: bool
    saturation: bool
    quantisation: bool
    nominal_mass_kg: tuple[float, float]
    mass_kg: tuple[float, float]
    nominal_force_constant_n_per_a: tuple[float, float]
    force_constant_n_per_a: tuple[float, float]
    amplifier_bandwidth_hz: tuple[float, float]
    peak_force_n: tuple[float, float]
    continuous_force_n: tuple[float, float]
    coulomb_n: tuple[float, float]
    static_n: tuple[float, float]
    stribeck_m_s: tuple[float, float]
    bristle_stiffness_n_per_m: tuple[float, float]
    bristle_damping_n_s_per_m: tuple[float, float]
    viscous_n_s_per_m: tuple[float, float]
    cogging_n: tuple[float, float]
    cogging_pitch_m: tuple[float, float]
    cogging_phase_rad: tuple[float, float]
    cable_stiffness_n_per_m: tuple[float, float]
    cable_rest_m: tuple[float, float]
    noise_rms_m: tuple[float, float]

    def __post_init__(self) -> None:
        fs = check_positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        nmin = check_int("substeps_min", self.substeps_min, 1)
        nmax = check_int("substeps_max", self.substeps_max, 1)
        if nmax < nmin:
            raise ValueError(
                f"substeps_max ({nmax}) must be >= substeps_min ({nmin}); raise substeps_max"
            )
        check_in_range(
            "relaxation_per_substep", self.relaxation_per_substep, 0.0, 2.0, low_closed=False
        )
        check_positive("encoder_resolution_m", self.encoder_resolution_m, "m")
        check_nonnegative("disturbance_scale", self.disturbance_scale)
        for name in SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"switch {name} must be true or false, got {getattr(self, name)!r}"
                )
        for name, (unit, check) in _PER_AXIS.items():
            object.__setattr__(self, name, check_axis_pair(name, getattr(self, name), unit, check))
        laws = self.friction_laws  # checks the friction, cogging and cable values
        for name in _LAW_FIELDS:
            object.__setattr__(self, name, tuple(getattr(law, name) for law in laws))
        for i, ax in enumerate(AXES):
            fpk, fcont = self.peak_force_n[i], self.continuous_force_n[i]
            if fcont > fpk:
                raise ValueError(
                    f"continuous_force_n[{ax}] = {fcont} N exceeds peak_force_n[{ax}] = "
                    f"{fpk} N; the continuous rating must not exceed the peak"
                )
            fa = self.amplifier_bandwidth_hz[i]
            if fa >= fs / 2:
                raise ValueError(
                    f"amplifier_bandwidth_hz[{ax}] = {fa} Hz must lie below the Nyquist "
                    f"frequency {fs / 2:g} Hz; lower it or raise sample_rate_hz"
                )

    @cached_property
    def friction_laws(self) -> tuple[StageFriction, StageFriction]:
        """The validated `StageFriction` of each axis ``(x, y)``: LuGre, cogging, cable.

        Built from the per-axis fields and the ``friction``, ``cogging`` and ``cable``
        switches (before ``disturbance_scale``, which the kernels apply to their sum).
        """
        return StageFriction.per_axis(
            {name: getattr(self, name) for name in _LAW_FIELDS},
            friction=self.friction,
            cogging=self.cogging,
            cable=self.cable,
        )

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return 1.0 / self.sample_rate_hz

    def amplifier_time_constant_s(self) -> tuple[float, float]:
        """``τ = 1 / (2π f_a)`` of the current amplifier per axis, s."""
        return tuple(1.0 / (2 * math.pi * f) for f in self.amplifier_bandwidth_hz)  # type: ignore[return-value]

    def peak_current_a(self) -> tuple[float, float]:
        """Current limit of the amplifier per axis, ``F_peak / K_f`` (true K_f), A."""
        pairs = zip(self.peak_force_n, self.force_constant_n_per_a, strict=True)
        return tuple(f / k for f, k in pairs)  # type: ignore[return-value]

    def nominal(self) -> StageNominal:
        """The nominal model a controller is given (M_n, K_fn, the amplifier, Table I)."""
        return StageNominal(
            mass_kg=self.nominal_mass_kg,
            force_constant_n_per_a=self.nominal_force_constant_n_per_a,
            amplifier_bandwidth_hz=self.amplifier_bandwidth_hz,
            peak_force_n=self.peak_force_n,
            continuous_force_n=self.continuous_force_n,
            dt=self.dt,
        )

    def pack(self) -> np.ndarray:
        """The flat ``float64`` params of the kernels (layout in the module source)."""
        out = [
            self.dt,
            float(self.substeps_min),
            float(self.substeps_max),
            self.relaxation_per_substep,
            self.disturbance_scale,
            *(float(getattr(self, s)) for s in SWITCHES),
            self.encoder_resolution_m,
        ]
        tau = self.amplifier_time_constant_s()
        ipk = self.peak_current_a()
        for i, law in enumerate(self.friction_laws):
            out += [self.mass_kg[i], self.force_constant_n_per_a[i], tau[i], ipk[i], *law.pack()]
        return np.array(out, dtype=np.float64)

    def with_(self, **changes: Any) -> LMWStageParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        return replace_known(self, "stage", **changes)

    def linear(self) -> LMWStageParams:
        """A copy with every nonlinear part off: the model of `LMWStage.linear_model`."""
        return self.with_(**dict.fromkeys(SWITCHES, False))


_SECTIONS = {  # TOML section -> the fields it holds (per-axis fields under [axes.x], [axes.y])
    "sampling": ("sample_rate_hz",),
    "integration": ("substeps_min", "substeps_max", "relaxation_per_substep"),
    "encoder": ("encoder_resolution_m",),
    "disturbance": ("disturbance_scale",),
    "switches": SWITCHES,
}


def load_params(path: str | os.PathLike[str] | None = None) -> LMWStageParams:
    """Read the stage twin's parameters (default ``data/lmw_stage.toml``).

    Every value needs a ``<key>_source`` string; unknown sections and keys are refused.

    Raises
    ------
    ValueError
        Naming the file, the section and the key (layout), or the parameter (value).
    """
    values = read_sourced(path, "lmw_stage.toml", _SECTIONS, _FILE_PER_AXIS, AXES)
    return LMWStageParams(**values)
