"""Digital twin of the SLM galvo scanner of seed 003 part 2 (Buls et al., HurryScan25).

The seed identifies one axis of the scanner from its set position to its measured position
(both in bit of the 16-bit field, the scanner's own position loop inside) by a chirp and a
nonlinear least-squares fit (§1):

``G(s) = 1.242e11 / (s³ + 9517 s² + 5.773e7 s + 1.272e11)``  (seed 003 part 2 §1)

with static gain ``G(0) = 1.242e11 / 1.272e11 = 0.9764`` (not one: the seed's shaper
inverts the dynamics only, §2). The twin (`GalvoSLMPlant`) has two identical axes ``x`` and
``y`` (the seed measured one; assumed), input = set position every ``T = 10 µs`` (the RTC
tick, the seed's "fs = 1e-5" read as the period) held over the tick, output = measured
position, both in bit; the truth is ``G`` discretised by ZOH at ``T``. It is an
`microfab.plants.base.LTIPlant`, so the lifted simulator (`microfab.sim.lti_fast`) and the
compiled per-sample loop both run it. Measured output noise (0.3 bit rms, assumed) is not
added by the plant: the simulators add it (`GalvoSLMPlant.noise`, seeded).

**Realisation.** ``G`` is factored into its real pole ``a`` (3459 rad/s, 550.5 Hz) and its
complex pair (``ωn`` 6064 rad/s = 965.2 Hz, ``ζ`` 0.4995) and realised as the cascade
``G(0) · a / (s + a) · ωn² / (s² + 2 ζ ωn s + ωn²)`` with states in bit (the first-order
output, the position and the velocity scaled by ``1 / ωn``): the transfer function is the
seed's, and the state entries stay of order one (the companion form of the polynomial
spans 1e-1 to 1e11).

**Option** (``mirror_mode=True``): a lightly damped mirror mode ``ωm² / (s² + 2 ζm ωm s +
ωm²)`` (3 kHz, ``ζm`` 0.02, unit static gain; assumed) in series after ``G``, for
robustness and classic-shaper studies.

**Field and limits.** Set positions lie in ±32768 bit (16 bit, assumed), 1 bit = 1.5 µm at
the work plane (assumed): ±49.15 mm. `GalvoSLMPlant.axis_limits` declares them as
`microfab.core.limits.AxisLimits` in bit for `microfab.core.limits.check_command`;
`microfab.core.limits.MachineLimits.seed003_slm` is the same in m for trajectories.

Parameters and their sources: ``data/galvo_slm.toml`` (`load_params`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

import control
from microfab.core.limits import AxisLimits
from microfab.core.validate import check_in_range, check_nonnegative, check_positive, replace_known
from microfab.plants.base import LTIPlant, NoiseLevel, NoisyOutputs
from microfab.plants.lti import block_diag, discretize
from microfab.plants.sourced_toml import read_sourced

__all__ = ["AXES", "GalvoSLMParams", "GalvoSLMPlant", "galvo_slm_twin", "load_params"]

AXES = ("x", "y")  # two identical axes (assumed: the seed measured one)


@dataclass(frozen=True, kw_only=True)
class GalvoSLMParams:
    """Parameters of the SLM galvo twin (positions in bit, time in s).

    Values and their sources: ``data/galvo_slm.toml`` (`load_params`).

    Parameters
    ----------
    numerator : float
        ``b0`` of ``G(s) = b0 / (s³ + a2 s² + a1 s + a0)``, 1/s³ (seed: 1.242e11).
    denominator_s2, denominator_s1, denominator_s0 : float
        ``a2`` (1/s), ``a1`` (1/s²), ``a0`` (1/s³) (seed: 9517, 5.773e7, 1.272e11); the
        polynomial must be Hurwitz (every pole in the left half plane).
    sample_time_s : float
        Set-point period ``T``, s (10 µs).
    bit_size_m : float
        One bit at the work plane, m (1.5 µm, assumed).
    field_bit : float
        Largest ``|set position|``, bit (32768, assumed).
    velocity_limit_m_s : float
        Largest set-point speed, m/s (assumed).
    acceleration_limit_m_s2 : float
        Largest set-point acceleration (sampled), m/s² (assumed).
    noise_rms_bit : float
        Measured-position noise rms, bit (0.3, assumed); drawn by the simulators.
    mirror_mode_hz : float
        Frequency of the optional mirror mode, Hz, below the Nyquist frequency (assumed).
    mirror_mode_damping : float
        Damping ratio of the optional mirror mode, in (0, 1) (assumed).

    Raises
    ------
    ValueError
        On a value out of range, naming it, its value and unit.
    """

    numerator: float
    denominator_s2: float
    denominator_s1: float
    denominator_s0: float
    sample_time_s: float
    bit_size_m: float
    field_bit: float
    velocity_limit_m_s: float
    acceleration_limit_m_s2: float
    noise_rms_bit: float
    mirror_mode_hz: float
    mirror_mode_damping: float

    def __post_init__(self) -> None:
        check_positive("numerator", self.numerator, "1/s^3")
        check_positive("denominator_s2", self.denominator_s2, "1/s")
        check_positive("denominator_s1", self.denominator_s1, "1/s^2")
        check_positive("denominator_s0", self.denominator_s0, "1/s^3")
        check_positive("sample_time_s", self.sample_time_s, "s")
        check_positive("bit_size_m", self.bit_size_m, "m")
        check_positive("field_bit", self.field_bit, "bit")
        check_positive("velocity_limit_m_s", self.velocity_limit_m_s, "m/s")
        check_positive("acceleration_limit_m_s2", self.acceleration_limit_m_s2, "m/s^2")
        check_nonnegative("noise_rms_bit", self.noise_rms_bit, "bit")
        nyquist = 0.5 / self.sample_time_s
        check_in_range(
            "mirror_mode_hz",
            self.mirror_mode_hz,
            0.0,
            nyquist,
            "Hz",
            low_closed=False,
            high_closed=False,
        )
        check_in_range(
            "mirror_mode_damping",
            self.mirror_mode_damping,
            0.0,
            1.0,
            low_closed=False,
            high_closed=False,
        )
        a2, a1, a0 = self.denominator_s2, self.denominator_s1, self.denominator_s0
        # Routh-Hurwitz for a cubic with positive coefficients: a2 a1 > a0
        if not a2 * a1 > a0:
            raise ValueError(
                f"the denominator s^3 + {a2:g} s^2 + {a1:g} s + {a0:g} is not Hurwitz "
                f"(a2 a1 = {a2 * a1:.4g} must exceed a0 = {a0:.4g}): the twin would be unstable"
            )

    @property
    def static_gain(self) -> float:
        """``G(0) = b0 / a0`` (seed: 0.9764)."""
        return self.numerator / self.denominator_s0

    @property
    def denominator(self) -> tuple[float, float, float, float]:
        """``(1, a2, a1, a0)``: the denominator of ``G`` in descending powers of ``s``."""
        return (1.0, self.denominator_s2, self.denominator_s1, self.denominator_s0)

    def poles(self) -> np.ndarray:
        """Continuous poles of ``G``, rad/s, shape (3,): the real one first, then the pair."""
        r = np.roots(self.denominator)
        return r[np.argsort(np.abs(r.imag))]

    def factors(self) -> tuple[float, float, float]:
        """``(a, ωn, ζ)``: real pole ``-a`` and the pair ``ωn``, ``ζ`` (rad/s, rad/s, 1).

        Raises
        ------
        ValueError
            When ``G`` has three real poles (no complex pair to realise).
        """
        p = self.poles()
        if abs(p[2].imag) == 0.0:
            raise ValueError(
                f"the model's poles {p} are all real; the twin realises one real pole and a "
                "complex pair"
            )
        wn = float(abs(p[2]))
        return float(-p[0].real), wn, float(-p[2].real / wn)

    def with_(self, **changes: Any) -> GalvoSLMParams:
        """A validated copy with ``changes``; unknown names are refused (ValueError)."""
        return replace_known(self, "galvo", **changes)


_SECTIONS = {
    "model": ("numerator", "denominator_s2", "denominator_s1", "denominator_s0"),
    "sampling": ("sample_time_s",),
    "field": ("bit_size_m", "field_bit", "velocity_limit_m_s", "acceleration_limit_m_s2"),
    "noise": ("noise_rms_bit",),
    "mirror_mode": ("mirror_mode_hz", "mirror_mode_damping"),
}


def load_params(path: str | os.PathLike[str] | None = None) -> GalvoSLMParams:
    """Read the SLM galvo twin's parameters (default ``data/galvo_slm.toml``).

    Every value needs a ``<key>_source`` string; unknown sections and keys are refused.

    Raises
    ------
    ValueError
        Naming the file, the section and the key (layout), or the parameter (value).
    """
    return GalvoSLMParams(**read_sourced(path, "galvo_slm.toml", _SECTIONS))


def continuous_axis(config: GalvoSLMParams, mirror_mode: bool = False) -> control.StateSpace:
    """One axis as a continuous state-space model, bit -> bit (the cascade of the module doc).

    Parameters
    ----------
    config : GalvoSLMParams
        The twin's parameters.
    mirror_mode : bool
        Append the lightly damped mirror mode in series.

    Returns
    -------
    control.StateSpace
        States ``(first-order output, position, velocity / ωn)`` in bit, then the mirror
        mode's ``(position, velocity / ωm)`` when present; one input, one output.
    """
    a, wn, zeta = config.factors()
    # x1' = a (G(0) u - x1); x2' = wn x3; x3' = wn (x1 - x2) - 2 zeta wn x3 (x3 = velocity/wn)
    A = np.array([[-a, 0.0, 0.0], [0.0, 0.0, wn], [wn, -wn, -2.0 * zeta * wn]])
    B = np.array([[a * config.static_gain], [0.0], [0.0]])
    C = np.array([[0.0, 1.0, 0.0]])
    if mirror_mode:
        wm = 2.0 * math.pi * config.mirror_mode_hz
        zm = config.mirror_mode_damping
        A = np.block([[A, np.zeros((3, 2))], [np.zeros((2, 5))]])
        A[3, 4] = wm
        A[4, 1], A[4, 3], A[4, 4] = wm, -wm, -2.0 * zm * wm  # driven by the position x2
        B = np.vstack([B, np.zeros((2, 1))])
        C = np.array([[0.0, 0.0, 0.0, 1.0, 0.0]])
    return control.ss(A, B, C, np.zeros((1, 1)))


class GalvoSLMPlant(LTIPlant, NoisyOutputs):
    """The two-axis SLM galvo twin: set positions (bit) in, measured positions (bit) out.

    Parameters
    ----------
    config : GalvoSLMParams
        The twin's parameters.
    mirror_mode : bool
        Add the lightly damped mirror mode (assumed 3 kHz, ζ 0.02) in series.

    Attributes
    ----------
    config : GalvoSLMParams
        The parameters.
    mirror_mode : bool
        Whether the mirror mode is in.
    axes : tuple of str
        ``("x", "y")``.
    axis_model : DiscreteLTI
        One axis, ZOH at ``T`` (SISO), bit -> bit.
    sys : DiscreteLTI
        Both axes, block-diagonal (the `LTIPlant` model).
    noise_level : NoiseLevel
        Measured-position noise per axis, bit (0.3, assumed); `noise` draws it, seeded.

    Notes
    -----
    State: both axes' states (3 each, 5 with the mirror mode) followed by the `LTIPlant`
    kernel scratch. Noise is not added here; `noise` draws it for the simulators.
    """

    def __init__(self, config: GalvoSLMParams, *, mirror_mode: bool = False) -> None:
        if not isinstance(mirror_mode, bool):
            raise ValueError(f"mirror_mode must be true or false, got {mirror_mode!r}")
        self.config = config
        self.mirror_mode = mirror_mode
        self.axes = AXES
        self.noise_level = NoiseLevel((config.noise_rms_bit,) * 2, "bit")
        self.axis_model = discretize(
            continuous_axis(config, mirror_mode), config.sample_time_s, "zoh"
        )
        super().__init__(block_diag(self.axis_model, self.axis_model))
        self.params.setflags(write=False)

    @property
    def static_gain(self) -> float:
        """``G(0)`` of each axis (the mirror mode has unit static gain), bit/bit."""
        return self.config.static_gain

    def continuous_axis(self) -> control.StateSpace:
        """One axis, continuous (`continuous_axis` with this twin's mirror-mode switch)."""
        return continuous_axis(self.config, self.mirror_mode)

    def transfer_function(self) -> control.TransferFunction:
        """One axis as a continuous transfer function, bit -> bit.

        Without the mirror mode it is the seed's ``G`` with the seed's coefficients.
        """
        if not self.mirror_mode:
            return control.tf([self.config.numerator], list(self.config.denominator))
        return control.tf(self.continuous_axis())

    def to_bit(self, meters: float | np.ndarray) -> np.ndarray:
        """Work-plane positions or lengths in m as bit (``m / bit_size_m``)."""
        return np.asarray(meters, dtype=float) / self.config.bit_size_m

    def to_m(self, bits: float | np.ndarray) -> np.ndarray:
        """Positions or lengths in bit as m at the work plane (``bit * bit_size_m``)."""
        return np.asarray(bits, dtype=float) * self.config.bit_size_m

    def axis_limits(self) -> dict[str, AxisLimits]:
        """Declared set-point limits per axis, in bit, bit/s and bit/s² (the field first)."""
        c = self.config
        lim = AxisLimits(
            position=c.field_bit,
            velocity=c.velocity_limit_m_s / c.bit_size_m,
            acceleration=c.acceleration_limit_m_s2 / c.bit_size_m,
            unit="bit",
        )
        return dict.fromkeys(AXES, lim)


def galvo_slm_twin(
    path: str | os.PathLike[str] | None = None,
    *,
    params: GalvoSLMParams | None = None,
    mirror_mode: bool = False,
    **overrides: Any,
) -> GalvoSLMPlant:
    """The SLM galvo twin from the data file (default ``data/galvo_slm.toml``).

    Parameters
    ----------
    path : path-like, optional
        Another parameter file.
    params : GalvoSLMParams, optional
        Parameters already read (then ``path`` is not read); the machine modules pass
        the ones they parsed once (`microfab.machines.twins`).
    mirror_mode : bool
        Add the lightly damped mirror mode (assumed 3 kHz, ζ 0.02).
    **overrides
        `GalvoSLMParams` fields to replace (validated; unknown names refused).
    """
    cfg = load_params(path) if params is None else params
    return GalvoSLMPlant(cfg.with_(**overrides) if overrides else cfg, mirror_mode=mirror_mode)
