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
* **Detector** (a "dark-field" focus sensor; the seed's Fig. 6a minimises a photocurrent):
  the beam falls on a photodiode whose centre is masked by an opaque disc of radius
  ``a``; the diode collects the power outside it, ``P exp(-2 a² / w²)`` for a Gaussian spot,
  smallest at focus and rising to ``P`` far from it. A transimpedance amplifier (gain
  ``R_f``) turns the photocurrent (responsivity ``ℜ``) into volts:
  ``y = offset + R_f ℜ P exp(-2 a² / w(z)²)``. With ``a = w0/sqrt 2`` (assumed: the disc
  that maximises the curvature of ``y`` at focus) the rise from focus is
  ``y_fs e⁻¹ ((Δz/z_R)² + …)`` for small defocus: `LMWFocusParams.curvature_v`, V per
  ``(Δz/z_R)²``. The converter rounds ``y`` to its count (``adc_range_v``, ``adc_bits``;
  ``detector_quantisation`` switch). The noise is not added here (the simulator adds
  output noise, so it falls after the rounding: an approximation, the converter's staircase
  is kept); its rms (`LMWFocusParams.noise_rms_v`) follows from a noise budget at the focus
  level (`LMWFocusParams.noise_budget`): the source's relative intensity noise, the
  photocurrent's shot noise and the feedback resistor's Johnson noise over the noise
  bandwidth.
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
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

import control
from microfab.core.validate import (
    check_finite,
    check_int,
    check_nonnegative,
    check_positive,
    replace_known,
)
from microfab.plants.base import CompiledPlant, NoiseLevel, NoisyOutputs
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
_DT, _E, _TEM, _VMAX, _ZF0, _RATE, _ZR, _OFF, _FS, _RES, _QUANT, _A2, _COUNT, _DQUANT = range(14)
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
    power_w : float
        Power of the beam on the focus detector, W.
    responsivity_a_w : float
        Photodiode responsivity at the wavelength, A/W.
    stop_radius_ratio : float
        Radius of the opaque disc on the diode over ``w0`` (> 0).
    transimpedance_ohm : float
        Feedback resistance ``R_f`` of the transimpedance amplifier, Ω.
    offset_v : float
        Dark and stray-light offset of the detector output, V.
    rin_db_hz : float
        Relative intensity noise of the source, dB/Hz (< 0).
    noise_bandwidth_hz : float
        Equivalent noise bandwidth of the detector chain, Hz.
    temperature_k : float
        Temperature of the feedback resistor (Johnson noise), K.
    adc_range_v : float
        Converter input range ``±adc_range_v``, V.
    adc_bits : int
        Converter resolution, bits.
    detector_quantisation : bool
        Round the detector output to the converter's count.

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
    power_w: float
    responsivity_a_w: float
    stop_radius_ratio: float
    transimpedance_ohm: float
    offset_v: float
    rin_db_hz: float
    noise_bandwidth_hz: float
    temperature_k: float
    adc_range_v: float
    adc_bits: int
    detector_quantisation: bool

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
        check_positive("power_w", self.power_w, "W")
        check_positive("responsivity_a_w", self.responsivity_a_w, "A/W")
        check_positive("stop_radius_ratio (disc radius / w0)", self.stop_radius_ratio)
        check_positive("transimpedance_ohm", self.transimpedance_ohm, "Ω")
        check_finite("offset_v", self.offset_v, "V")
        if not check_finite("rin_db_hz", self.rin_db_hz, "dB/Hz") < 0.0:
            raise ValueError(
                f"rin_db_hz must be negative (a noise below the carrier), got "
                f"{self.rin_db_hz} dB/Hz"
            )
        check_positive("noise_bandwidth_hz", self.noise_bandwidth_hz, "Hz")
        check_positive("temperature_k", self.temperature_k, "K")
        check_positive("adc_range_v", self.adc_range_v, "V")
        check_int("adc_bits", self.adc_bits, 2)
        if not isinstance(self.detector_quantisation, bool):
            raise ValueError(
                "switch detector_quantisation must be true or false, got "
                f"{self.detector_quantisation!r}"
            )
        top = self.offset_v + self.full_scale_v
        if top > self.adc_range_v or self.offset_v < -self.adc_range_v:
            raise ValueError(
                f"the detector output spans {self.offset_v:g} to {top:g} V, outside the "
                f"converter's ±{self.adc_range_v:g} V: lower transimpedance_ohm or power_w, "
                "or widen adc_range_v"
            )

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

    @property
    def full_scale_v(self) -> float:
        """``R_f ℜ P``: the detector's rise from dark to the whole beam, V."""
        return self.transimpedance_ohm * self.responsivity_a_w * self.power_w

    @property
    def curvature_v(self) -> float:
        """Rise of ``y`` per ``(Δz / z_R)²`` at focus, V: ``y_fs 2α e^(-2α)``, ``α = (a/w0)²``."""
        a2 = 2.0 * self.stop_radius_ratio**2
        return self.full_scale_v * a2 * math.exp(-a2)

    @property
    def adc_count_v(self) -> float:
        """One count of the converter, V: ``2 adc_range_v / 2^bits``."""
        return 2.0 * self.adc_range_v / 2.0**self.adc_bits

    def detector_v(self, defocus_m: float | np.ndarray) -> float | np.ndarray:
        """Detector output ``offset + y_fs exp(-2 a² / w²)`` at a defocus (m), V (not rounded)."""
        r = np.asarray(defocus_m, dtype=float) / self.rayleigh_range_m
        a2 = 2.0 * self.stop_radius_ratio**2
        out = self.offset_v + self.full_scale_v * np.exp(-a2 / (1.0 + r * r))
        return float(out) if out.ndim == 0 else out

    def noise_budget(self) -> dict[str, float]:
        """Detector noise rms at the focus level by source, V (``total`` their root sum square).

        ``rin``: ``y sqrt(10^(RIN/10) B)``; ``shot``: ``R_f sqrt(2 q I B)``; ``johnson``:
        ``sqrt(4 k T R_f B)``, with ``y = y_fs e^(-2α)`` the signal and ``I = y / R_f`` the
        photocurrent at focus, ``B`` the noise bandwidth. The converter's rounding is not
        in it (`detector_quantisation` keeps its staircase).
        """
        q, k_b = 1.602176634e-19, 1.380649e-23  # C, J/K (SI exact)
        b = self.noise_bandwidth_hz
        y = float(self.detector_v(0.0)) - self.offset_v
        rin = y * math.sqrt(10.0 ** (self.rin_db_hz / 10.0) * b)
        shot = self.transimpedance_ohm * math.sqrt(2.0 * q * (y / self.transimpedance_ohm) * b)
        johnson = math.sqrt(4.0 * k_b * self.temperature_k * self.transimpedance_ohm * b)
        total = math.sqrt(rin * rin + shot * shot + johnson * johnson)
        return {"rin": rin, "shot": shot, "johnson": johnson, "total": total}

    @property
    def noise_rms_v(self) -> float:
        """Detector noise rms, V (`noise_budget` total; drawn by the experiment)."""
        return self.noise_budget()["total"]

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
                self.full_scale_v,
                self.encoder_resolution_m,
                float(self.quantisation),
                2.0 * self.stop_radius_ratio**2,
                self.adc_count_v,
                float(self.detector_quantisation),
            ],
            dtype=np.float64,
        )

    def with_(self, **changes: Any) -> LMWFocusParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        return replace_known(self, "focus", **changes)


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
    "detector": (
        "power_w",
        "responsivity_a_w",
        "stop_radius_ratio",
        "transimpedance_ohm",
        "offset_v",
        "rin_db_hz",
        "noise_bandwidth_hz",
        "temperature_k",
        "adc_range_v",
        "adc_bits",
        "detector_quantisation",
    ),
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
    yd = p[_OFF] + p[_FS] * math.exp(-p[_A2] / (1.0 + r * r))
    c = p[_COUNT]
    y[0] = math.floor(yd / c + 0.5) * c if p[_DQUANT] != 0.0 else yd
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


