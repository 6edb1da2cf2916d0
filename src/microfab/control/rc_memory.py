"""The saved state of the plug-in RC (`RCMemory`).

One file format for the simulated RC (`microfab.control.repetitive.PluginRC.save_state`)
and the file-based step on hardware.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.control.rc_law import RCConfig, rc_update
from microfab.core.validate import check_int
from microfab.io.checkpoint import read_state, save_state

__all__ = ["RC_FORMAT", "RC_KIND", "RC_VERSION", "RCMemory"]

RC_FORMAT = "microfab-plugin-rc"
#: Version of the saved RC state (`RCMemory.save`); `RCMemory.load` refuses another.
RC_VERSION = 1
#: What `microfab.io.checkpoint` calls the file (files of version 1 written before the
#: run store have no kind, only ``"format": RC_FORMAT`` in their metadata).
RC_KIND = "RC state"


@dataclass(frozen=True, kw_only=True, eq=False)
class RCMemory:
    """The RC's saved state: the one file format of the simulated and file-based RC.

    At a period boundary ``memory`` is the correction applied over the last period and
    ``error`` its measured error; the next period's correction is `next_correction`.

    Parameters
    ----------
    config : RCConfig
        The RC settings.
    memory : numpy.ndarray
        Correction memory, mm, shape (N, n_axes) (mid-period: this period's up to the
        current phase, the last period's after it).
    error : numpy.ndarray
        Error ``r - y`` of the last complete period, mm, shape (N, n_axes).
    error_current : numpy.ndarray
        Error of the current period so far, mm, shape (N, n_axes).
    samples : int
        Samples since the RC started (its sample counter).
    inner : numpy.ndarray
        Flat state of the inner controller (empty for the file-based RC).
    """

    config: RCConfig
    memory: np.ndarray
    error: np.ndarray
    error_current: np.ndarray
    samples: int
    inner: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.config, RCConfig):
            raise TypeError(f"config must be an RCConfig, got {type(self.config).__name__}")
        n = self.config.period_samples
        shape = np.shape(self.memory)
        for name in ("memory", "error", "error_current"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.ndim != 2 or arr.shape[0] != n or arr.shape[1] < 1 or arr.shape != shape:
                raise ValueError(
                    f"RC {name} must be shaped (N = {n}, n_axes) like memory {shape}, "
                    f"got {arr.shape}"
                )
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"RC {name} holds NaN or inf")
            object.__setattr__(self, name, arr)
        check_int("samples", self.samples, 0, "samples")
        inner = np.array(self.inner, dtype=np.float64).ravel()
        object.__setattr__(self, "inner", inner)

    @classmethod
    def initial(cls, config: RCConfig, n_axes: int) -> RCMemory:
        """An empty memory (the first period runs without correction)."""
        check_int("n_axes", n_axes, 1)
        z = np.zeros((config.period_samples, n_axes))
        return cls(config=config, memory=z, error=z, error_current=z, samples=0, inner=())

    def next_correction(self) -> np.ndarray:
        """The correction for the next period, mm, shape (N, n_axes) (`rc_update`)."""
        return rc_update(self.memory, self.error, self.config)

    def after_period(self, error_period: np.ndarray) -> RCMemory:
        """The state after one more period run with `next_correction` and measured error.

        Parameters
        ----------
        error_period : numpy.ndarray
            Error ``r - y`` of that period (against the uncorrected reference), mm,
            shape (N, n_axes).
        """
        applied = self.next_correction()
        err = np.array(error_period, dtype=np.float64)
        if err.shape != applied.shape or not np.all(np.isfinite(err)):
            raise ValueError(
                f"error_period must be finite and shaped {applied.shape} (N, n_axes), "
                f"got {err.shape}"
            )
        return RCMemory(
            config=self.config,
            memory=applied,
            error=err,
            error_current=err,
            samples=self.samples + self.config.period_samples,
            inner=self.inner,
        )

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` (an ``.npz``) atomically; returns the path."""
        return save_state(
            path,
            kind=RC_KIND,
            version=RC_VERSION,
            arrays={
                "memory": self.memory,
                "error": self.error,
                "error_current": self.error_current,
                "inner": self.inner,
            },
            meta={"config": self.config.to_json(), "samples": self.samples},
        )

    @classmethod
    def load(cls, path: str | Path) -> RCMemory:
        """Read a state written by `save`.

        Raises
        ------
        FileNotFoundError
            No file at ``path``.
        ValueError
            Unreadable (`microfab.io.checkpoint.StateFileError`), of another kind or
            version (`microfab.io.runstore.RunRefusedError`), or inconsistent.
        """
        p = Path(path)
        saved = read_state(
            p,
            kind=RC_KIND,
            versions=(RC_VERSION,),
            fix="remove it, or give a new state folder, to start learning again",
        )
        if saved is None:
            raise FileNotFoundError(f"no RC state at {p}")
        try:
            arrays = {k: saved.arrays[k] for k in ("memory", "error", "error_current", "inner")}
            config = RCConfig.from_json(saved.meta["config"])
            return cls(config=config, samples=int(saved.meta["samples"]), **arrays)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"RC state {p} is inconsistent: {exc}") from exc
