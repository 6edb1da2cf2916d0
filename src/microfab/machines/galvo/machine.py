"""The galvo-scanner MSL twin of seed 000: each axis stabilised by eq. (1) lead-lag feedback.

The plant (`microfab.plants.galvo.GalvoAxis`) is open loop; this module closes the loop
with the seed's controller and gives the stabilised scanner that the ILC sees, as
transfer functions (`open_loop`, `complementary_sensitivity`) and as a `SimulatedMachine`
(`twin`, alias `galvo_twin`). The machine surface: `DATA_FILES`, `limits`, `twin` and
`play` (one periodic command through the twin, what its encoders measure). The twin's
axes are read once per version of the data file and each axis' loop is built once; the
machine itself is new at each call, since it carries its noise generator's state.
The calibration of the axes against seed 000 Table 1 is
`microfab.machines.galvo.calibration`.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np

import control
from microfab.control.base import LTIController
from microfab.control.leadlag import lead_lag
from microfab.core.limits import AxisLimits
from microfab.machines.base import Measurement
from microfab.machines.simulated import EncoderNoise, SimPath, SimulatedMachine
from microfab.machines.twins import TwinCache
from microfab.plants.base import LTIPlant
from microfab.plants.galvo import GalvoAxis, default_galvo_axes
from microfab.plants.lti import DiscreteLTI, discretize

__all__ = [
    "DATA_FILES",
    "GALVO_LIMITS",
    "calibrated_axes",
    "complementary_sensitivity",
    "controller_tf",
    "discrete_controller",
    "galvo_twin",
    "limits",
    "open_loop",
    "play",
    "twin",
]

# Declared command limits of the twin, in encoder volts. Not from the seed: position is the
# +-10 V range of the DAQ analogue output that feeds the loop (seed 000 §3.2 names a Keysight
# U2531A). Velocity: about 8x the largest slope of the 400 features/s ILC input (5.9e3 V/s).
# Acceleration is a bound on the sampled command, whose corners (u_1 = y_d, seed 000 §4)
# change slope by up to 2 x 4.6e3 V/s within one 1 us sample (~9e9 V/s^2); the feedback
# loop, not the command, limits the mirror's acceleration.
GALVO_LIMITS = {
    name: AxisLimits(position=10.0, velocity=5e4, acceleration=2e10, unit="V")
    for name in ("x", "y")
}


#: The packaged data file the calibrated axes are read from.
DATA_FILES = ("galvo_twin.toml",)

_AXES: TwinCache[dict[str, GalvoAxis], dict[str, GalvoAxis]] = TwinCache(
    lambda path: default_galvo_axes(), lambda axes: axes, DATA_FILES[0]
)


def calibrated_axes() -> dict[str, GalvoAxis]:
    """The calibrated axes (`default_galvo_axes`), read once per version of the data file.

    Returns a new dict of the shared, immutable axes.
    """
    return dict(_AXES())


@functools.lru_cache(maxsize=64)
def _loop(axes: tuple[GalvoAxis, ...]) -> tuple[tuple[LTIPlant, ...], tuple[LTIController, ...]]:
    """Plant and controller of each axis' loop, built once per distinct axes (immutable)."""
    return (
        tuple(LTIPlant(a.discrete_plant()) for a in axes),
        tuple(LTIController(discrete_controller(a)) for a in axes),
    )


