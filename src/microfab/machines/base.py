"""The `Machine` protocol: anything that takes a command and returns a measurement.

Learning methods (ILC, identification, reference optimisation) only talk to a `Machine`,
so the same code runs on a digital twin and on hardware reached through files.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["Machine", "Measurement"]


@dataclass(frozen=True, kw_only=True, eq=False)
class Measurement:
    """What a machine returns for one command.

    Attributes
    ----------
    dt : float
        Sample time, s.
    command : numpy.ndarray
        The command that was applied, shape (n_samples, n_axes).
    output : numpy.ndarray
        The measured output (e.g. encoder), shape (n_samples, n_axes).
    axes : tuple of str
        Axis names.
    actuator : numpy.ndarray or None
        The feedback controller's actuator signal when available (same shape).
    """

    dt: float
    command: np.ndarray
    output: np.ndarray
    axes: tuple[str, ...]
    actuator: np.ndarray | None = None


@runtime_checkable
class Machine(Protocol):
    """A machine that runs a periodic command and measures one period of its response."""

    axes: tuple[str, ...]
    dt: float

    def run(self, command: np.ndarray) -> Measurement:
        """Apply one period of ``command`` (n_samples, n_axes) and measure it."""
        ...
