"""`SimResult`: the labelled output of a closed-loop simulation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["SimResult"]


@dataclass(frozen=True, kw_only=True, eq=False)
class SimResult:
    """Signals of one closed-loop run, all shaped (n_samples, n_axes).

    Attributes
    ----------
    dt : float
        Sample time in s.
    reference : numpy.ndarray
        Reference fed to the feedback loop.
    output : numpy.ndarray
        True plant output (noise-free).
    measured : numpy.ndarray
        Measured output (encoder: output plus noise).
    command : numpy.ndarray
        Controller command to the plant actuator (``None`` when not computed).
    axes : tuple of str
        Axis names.
    final_state : Any
        Opaque state from which a later run continues (machine keeps running).
    """

    dt: float
    reference: np.ndarray
    output: np.ndarray
    measured: np.ndarray
    command: np.ndarray | None
    axes: tuple[str, ...] = ()
    final_state: Any = field(default=None, repr=False)

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.reference.shape[0])

    @property
    def time(self) -> np.ndarray:
        """Sample times in s, shape (n_samples,)."""
        return np.arange(self.n_samples) * self.dt

    @property
    def error(self) -> np.ndarray:
        """Tracking error of the measurement, ``measured - reference``."""
        return self.measured - self.reference

    def tail(self, n: int) -> SimResult:
        """The last ``n`` samples (e.g. the measured period after settling)."""
        sl = slice(self.n_samples - n, None)
        return SimResult(
            dt=self.dt,
            reference=self.reference[sl],
            output=self.output[sl],
            measured=self.measured[sl],
            command=None if self.command is None else self.command[sl],
            axes=self.axes,
            final_state=self.final_state,
        )
