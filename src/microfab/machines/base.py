"""The `Machine` protocol: anything that takes a command and returns a measurement.

Learning methods (ILC, identification, reference optimisation) only talk to a `Machine`,
so the same code runs on a digital twin and on hardware reached through files. A machine
has two run modes: `Machine.run` plays a command periodically and records one period of
the steady state; `Machine.run_once` plays a command once from rest, holds its last value
until the machine has settled, and records the whole response.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["Machine", "Measurement", "Resumable"]


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
    reference : numpy.ndarray or None
        The reference the measurement belongs to, when the machine reports it (a trial
        file does; a twin does not, the learner knows it), same shape.
    settled : bool or None
        For a one-shot run (`Machine.run_once`), whether the output settled before the
        longest hold ran out; ``None`` for a periodic run or when unknown.
    """

    dt: float
    command: np.ndarray
    output: np.ndarray
    axes: tuple[str, ...]
    actuator: np.ndarray | None = None
    reference: np.ndarray | None = None
    settled: bool | None = None

    @property
    def n_samples(self) -> int:
        """Number of recorded samples."""
        return int(self.output.shape[0])

    @property
    def time(self) -> np.ndarray:
        """Sample times from the start of the record, s, shape (n_samples,)."""
        return np.arange(self.n_samples) * self.dt


@runtime_checkable
class Machine(Protocol):
    """A machine that runs commands and measures its response, periodically or once.

    Attributes
    ----------
    axes : tuple of str
        Axis names (the command's columns).
    dt : float
        Sample time, s.
    """

    axes: tuple[str, ...]
    dt: float

    def run(self, command: np.ndarray) -> Measurement:
        """Play one period of ``command`` (n_samples, n_axes) repeatedly; measure a period.

        The machine keeps running from where it stands, plays the period until it is in
        periodic steady state, and returns the last period (n_samples long).
        """
        ...

    def run_once(self, command: np.ndarray, *, settle_s: float | None = None) -> Measurement:
        """Play ``command`` (n_samples, n_axes) once from rest, then hold its last value.

        The hold ends once the output has settled, and after ``settle_s`` seconds at most
        (``None``: the machine's default). The whole record is returned: the command
        followed by the hold.
        """
        ...


@runtime_checkable
class Resumable(Protocol):
    """A machine whose whole state (loops, noise generator) can be saved and restored.

    `microfab.machines.learning.learn` saves a snapshot with the learner's state after
    every trial and restores it on resume, so that a run interrupted and resumed on a new
    machine object gives bit for bit what an uninterrupted run gives.
    """

    def snapshot(self) -> dict[str, Any] | None:
        """JSON-ready state, or None when some part cannot be saved."""
        ...

    def restore(self, snapshot: dict[str, Any]) -> None:
        """Put the machine back where `snapshot` was taken."""
        ...
