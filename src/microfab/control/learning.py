"""The `Learner` protocol: trial-to-trial learning that saves and resumes its state.

A learner proposes a command for a periodic task, learns from each measured trial
(`microfab.control.ilc.Trial`) and proposes the next one. Its whole state is written
atomically to a directory by ``save`` and read back by ``load``, with a format version,
so a run interrupted at any point resumes exactly where it stopped. The loop that drives
a learner on a machine (twin or hardware) is `microfab.machines.learning.learn`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from microfab.control.ilc import Trial

__all__ = ["Learner"]


@runtime_checkable
class Learner(Protocol):
    """A trial-to-trial learner of one periodic reference.

    Attributes
    ----------
    reference : numpy.ndarray
        One period of the desired output, shape (N, n_axes).
    dt : float
        Sample time, s.
    axes : tuple of str
        Axis names.
    iteration : int
        Trials learned from so far.
    meta : dict
        Data saved with the state (the learning loop keeps its record here): JSON-ready
        values and NumPy arrays, which ``save`` keeps bit for bit.
    """

    reference: np.ndarray
    dt: float
    axes: tuple[str, ...]

    @property
    def iteration(self) -> int:
        """Trials learned from so far."""
        ...

    @property
    def meta(self) -> dict[str, Any]:
        """Data kept with the state (JSON-ready values and NumPy arrays)."""
        ...

    @property
    def rms_history(self) -> np.ndarray:
        """RMS error per learned trial, shape (n_trials, n_axes)."""
        ...

    def current_input(self) -> np.ndarray:
        """The command to apply next, shape (N, n_axes)."""
        ...

    def update(self, trial: Trial) -> np.ndarray:
        """Learn from one measured trial; return the next command, shape (N, n_axes)."""
        ...

    def save(self, directory: str | Path, extra: dict[str, Any] | None = None) -> Path:
        """Write the whole state atomically (``extra`` merged into ``meta``)."""
        ...