class LMWFocus(CompiledPlant, NoisyOutputs):
    """The focus axis twin as a compiled plant (command z velocity m/s; outputs V, m).

    Parameters
    ----------
    config : LMWFocusParams
        The twin's parameters.

    Attributes
    ----------
    noise_level : NoiseLevel
        Output noise ``(detector V, encoder m)``: `LMWFocusParams.noise_rms_v` and
        ``encoder_noise_rms_m``; drawn by the experiment.

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
        self.noise_level = NoiseLevel((config.noise_rms_v, config.encoder_noise_rms_m), ("V", "m"))

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
        y = c.offset_v + c.full_scale_v * math.exp(-2.0 * c.stop_radius_ratio**2 / w_ratio**2)
        if c.detector_quantisation:
            y = math.floor(y / c.adc_count_v + 0.5) * c.adc_count_v
        z = float(state[0])
        q = c.encoder_resolution_m
        zq = math.floor(z / q + 0.5) * q if c.quantisation else z
        return np.array([y, zq])

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """State one sample later (a new array): velocity command (m/s) held."""
        c = self.config
        tau, dt = c.velocity_lag_s, self.dt
        u = min(max(float(command[0]), -c.speed_limit_m_s), c.speed_limit_m_s)
        z, v = float(state[0]), float(state[1])
        decay = math.exp(-dt / tau)
        z_new = z + u * dt + (v - u) * tau * (1.0 - decay)
        return np.array([z_new, u + (v - u) * decay, float(state[2]) + 1.0])

    def depth_of_focus_m(self, growth: float = DOF_GROWTH) -> float:
        """Depth of focus of the twin's beam, m (`LMWFocusParams.depth_of_focus_m`)."""
        return self.config.depth_of_focus_m(growth)

    def linear_model(self) -> DiscreteLTI:
        """ZOH of the z stage below its speed limit: states ``(z, v)``, input ``u``, output z."""
        tau = self.config.velocity_lag_s
        sys = control.ss([[0.0, 1.0], [0.0, -1.0 / tau]], [[0.0], [1.0 / tau]], [[1.0, 0.0]], 0.0)
        return discretize(sys, self.dt, "zoh")


def lmw_focus_twin(
    path: str | os.PathLike[str] | None = None,
    *,
    params: LMWFocusParams | None = None,
    **overrides: Any,
) -> LMWFocus:
    """The focus twin from the data file (default ``data/lmw_focus.toml``), with overrides."""
    cfg = load_params(path) if params is None else params
    return LMWFocus(cfg.with_(**overrides) if overrides else cfg)
