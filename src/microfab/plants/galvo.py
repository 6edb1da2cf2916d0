"""Digital twin of a moving-magnet galvanometer scanner axis (seed 000 §2-3.1).

Open-loop model, in encoder volts per command volt:

``G(s) = g * K / (s (s + a)) * w_amp / (s + w_amp) * prod_i w_i^2 / (s^2 + 2 zeta w_i s + w_i^2)``

followed by ``delay_samples`` samples of computation delay at 1 MHz. The rigid body
(``K / s(s + a)``) is marginally stable; ``w_amp`` is the current amplifier; the ``w_i`` are
the structural resonances the seed measured. The feedback controller (`microfab.machines.galvo`)
is designed with eq. (1) on the *nominal* model (``g = 1``); ``g`` is the ratio of true to
nominal gain.
``K`` itself cancels in the loop (eq. (1) normalises by ``|G(j w_c)|``), so the parameters
that shape the closed loop are ``a``, ``g``, the damping and the delay. ``a`` and ``g`` are
calibrated against seed Table 1 by `microfab.machines.galvo.calibration`.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace

import numpy as np

import control
from microfab.core.validate import check_nonnegative, check_positive
from microfab.plants.lti import DiscreteLTI, discretize, with_input_delay
from microfab.plants.sourced_toml import read_sourced

__all__ = ["CALIBRATED_KEYS", "FS_HZ", "GalvoAxis", "default_galvo_axes"]

FS_HZ = 1e6  # seed 000 §3.1: controllers run at 1 Msps
NOMINAL_GAIN = (2 * np.pi * 2000.0) ** 2  # K in V/(V s^2); cancels in the loop (see module doc)


@dataclass(frozen=True, kw_only=True)
class GalvoAxis:
    """One galvanometer scanner axis and the design data of its lead-lag feedback.

    Parameters
    ----------
    name : str
        Axis name (``"x"`` or ``"y"``).
    resonances_hz : tuple of float
        Structural resonances in Hz (seed 000 §3.1).
    amplitude_v : float
        Half side of the test square in encoder volts (seed 000 §4.3).
    scale_mm_per_v : float
        Beam position per encoder volt in mm/V (seed 000 §4.2).
    rigid_pole_hz : float
        Rigid-body damping pole ``a / 2 pi`` in Hz (calibrated).
    gain_ratio : float
        True over nominal plant gain ``g`` (calibrated).
    resonance_damping : float
        Damping ratio of the structural modes (assumption).
    amplifier_bandwidth_hz : float
        Current amplifier bandwidth in Hz (seed 000 §2: "more than 50 kHz").
    delay_samples : int
        Computation delay in samples of the 1 MHz controller (assumption: one sample).
    noise_rms_v : float
        Encoder noise standard deviation in V (calibrated).
    crossover_hz : float
        Feedback crossover in Hz (seed 000 §3.1).
    fs_hz : float
        Control sample rate in Hz (seed 000 §3.1).
    """

    name: str
    resonances_hz: tuple[float, ...]
    amplitude_v: float
    scale_mm_per_v: float
    rigid_pole_hz: float
    gain_ratio: float = 1.0
    resonance_damping: float = 0.05
    amplifier_bandwidth_hz: float = 50e3
    delay_samples: int = 1
    noise_rms_v: float = 0.0
    crossover_hz: float = 2000.0
    fs_hz: float = FS_HZ

    def __post_init__(self) -> None:
        check_nonnegative("rigid_pole_hz", self.rigid_pole_hz, "Hz")
        for name, unit in (
            ("gain_ratio", ""),
            ("resonance_damping", ""),
            ("amplifier_bandwidth_hz", "Hz"),
            ("amplitude_v", "V"),
            ("scale_mm_per_v", "mm/V"),
            ("crossover_hz", "Hz"),
            ("fs_hz", "Hz"),
        ):
            check_positive(name, getattr(self, name), unit)
        if any(not (0 < f < self.fs_hz / 2) for f in self.resonances_hz):
            raise ValueError(f"resonances must lie in (0, fs/2), got {self.resonances_hz} Hz")
        if self.noise_rms_v < 0:
            raise ValueError(f"noise_rms_v must be >= 0, got {self.noise_rms_v} V")
        if self.delay_samples < 0:
            raise ValueError(f"delay_samples must be >= 0, got {self.delay_samples} samples")

    @property
    def dt(self) -> float:
        """Sample time in s."""
        return 1.0 / self.fs_hz

    def model(self, gain_ratio: float | None = None) -> control.StateSpace:
        """Continuous open-loop galvo model (series of small blocks, well conditioned).

        Parameters
        ----------
        gain_ratio : float, optional
            Overrides ``g``; ``1.0`` gives the nominal design model.
        """
        g = self.gain_ratio if gain_ratio is None else gain_ratio
        a = 2 * np.pi * self.rigid_pole_hz
        rigid = control.ss([[0.0, 1.0], [0.0, -a]], [[0.0], [g * NOMINAL_GAIN]], [[1.0, 0.0]], 0)
        wa = 2 * np.pi * self.amplifier_bandwidth_hz
        sys = control.series(control.ss([[-wa]], [[wa]], [[1.0]], 0), rigid)
        for f in self.resonances_hz:
            w = 2 * np.pi * f
            z = self.resonance_damping
            mode = control.ss([[0.0, 1.0], [-w * w, -2 * z * w]], [[0.0], [w * w]], [[1.0, 0.0]], 0)
            sys = control.series(sys, mode)
        return sys

    def discrete_plant(self) -> DiscreteLTI:
        """ZOH plant at ``fs_hz`` with the computation delay appended.

        Discretised once per distinct axis and shared (the model is immutable).
        """
        return _zoh_plant(self)

    def with_calibration(self, **values: float) -> GalvoAxis:
        """A copy with calibrated parameters replaced."""
        return replace(self, **values)


@functools.lru_cache(maxsize=64)
def _zoh_plant(axis: GalvoAxis) -> DiscreteLTI:
    """`GalvoAxis.discrete_plant`, kept per axis: a twin, its FRF and margins share one."""
    return with_input_delay(discretize(axis.model(), axis.dt, "zoh"), axis.delay_samples)


def _seed_axes() -> dict[str, GalvoAxis]:
    """Axes with the seed's constants and neutral values for the calibrated ones."""
    # seed 000 §3.1: x resonances 31.26/41.70 kHz, y 25.71/31.55 kHz.
    # seed 000 §4.3: the 0.6 mm square is 1 V (x) and 1.44 V (y) of encoder signal.
    # seed 000 §4.2: encoder outputs scaled by 0.3 mm/V. Taken literally for y, 1.44 V would
    # be 0.864 mm, contradicting the 0.6 mm square and the 240/480/960 mm/s targets of the
    # same section; we keep 0.3 mm/V for x and scale y so that 1.44 V is 0.3 mm.
    return {
        "x": GalvoAxis(
            name="x",
            resonances_hz=(31.26e3, 41.70e3),
            amplitude_v=1.0,
            scale_mm_per_v=0.3,
            rigid_pole_hz=100.0,
        ),
        "y": GalvoAxis(
            name="y",
            resonances_hz=(25.71e3, 31.55e3),
            amplitude_v=1.44,
            scale_mm_per_v=0.3 / 1.44,
            rigid_pole_hz=100.0,
        ),
    }


