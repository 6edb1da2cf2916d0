"""One excitation run of the seed 002 XY stage: a checked command record at 10 kHz.

`ExcitationRun` holds both axes' set-points (m) from rest to rest; it is refused unless it
passes :func:`~microfab.core.limits.check_trajectory` against seed 002 Table I
(`MachineLimits.seed002_stage`). The generators are in :mod:`microfab.identify.excitation`.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.core.signals import Trace
from microfab.core.validate import check_in_range, check_int, check_positive
from microfab.trajectory.base import Trajectory

__all__ = [
    "AXES",
    "DT",
    "KINDS",
    "LIMITS",
    "SEED_A_MAX",
    "ExcitationRun",
    "check_a_max",
    "command_digest",
    "spawn_seeds",
]

DT = 1e-4  # seed 002 Table I: low-level control loop frequency 10 kHz
LIMITS = MachineLimits.seed002_stage()  # seed 002 Table I
AXES = ("input_x", "input_y")  # columns of a run file, as `microfab ilc step` reads them
KINDS = ("random", "shape", "prbs", "chirp")
#: Largest acceleration of the seed's training data, m/s² (seed 002 §III-D: "up to
#: 5 m s⁻²"; Table I allows 40).
SEED_A_MAX = 5.0
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*\Z")


def command_digest(command: np.ndarray) -> str:
    """SHA-256 of the command's float64 little-endian bytes (C order)."""
    return hashlib.sha256(np.ascontiguousarray(command, dtype="<f8").tobytes()).hexdigest()


@dataclass(frozen=True, kw_only=True, eq=False)
class ExcitationRun:
    """One command record for both axes, from rest to rest, within Table I.

    Parameters
    ----------
    kind : str
        One of `KINDS`.
    name : str
        Unique within a data set; the file stem (letters, digits, ``_``, ``.``, ``-``).
    dt : float
        Sample time, s (`DT`, 10 kHz, for the generators here).
    command : array_like, shape (n, 2)
        Set-points of x and y, m; copied read-only.
    seed : int
        Seed the run was drawn from (0 for a deterministic one).
    params : Mapping
        How it was made (JSON-serialisable numbers and strings).

    Raises
    ------
    ValueError
        A bad kind, name, ``dt`` or shape.
    microfab.core.limits.LimitViolation
        When ``check_trajectory(..., MachineLimits.seed002_stage())`` refuses the command
        (the message names the run, the check, the axis, the quantity and the limit).
    """

    kind: str
    name: str
    dt: float
    command: np.ndarray
    seed: int = 0
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"run kind must be one of {KINDS}, got {self.kind!r}")
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(
                f"run name {self.name!r} must start with a letter or digit and hold only "
                "letters, digits, '_', '.' and '-' (it names the file)"
            )
        check_positive("dt", self.dt, "s")
        check_int("seed", self.seed, 0)
        cmd = np.array(self.command, dtype=float)
        if cmd.ndim != 2 or cmd.shape[1] != 2 or cmd.shape[0] < 2:
            raise ValueError(f"run {self.name}: command must be (n >= 2, 2) m, got {cmd.shape}")
        object.__setattr__(self, "command", readonly(cmd))
        object.__setattr__(self, "params", dict(self.params))
        self.check()

    def check(self) -> None:
        """Refuse the run unless it passes ``check_trajectory`` against Table I (at rest)."""
        try:
            traj = Trajectory(dt=self.dt, position=self.command, at_rest=True)
            check_trajectory(traj, LIMITS)
        except (LimitViolation, ValueError) as exc:
            raise LimitViolation(
                f"run {self.name} ({self.kind}) fails check_trajectory against seed 002 "
                f"Table I: {exc}"
            ) from None

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.command.shape[0])

    @property
    def duration(self) -> float:
        """``n_samples * dt``, s."""
        return self.n_samples * self.dt

    @property
    def digest(self) -> str:
        """SHA-256 of the command (float64 little-endian bytes)."""
        return command_digest(self.command)

    def peaks(self) -> dict[str, list[float]]:
        """Largest sampled ``|v|`` (m/s) and ``|a|`` (m/s²) per axis (finite differences)."""
        x = np.vstack([self.command[:1], self.command, self.command[-1:]])  # held at rest
        v = np.max(np.abs(np.diff(x, axis=0)), axis=0) / self.dt
        a = np.max(np.abs(np.diff(x, 2, axis=0)), axis=0) / self.dt**2
        return {"velocity_m_s": v.tolist(), "acceleration_m_s2": a.tolist()}

    def to_trace(self) -> Trace:
        """The command as a `Trace`: axes ``input_x``, ``input_y``, unit m, from t = 0."""
        return Trace(dt=self.dt, values=self.command, axes=AXES, unit="m")


def check_a_max(a_max: float) -> float:
    """``a_max`` (m/s²) if in (0, 40], Table I's limit; else ``ValueError``."""
    return check_in_range("a_max", a_max, 0.0, LIMITS.acceleration[0], "m/s^2", low_closed=False)


def spawn_seeds(seed: int, n: int) -> list[int]:
    """``n`` independent 63-bit seeds from ``seed`` (NumPy's SeedSequence)."""
    check_int("seed", seed, 0)
    return [
        int(s.generate_state(1, np.uint64)[0] >> np.uint64(1))
        for s in np.random.SeedSequence(seed).spawn(n)
    ]