def galvo_twin(
    axes: Mapping[str, GalvoAxis] | None = None,
    seed: int = 0,
    settle_periods: int = 1,
    limits: Mapping[str, AxisLimits] | None = None,
    path: SimPath | None = None,
) -> SimulatedMachine:
    """The calibrated two-axis galvo twin with lead-lag feedback and encoder noise.

    One SISO loop per axis (`LTIPlant` of ``axis.discrete_plant()`` with an
    `LTIController` of `discrete_controller`), so the machine runs on the lifted LTI path
    unless ``path`` says otherwise.

    Parameters
    ----------
    axes : mapping of str to GalvoAxis, optional
        Axis models; the calibrated defaults when omitted.
    seed : int
        Noise seed.
    settle_periods : int
        Periods played before the recorded one at each run.
    limits : mapping of str to AxisLimits, optional
        Declared limits; `GALVO_LIMITS` when omitted.
    path : SimPath, optional
        Force a simulator (``compiled`` or ``python`` give the same numbers, slower).
    """
    ax = dict(axes) if axes is not None else calibrated_axes()
    plants, controllers = _loop(tuple(ax.values()))
    return SimulatedMachine(
        list(plants),
        list(controllers),
        EncoderNoise(rms=tuple(a.noise_rms_v for a in ax.values()), seed=seed),
        axes=tuple(ax),
        limits=limits if limits is not None else GALVO_LIMITS,
        settle_periods=settle_periods,
        path=path,
    )


twin = galvo_twin


def limits() -> dict[str, AxisLimits]:
    """The twin's declared command limits per axis, encoder V (`GALVO_LIMITS`, a copy)."""
    return dict(GALVO_LIMITS)


def play(
    command: np.ndarray,
    *,
    axes: Mapping[str, GalvoAxis] | None = None,
    seed: int = 0,
    settle_periods: int = 1,
) -> Measurement:
    """Play one period of a command on a fresh twin; its steady-state period measured.

    Parameters
    ----------
    command : numpy.ndarray
        One period of the command, encoder V, shape (n, 2): x and y at the axes' 1 MHz.
    axes : mapping of str to GalvoAxis, optional
        Axis models; the calibrated defaults when omitted.
    seed : int
        Noise seed.
    settle_periods : int
        Periods played before the recorded one.

    Returns
    -------
    Measurement
        The last period: ``output`` the encoders' positions, V, shape (n, 2).

    Raises
    ------
    microfab.core.limits.LimitViolation
        A command beyond `limits` (nothing is run).
    """
    return galvo_twin(axes, seed=seed, settle_periods=settle_periods).run(command)


def controller_tf(axis: GalvoAxis) -> control.TransferFunction:
    """Continuous lead-lag controller of seed 000 eq. (1), designed on the nominal model.

    Parameters
    ----------
    axis : GalvoAxis
        The axis; its ``crossover_hz`` places the crossover (seed 000 §3.1: 2 kHz).
    """
    return lead_lag(axis.model(gain_ratio=1.0), axis.crossover_hz)


@functools.lru_cache(maxsize=64)
def discrete_controller(axis: GalvoAxis) -> DiscreteLTI:
    """Tustin-discretised lead-lag controller at the axis' ``fs_hz`` (seed 000 §3.1: 1 MHz).

    Designed and discretised once per distinct axis and shared (the model is immutable).
    """
    return discretize(controller_tf(axis), axis.dt, "tustin")


@functools.lru_cache(maxsize=64)
def open_loop(axis: GalvoAxis) -> DiscreteLTI:
    """Discrete open loop ``L = C G`` (controller then plant), for margins (seed 000 §3.1).

    Built once per distinct axis and shared (the model is immutable).
    """
    c = discrete_controller(axis)
    p = axis.discrete_plant()
    ser = control.series(control.ss(c.A, c.B, c.C, c.D, c.dt), control.ss(p.A, p.B, p.C, p.D, p.dt))
    return DiscreteLTI(ser.A, ser.B, ser.C, ser.D, axis.dt)


def complementary_sensitivity(axis: GalvoAxis, freq_hz: np.ndarray) -> np.ndarray:
    """``T = L / (1 + L)`` of the stabilised scanner ``P`` at ``freq_hz`` (complex).

    Parameters
    ----------
    axis : GalvoAxis
        The axis.
    freq_hz : numpy.ndarray
        Frequencies, Hz, any shape.

    Returns
    -------
    numpy.ndarray
        Complex response, shape of ``freq_hz``; at DC, where ``L`` has a pole, ``T = 1``.
    """
    f = np.asarray(freq_hz, dtype=float)
    L = open_loop(axis).frequency_response(f)[:, 0, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        T = L / (1.0 + L)
    T[~np.isfinite(L)] = 1.0
    return T.reshape(f.shape)
