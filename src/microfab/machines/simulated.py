"""`SimulatedMachine`: a digital twin (plant + built-in feedback + seeded encoder noise)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from microfab.core.limits import AxisLimits, check_command
from microfab.machines.base import Measurement
from microfab.plants.lti import DiscreteLTI
from microfab.sim.lti_fast import LTILoop

__all__ = ["SimulatedMachine"]


class SimulatedMachine:
    """A twin of a stabilised multi-axis machine driven by periodic commands.

    The machine runs continuously: each `run` plays the command ``settle_periods + 1``
    times from wherever the previous run left the loop, and returns the last period (the
    steady state, as an experimenter would record it).

    Parameters
    ----------
    plants, controllers : sequence of DiscreteLTI
        One SISO plant and its feedback controller per axis (closed-loop injection: the
        command is the feedback loop's reference, seed 000 Fig. 2).
    axes : tuple of str
        Axis names.
    noise_rms : sequence of float
        Encoder noise standard deviation per axis, in the output unit.
    limits : mapping of str to AxisLimits
        Declared command limits; a command beyond them is refused before it runs.
    seed : int
        Seed of the noise generator.
    settle_periods : int
        Periods played before the recorded one.
    """

    def __init__(
        self,
        plants: Sequence[DiscreteLTI],
        controllers: Sequence[DiscreteLTI],
        axes: tuple[str, ...],
        noise_rms: Sequence[float],
        limits: Mapping[str, AxisLimits],
        seed: int = 0,
        settle_periods: int = 1,
    ) -> None:
        if len(noise_rms) != len(axes):
            raise ValueError(f"give one noise level per axis ({len(axes)})")
        if settle_periods < 0:
            raise ValueError(f"settle_periods must be >= 0, got {settle_periods}")
        self.loop = LTILoop(list(plants), list(controllers), axes)
        self.axes = axes
        self.dt = self.loop.dt
        self.noise_rms = np.asarray(noise_rms, dtype=float)
        self.limits = dict(limits)
        self.rng = np.random.default_rng(seed)
        self.settle_periods = settle_periods
        self.samples_simulated = 0

    def run(self, command: np.ndarray, with_actuator: bool = False) -> Measurement:
        """Play ``command`` periodically and measure its last period.

        Parameters
        ----------
        command : numpy.ndarray
            One period of the command, shape (n_samples, n_axes), output unit.
        with_actuator : bool
            Also return the feedback controller's actuator signal (more work).

        Raises
        ------
        microfab.core.limits.LimitViolation
            When the command exceeds the declared limits (nothing is run).
        """
        cmd = np.asarray(command, dtype=float)
        if cmd.ndim == 1:
            cmd = cmd[:, None]
        if cmd.shape[1] != len(self.axes):
            raise ValueError(f"command needs {len(self.axes)} columns, got {cmd.shape[1]}")
        check_command(cmd, self.dt, self.limits, self.axes, periodic=True)
        for _ in range(self.settle_periods):
            self.loop.run(cmd, self._noise(cmd.shape), with_command=False)
        res = self.loop.run(cmd, self._noise(cmd.shape), with_command=with_actuator)
        self.samples_simulated += cmd.shape[0] * (self.settle_periods + 1)
        return Measurement(
            dt=self.dt, command=cmd, output=res.measured, axes=self.axes, actuator=res.command
        )

    def _noise(self, shape: tuple[int, ...]) -> np.ndarray:
        return self.rng.standard_normal(shape) * self.noise_rms[None, :]
