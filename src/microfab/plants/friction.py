"""The force opposing a stage carriage: LuGre friction, cogging ripple, cable carrier.

One law for the stage twins of seed 002 (`microfab.plants.xy_stage`) and seed 004
(`microfab.plants.lmw_stage`), per axis, in SI units (m, s, N):

* LuGre friction (``friction`` switch): ``ż = v - σ0 |v| z / g(v)``,
  ``g(v) = F_c + (F_s - F_c) exp(-(v / v_s)²)`` (the Stribeck level),
  ``F_f = σ0 z + σ1 ż + σ2 v``; the bristle deflection ``z`` (m) gives pre-sliding and the
  quadrant glitch at a velocity reversal;
* cogging ripple of the motor (``cogging``): ``F_cog = A sin(2π x / p + φ)``;
* cable carrier (``cable``): the spring ``k (x - x_rest)`` plus the ripple of its links
  ``A_l sin(2π x / p_l + φ_l)`` (none when ``A_l = 0``).

`StageFriction` is the validated parameter block of one axis, `StageFriction.pack` its flat
layout inside a twin's kernel parameters, `friction_force` the numba kernel both twins call
(``(F, ż, g)`` at ``x``, ``v``, ``z``) and `bristle_step` the exact bristle advance over a
displacement at a held Stribeck level (the seed 002 twin's sub-steps). The Python
references of the twins call the same kernels (`StageFriction.force`,
`StageFriction.bristle`), so the law is written once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numba import njit

from microfab.core.validate import (
    check_axis_pair,
    check_finite,
    check_nonnegative,
    check_positive,
)

__all__ = [
    "FRICTION_FIELDS",
    "N_FRICTION",
    "StageFriction",
    "bristle_step",
    "friction_force",
]

#: The per-axis fields of the LuGre and cogging parts (the keys of the twins' data files).
FRICTION_FIELDS = (
    "coulomb_n",
    "static_n",
    "stribeck_m_s",
    "bristle_stiffness_n_per_m",
    "bristle_damping_n_s_per_m",
    "viscous_n_s_per_m",
    "cogging_n",
    "cogging_pitch_m",
    "cogging_phase_rad",
)

# flat layout of one axis's block (`StageFriction.pack`), offsets from its start
_ON_FRIC, _ON_COG, _ON_CAB = 0, 1, 2
_FC, _FS, _VS, _S0, _S1, _S2 = 3, 4, 5, 6, 7, 8
_ACOG, _KCOG, _PCOG = 9, 10, 11
_KCAB, _XREST, _ALINK, _KLINK, _PLINK = 12, 13, 14, 15, 16
#: Length of one axis's block in a twin's kernel parameters.
N_FRICTION = 17

_CHECKS: dict[str, tuple[str, Any]] = {
    "coulomb_n": ("N", check_nonnegative),
    "static_n": ("N", check_nonnegative),
    "stribeck_m_s": ("m/s", check_positive),
    "bristle_stiffness_n_per_m": ("N/m", check_positive),
    "bristle_damping_n_s_per_m": ("N s/m", check_nonnegative),
    "viscous_n_s_per_m": ("N s/m", check_nonnegative),
    "cogging_n": ("N", check_nonnegative),
    "cogging_pitch_m": ("m", check_positive),
    "cogging_phase_rad": ("rad", check_finite),
    "cable_stiffness_n_per_m": ("N/m", check_nonnegative),
    "cable_rest_m": ("m", check_finite),
    "cable_link_force_n": ("N", check_nonnegative),
    "cable_link_pitch_m": ("m", check_positive),
    "cable_link_phase_rad": ("rad", check_finite),
}


@dataclass(frozen=True, kw_only=True)
class StageFriction:
    """The force law opposing one stage axis: LuGre friction, cogging, cable carrier.

    The twins build one per axis from their data files (`LMWStageParams.friction_laws`,
    `XYStageParams.friction_laws`); the values are the twins' own, each with its source in
    the data file.

    Parameters
    ----------
    axis : str
        Axis name, for the messages (``coulomb_n[x]``); empty: no suffix.
    friction, cogging, cable : bool
        Switches of the three parts (off: the part adds no force).
    coulomb_n, static_n : float
        LuGre Coulomb force ``F_c`` and break-away force ``F_s`` (>= ``F_c``), N;
        ``F_c > 0`` when ``friction`` is on (the bristle law divides by ``g(v) >= F_c``).
    stribeck_m_s : float
        Stribeck velocity ``v_s``, m/s (> 0).
    bristle_stiffness_n_per_m, bristle_damping_n_s_per_m, viscous_n_s_per_m : float
        LuGre ``σ0`` (N/m, > 0), ``σ1`` (N s/m, >= 0), ``σ2`` (N s/m, >= 0).
    cogging_n, cogging_pitch_m, cogging_phase_rad : float
        Cogging ripple ``A sin(2π x / p + φ)``: amplitude N (>= 0), pitch m (> 0), phase rad.
    cable_stiffness_n_per_m, cable_rest_m : float
        Cable carrier spring ``k (x - x_rest)``: N/m (>= 0), m. Default none.
    cable_link_force_n, cable_link_pitch_m, cable_link_phase_rad : float
        Ripple of the carrier's links ``A_l sin(2π x / p_l + φ_l)``: N (>= 0; 0 adds
        nothing, not even a sine), m (> 0), rad. Default none.

    Raises
    ------
    ValueError
        On a value out of range, naming it (with ``[axis]``), its value, unit and the fix.
    """

    axis: str = ""
    friction: bool = True
    cogging: bool = True
    cable: bool = True
    coulomb_n: float
    static_n: float
    stribeck_m_s: float
    bristle_stiffness_n_per_m: float
    bristle_damping_n_s_per_m: float
    viscous_n_s_per_m: float
    cogging_n: float
    cogging_pitch_m: float
    cogging_phase_rad: float
    cable_stiffness_n_per_m: float = 0.0
    cable_rest_m: float = 0.0
    cable_link_force_n: float = 0.0
    cable_link_pitch_m: float = 1.0
    cable_link_phase_rad: float = 0.0

    def __post_init__(self) -> None:
        sfx = f"[{self.axis}]" if self.axis else ""
        for name in ("friction", "cogging", "cable"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(
                    f"switch {name} must be true or false, got {getattr(self, name)!r}"
                )
        for name, (unit, check) in _CHECKS.items():
            object.__setattr__(self, name, check(f"{name}{sfx}", getattr(self, name), unit))
        fc, fs = self.coulomb_n, self.static_n
        if fs < fc:
            raise ValueError(
                f"static_n{sfx} = {fs} N is below coulomb_n{sfx} = {fc} N; the break-away "
                "force F_s must be >= the Coulomb force F_c"
            )
        if fc == 0.0 and self.friction:
            raise ValueError(
                f"coulomb_n{sfx} = 0 N with friction on: the LuGre bristle law divides by "
                "g(v) >= F_c; give F_c > 0 or turn friction off"
            )

    @classmethod
    def per_axis(
        cls,
        pairs: Mapping[str, Any],
        *,
        each: Sequence[Mapping[str, Any]] = ({}, {}),
        **common: Any,
    ) -> tuple[StageFriction, StageFriction]:
        """One law per axis ``(x, y)`` from per-axis pairs, as the twins' data files hold them.

        Parameters
        ----------
        pairs : mapping of str to pair
            Field name -> ``(x, y)`` values (e.g. ``coulomb_n``), each a pair.
        each : sequence of two mappings
            Fields of the x law and of the y law alone (e.g. a cable on y only).
        **common
            Fields of both laws (the switches).

        Raises
        ------
        ValueError
            On a value that is not a pair, or one the law refuses (``name[x]`` / ``name[y]``).
        """
        for name, value in pairs.items():
            check_axis_pair(name, value, _CHECKS[name][0], _as_given)
        return tuple(  # type: ignore[return-value]
            cls(axis=ax, **{k: v[i] for k, v in pairs.items()}, **common, **each[i])
            for i, ax in enumerate(("x", "y"))
        )

    def pack(self) -> list[float]:
        """The block's `N_FRICTION` flat values for a twin's kernel parameters.

        Switches as 0.0 / 1.0; the pitches as wave numbers ``2π / p`` (rad/m).
        """
        return [
            float(self.friction),
            float(self.cogging),
            float(self.cable),
            self.coulomb_n,
            self.static_n,
            self.stribeck_m_s,
            self.bristle_stiffness_n_per_m,
            self.bristle_damping_n_s_per_m,
            self.viscous_n_s_per_m,
            self.cogging_n,
            2 * math.pi / self.cogging_pitch_m,
            self.cogging_phase_rad,
            self.cable_stiffness_n_per_m,
            self.cable_rest_m,
            self.cable_link_force_n,
            2 * math.pi / self.cable_link_pitch_m,
            self.cable_link_phase_rad,
        ]

    @cached_property
    def _packed(self) -> np.ndarray:
        return np.array(self.pack(), dtype=np.float64)

    def force(self, x: float, v: float, z: float) -> tuple[float, float, float]:
        """``(F, ż, g)`` at position ``x`` (m), speed ``v`` (m/s), bristle deflection ``z`` (m).

        `friction_force` on this block: the force opposing the carriage (N), the bristle
        rate (m/s; 0 with friction off) and the Stribeck level ``g(v)`` (N; 1 with
        friction off).
        """
        f, zd, g = friction_force(self._packed, 0, float(x), float(v), float(z))
        return float(f), float(zd), float(g)

    def bristle(self, z: float, dx: float, g: float) -> float:
        """`bristle_step` on this block: ``z`` (m) after moving ``dx`` (m) at level ``g`` (N)."""
        return float(bristle_step(self._packed, 0, float(z), float(dx), float(g)))


def _as_given(_name: str, value: Any, _unit: str) -> Any:
    """One value of a pair as given (the law checks it)."""
    return value


@njit(cache=True, inline="always")
def friction_force(
    p: np.ndarray, b: int, x: float, v: float, z: float
) -> tuple[float, float, float]:
    """``(F, ż, g)`` of the block at ``p[b:b + N_FRICTION]`` (`StageFriction.pack`).

    Parameters
    ----------
    p : numpy.ndarray
        Flat kernel parameters holding the block.
    b : int
        Offset of the block in ``p``.
    x, v, z : float
        Position (m), speed (m/s) and bristle deflection (m) of the axis.

    Returns
    -------
    tuple of float
        The force opposing the carriage (N), the bristle rate ``ż`` (m/s; 0 with friction
        off) and the Stribeck level ``g(v)`` (N; 1 with friction off).
    """
    f = 0.0
    zd = 0.0
    g = 1.0
    if p[b + _ON_FRIC] != 0.0:
        dv = v / p[b + _VS]
        g = p[b + _FC] + (p[b + _FS] - p[b + _FC]) * math.exp(-dv * dv)
        zd = v - p[b + _S0] * abs(v) * z / g
        f = p[b + _S0] * z + p[b + _S1] * zd + p[b + _S2] * v
    if p[b + _ON_COG] != 0.0:
        f += p[b + _ACOG] * math.sin(p[b + _KCOG] * x + p[b + _PCOG])
    if p[b + _ON_CAB] != 0.0:
        f += p[b + _KCAB] * (x - p[b + _XREST])
        if p[b + _ALINK] != 0.0:
            f += p[b + _ALINK] * math.sin(p[b + _KLINK] * x + p[b + _PLINK])
    return f, zd, g


@njit(cache=True, inline="always")
def bristle_step(p: np.ndarray, b: int, z: float, dx: float, g: float) -> float:
    """The LuGre bristle deflection (m) after the axis moved by ``dx`` (m) at level ``g`` (N).

    Exact for a speed of constant sign at a held Stribeck level ``g``:
    ``z_ss + (z - z_ss) exp(-σ0 |dx| / g)`` with ``z_ss = sign(dx) g / σ0``; ``z`` itself
    when ``dx = 0``. ``p[b:b + N_FRICTION]`` is the axis's block.
    """
    if dx == 0.0:
        return z
    s0 = p[b + _S0]
    zss = math.copysign(g / s0, dx)
    return zss + (z - zss) * math.exp(-s0 * abs(dx) / g)
