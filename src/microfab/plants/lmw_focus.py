"""Digital twin of the seed 004 focus axis: z stage, Gaussian beam, spot-size detector.

Seed 004 §III.B and §IV.C describe the autofocus only as "a sliding mode optimisation"
that moves a translation stage until a photodiode output is minimal (Fig. 6); its set-up is
in ref. [23], which the seed does not describe. Ours (every number assumed unless cited):

* **z stage**, commanded in velocity ``u`` (m/s): a velocity loop as a first-order lag
  ``τ v̇ = clip(u, ±v_max) - v`` (``τ`` 5 ms, ``v_max`` 2 mm/s), position ``ż = v``, and an
  encoder rounding ``z`` to the nearest 0.1 µm count (``quantisation`` switch). The
  command is held over the sample (ZOH); the update is the exact discretisation of the lag.
* **Gaussian beam** of the SPI fibre laser: ``λ = 1065 nm`` and waist diameter 10.8 µm
  (seed 004 §II.A), ``M² = 1`` (assumed), so the Rayleigh range is
  ``z_R = π w0² / (M² λ)`` = 86.0 µm and the spot radius
  ``w(z) = w0 sqrt(1 + ((z - z_f) / z_R)²)``. The depth of focus over which ``w`` grows by
  at most 5 %, ``2 z_R sqrt(1.05² - 1)`` = 55.1 µm, is the seed's "approximately 54 µm"
  (§II.A; `depth_of_focus`).
* **Detector**: a photodiode behind the optics reading the spot size (e.g. an annular
  diode around a pinhole in the reflected beam collects the light the pinhole misses, which
  to first order grows with the spot area), through a transimpedance amplifier:
  ``y = offset + gain (w(z) / w0)²`` in V, minimal at focus (the seed's Fig. 6a minimises
  a photocurrent). Its noise (``noise_rms_v``) is not added here: the experiment draws it as
  the simulator's noise array (`LMWFocus.noise_rms`).
* **Moving focus plane** (optional, a tilted part moving under the beam): the focus
  position drifts linearly, ``z_f(t) = z_f0 + r t`` with ``r = surface_rate_m_s`` (e.g. a
  1 mrad tilt at 10 mm/s is 10 µm/s); time ``t = k dt`` is the sample counter in the
  state.

`LMWFocus`: one input (z velocity command, m/s), two outputs (detector ``y`` in V, encoder
``z`` in m); state ``[z, v, k]`` (m, m/s, samples). Parameters in ``data/lmw_focus.toml``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numba import njit

import control
from microfab.core.validate import check_finite, check_nonnegative, check_positive
from microfab.plants.base import CompiledPlant
from microfab.plants.lti import DiscreteLTI, discretize
from microfab.plants.sourced_toml import read_sourced

__all__ = [
    "DOF_GROWTH",
    "LMWFocus",
    "LMWFocusParams",
    "depth_of_focus",
    "kernel_output",
    "kernel_update",
    "lmw_focus_twin",
    "load_params",
]

DOF_GROWTH = 0.05  # assumed: spot radius grows 5 % at the edge of the depth of focus

# flat params (see `LMWFocusParams.pack`)
_DT, _E, _TEM, _VMAX, _ZF0, _RATE, _ZR, _OFF, _GAIN, _RES, _QUANT = range(11)
_N_STATE = 3  # z, v, k


@dataclass(frozen=True, kw_only=True)
class LMWFocusParams:
    """Parameters of the focus axis twin (units SI; detector in V).

    Values and their sources: ``data/lmw_focus.toml`` (`load_params`).

    Parameters
    ----------
    sample_rate_hz : float
        Sample rate, Hz.
    velocity_lag_s : float
        Time constant ``τ`` of the z stage's velocity loop, s.
    speed_limit_m_s : float
        Largest commanded speed ``v_max``, m/s (commands are clipped to it).
    encoder_resolution_m : float
        z encoder count, m.
    quantisation : bool
        Round the z output to the nearest count.
    encoder_noise_rms_m : float
        z encoder noise rms, m (drawn by the experiment, not added by the plant).
    start_position_m : float
        z at rest in `LMWFocus.init`, m.
    wavelength_m : float
        Laser wavelength, m (seed 004 §II.A: 1065 nm).
    waist_diameter_m : float
        Beam waist diameter ``2 w0``, m (seed 004 §II.A: 10.8 µm).
    m_squared : float
        Beam quality ``M²`` (>= 1).
    focus_position_m : float
        z of the focus at ``t = 0``, ``z_f0``, m.
    surface_rate_m_s : float
        Drift of the focus position, m/s (0: a fixed focal plane).
    offset_v, gain_v : float
        Detector ``y = offset + gain (w / w0)²``, V (gain > 0: one minimum at focus).
    noise_rms_v : float
        Detector noise rms, V (drawn by the experiment, not added by the plant).

    Raises
    ------
    ValueError
        On a value out of range, naming it, its value and unit.
    """

    sample_rate_hz: float
    velocity_lag_s: float
    speed_limit_m_s: float
    encoder_resolution_m: float
    quantisation: bool
    encoder_noise_rms_m: float
    start_position_m: float
    wavelength_m: float
    waist_diameter_m: float
    m_squared: float
    focus_position_m: float
    surface_rate_m_s: float
    offset_v: float
    gain_v: float
    noise_rms_v: float

    def __post_init__(self) -> None:
        check_positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        check_positive("velocity_lag_s", self.velocity_lag_s, "s")
        check_positive("speed_limit_m_s", self.speed_limit_m_s, "m/s")
        check_positive("encoder_resolution_m", self.encoder_resolution_m, "m")
        if not isinstance(self.quantisation, bool):
            raise ValueError(
                f"switch quantisation must be true or false, got {self.quantisation!r}"
            )
        check_nonnegative("encoder_noise_rms_m", self.encoder_noise_rms_m, "m")
        check_finite("start_position_m", self.start_position_m, "m")
        check_positive("wavelength_m", self.wavelength_m, "m")
        check_positive("waist_diameter_m", self.waist_diameter_m, "m")
        if not check_finite("m_squared", self.m_squared) >= 1.0:
            raise ValueError(
                f"m_squared must be >= 1 (a real beam is no better than a Gaussian), "
                f"got {self.m_squared}"
            )
        check_finite("focus_position_m", self.focus_position_m, "m")
        check_finite("surface_rate_m_s", self.surface_rate_m_s, "m/s")
        check_finite("offset_v", self.offset_v, "V")
        check_positive("gain_v (detector gain; > 0 for a minimum at focus)", self.gain_v, "V")
        check_nonnegative("noise_rms_v", self.noise_rms_v, "V")

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return 1.0 / self.sample_rate_hz

    @property
    def waist_radius_m(self) -> float:
        """``w0``, m."""
        return 0.5 * self.waist_diameter_m

    @property
    def rayleigh_range_m(self) -> float:
        """``z_R = π w0² / (M² λ)``, m."""
        return math.pi * self.waist_radius_m**2 / (self.m_squared * self.wavelength_m)

    def spot_radius_m(self, defocus_m: float | np.ndarray) -> float | np.ndarray:
        """``w = w0 sqrt(1 + (Δz / z_R)²)`` at a defocus ``Δz = z - z_f`` (m), m."""
        r = np.asarray(defocus_m, dtype=float) / self.rayleigh_range_m
        out = self.waist_radius_m * np.sqrt(1.0 + r * r)
        return float(out) if out.ndim == 0 else out

    def depth_of_focus_m(self, growth: float = DOF_GROWTH) -> float:
        """``2 z_R sqrt((1 + growth)² - 1)``: the z range where ``w <= (1 + growth) w0``, m."""
        g = check_positive("growth", growth)
        return 2.0 * self.rayleigh_range_m * math.sqrt((1.0 + g) ** 2 - 1.0)

    def detector_v(self, defocus_m: float | np.ndarray) -> float | np.ndarray:
        """Detector output ``offset + gain (w / w0)²`` at a defocus (m), V."""
        r = np.asarray(defocus_m, dtype=float) / self.rayleigh_range_m
        out = self.offset_v + self.gain_v * (1.0 + r * r)
        return float(out) if out.ndim == 0 else out

    def pack(self) -> np.ndarray:
        """The flat ``float64`` params of the kernels (layout in the module source)."""
        x = self.dt / self.velocity_lag_s
        return np.array(
            [
                self.dt,
                math.exp(-x),
                -self.velocity_lag_s * math.expm1(-x),
                self.speed_limit_m_s,
                self.focus_position_m,
                self.surface_rate_m_s,
                self.rayleigh_range_m,
                self.offset_v,
                self.gain_v,
                self.encoder_resolution_m,
                float(self.quantisation),
            ],
            dtype=np.float64,
        )

    def with_(self, **changes: Any) -> LMWFocusParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise ValueError(
                f"unknown focus parameter(s) {', '.join(unknown)}; known: "
                f"{', '.join(sorted(known))}"
            )
        return replace(self, **changes)


_SECTIONS = {
    "sampling": ("sample_rate_hz",),
    "stage": (
        "velocity_lag_s",
        "speed_limit_m_s",
        "encoder_resolution_m",
        "quantisation",
        "encoder_noise_rms_m",
        "start_position_m",
    ),
    "beam": (
        "wavelength_m",
        "waist_diameter_m",
        "m_squared",
        "focus_position_m",
        "surface_rate_m_s",
    ),
    "detector": ("offset_v", "gain_v", "noise_rms_v"),
}


def load_params(path: str | os.PathLike[str] | None = None) -> LMWFocusParams:
    """Read the focus twin's parameters (default ``data/lmw_focus.toml``).

    Every value needs a ``<key>_source`` string; unknown sections and keys are refused.

    Raises
    ------
    ValueError
        Naming the file, the section and the key (layout), or the parameter (value).
    """
    return LMWFocusParams(**read_sourced(path, "lmw_focus.toml", _SECTIONS))


def depth_of_focus(growth: float = DOF_GROWTH, params: LMWFocusParams | None = None) -> float:
    """Depth of focus ``2 z_R sqrt((1 + growth)² - 1)``, m (default twin: 55.1 µm).

    Parameters
    ----------
    growth : float
        Relative growth of the spot radius allowed at the edges (assumed 5 %).
    params : LMWFocusParams, optional
        The beam (default: the data file's, seed 004 §II.A).
    """
    return (load_params() if params is None else params).depth_of_focus_m(growth)


@njit(cache=True)
def kernel_output(p: np.ndarray, s: np.ndarray, y: np.ndarray) -> None:
    """Write ``(detector V, encoder z m)`` into ``y``, shape (2,)."""
    z = s[0]
    r = (z - (p[_ZF0] + p[_RATE] * (s[2] * p[_DT]))) / p[_ZR]
    y[0] = p[_OFF] + p[_GAIN] * (1.0 + r * r)
    q = p[_RES]
    y[1] = math.floor(z / q + 0.5) * q if p[_QUANT] != 0.0 else z


@njit(cache=True)
def kernel_update(p: np.ndarray, s: np.ndarray, u: np.ndarray) -> None:
    """Advance ``s`` one sample in place under the velocity command ``u[0]`` (m/s), held."""
    vmax = p[_VMAX]
    uc = min(max(u[0], -vmax), vmax)
    dv = s[1] - uc
    s[0] += uc * p[_DT] + dv * p[_TEM]
    s[1] = uc + dv * p[_E]
    s[2] += 1.0


class LMWFocus(CompiledPlant):
    """The focus axis twin as a compiled plant (command z velocity m/s; outputs V, m).

    Parameters
    ----------
    config : LMWFocusParams
        The twin's parameters.

    Notes
    -----
    State ``[z, v, k]``: stage position (m), velocity (m/s), sample counter. ``output`` and
    ``update`` are plain Python written from ``config``, for the Python loop and as an
    independent check of the kernels; both agree to rounding.
    """

    kernel_output: Any = kernel_output
    kernel_update: Any = kernel_update
    n_inputs = 1
    n_outputs = 2

    def __init__(self, config: LMWFocusParams) -> None:
        self.config = config
        self.params = config.pack()
        self.params.setflags(write=False)
        self.dt = config.dt

    def init(self) -> np.ndarray:
        """At rest at ``start_position_m``, sample 0."""
        return np.array([self.config.start_position_m, 0.0, 0.0])

    def time_s(self, state: np.ndarray) -> float:
        """Time of ``state``, s."""
        return float(state[2]) * self.dt

    def focus_position_m(self, state: np.ndarray) -> float:
        """``z_f`` at the time of ``state``, m."""
        c = self.config
        return c.focus_position_m + c.surface_rate_m_s * (float(state[2]) * self.dt)

    def defocus_m(self, state: np.ndarray) -> float:
        """``z - z_f`` of ``state``, m."""
        return float(state[0]) - self.focus_position_m(state)

    def spot_radius_m(self, state: np.ndarray) -> float:
        """Spot radius ``w`` at ``state``, m."""
        return float(self.config.spot_radius_m(self.defocus_m(state)))

    def output(self, state: np.ndarray) -> np.ndarray:
        """``(detector y in V, encoder z in m)``, shape (2,)."""
        c = self.config
        w_ratio = self.spot_radius_m(state) / c.waist_radius_m
        z = float(state[0])
        q = c.encoder_resolution_m
        zq = math.floor(z / q + 0.5) * q if c.quantisation else z
        return np.array([c.offset_v + c.gain_v * w_ratio * w_ratio, zq])

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """State one sample later (a new array): velocity command (m/s) held."""
        c = self.config
        tau, dt = c.velocity_lag_s, self.dt
        u = min(max(float(command[0]), -c.speed_limit_m_s), c.speed_limit_m_s)
        z, v = float(state[0]), float(state[1])
        decay = math.exp(-dt / tau)
        z_new = z + u * dt + (v - u) * tau * (1.0 - decay)
        return np.array([z_new, u + (v - u) * decay, float(state[2]) + 1.0])

    def noise_rms(self) -> np.ndarray:
        """Noise rms of the outputs ``(detector V, encoder m)``, shape (2,): for the simulators."""
        return np.array([self.config.noise_rms_v, self.config.encoder_noise_rms_m])

    def depth_of_focus_m(self, growth: float = DOF_GROWTH) -> float:
        """Depth of focus of the twin's beam, m (`LMWFocusParams.depth_of_focus_m`)."""
        return self.config.depth_of_focus_m(growth)

    def linear_model(self) -> DiscreteLTI:
        """ZOH of the z stage below its speed limit: states ``(z, v)``, input ``u``, output z."""
        tau = self.config.velocity_lag_s
        sys = control.ss([[0.0, 1.0], [0.0, -1.0 / tau]], [[0.0], [1.0 / tau]], [[1.0, 0.0]], 0.0)
        return discretize(sys, self.dt, "zoh")


def lmw_focus_twin(path: str | os.PathLike[str] | None = None, **overrides: Any) -> LMWFocus:
    """The focus twin from the data file (default ``data/lmw_focus.toml``), with overrides."""
    cfg = load_params(path)
    return LMWFocus(cfg.with_(**overrides) if overrides else cfg)
