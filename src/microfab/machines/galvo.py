"""The galvo-scanner MSL twin of seed 000 as a `SimulatedMachine`."""

from __future__ import annotations

from collections.abc import Mapping

from microfab.machines.limits import AxisLimits
from microfab.machines.simulated import SimulatedMachine
from microfab.plants.galvo import GalvoAxis, default_galvo_axes

__all__ = ["GALVO_LIMITS", "galvo_twin"]

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


def galvo_twin(
    axes: Mapping[str, GalvoAxis] | None = None,
    seed: int = 0,
    settle_periods: int = 1,
    limits: Mapping[str, AxisLimits] | None = None,
) -> SimulatedMachine:
    """The calibrated two-axis galvo twin with lead-lag feedback and encoder noise.

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
    """
    ax = dict(axes) if axes is not None else default_galvo_axes()
    return SimulatedMachine(
        [a.discrete_plant() for a in ax.values()],
        [a.discrete_controller() for a in ax.values()],
        axes=tuple(ax),
        noise_rms=[a.noise_rms_v for a in ax.values()],
        limits=limits if limits is not None else GALVO_LIMITS,
        seed=seed,
        settle_periods=settle_periods,
    )