#: The calibrated values of each axis in ``data/galvo_twin.toml`` (``[axes.x]``, ``[axes.y]``).
CALIBRATED_KEYS = ("rigid_pole_hz", "gain_ratio", "noise_rms_v")


def default_galvo_axes(path: str | os.PathLike[str] | None = None) -> dict[str, GalvoAxis]:
    """The calibrated x and y galvo twins (values from ``data/galvo_twin.toml``).

    The file is written by ``microfab calibrate galvo`` (see
    `microfab.machines.galvo.calibration`); every value carries its ``_source``, which
    names the targets it was fitted to.

    Parameters
    ----------
    path : path-like, optional
        Another file of the same layout; the packaged one when omitted.

    Raises
    ------
    ValueError
        A value without its ``_source``, an unknown or missing key, a value the axis
        refuses; the message names the file.
    """
    axes = _seed_axes()
    values = read_sourced(path, "galvo_twin.toml", {}, CALIBRATED_KEYS, tuple(axes))
    out = {}
    for i, (name, ax) in enumerate(axes.items()):
        try:
            out[name] = ax.with_calibration(**{k: float(values[k][i]) for k in CALIBRATED_KEYS})
        except (TypeError, ValueError) as exc:
            where = path if path is not None else "data/galvo_twin.toml"
            raise ValueError(f"{where} [axes.{name}]: {exc}") from exc
    return out
