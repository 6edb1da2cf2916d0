"""The memo of a calibration's model evaluations, kept in memory and optionally on disk.

Every model evaluation is stored under its normalised point (the exact floats the optimiser
asked for), with the model value of every target. The polish, the sensitivity, the
conflict sweep and the report read points from it rather than re-run them, and a memo file
makes a calibration resumable: rerun with the same seed and budget, the optimiser asks for
the same points and finds each one stored. A memo file belongs to one problem (its
`CalibrationProblem.fingerprint`); another problem's file is refused.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from microfab.calibrate.problem import CalibrationProblem
from microfab.io.atomic import atomic_write_json
from microfab.io.schema import read_json

__all__ = ["MEMO_FORMAT", "Memo"]

MEMO_FORMAT = "microfab-calibration-memo"
_VERSION = 1
#: Size cap of a memo file: assumed, about 10^5 evaluations of 10 parameters and targets.
_MAX_BYTES = 200_000_000


class Memo:
    """Model values by normalised point, for one problem.

    Parameters
    ----------
    problem : CalibrationProblem
        The problem whose model values are stored.
    path : path-like, optional
        A JSON file to load from (if it exists) and `save` to, atomically.

    Raises
    ------
    ValueError
        If ``path`` holds a memo of another problem, or is not a memo file.
    """

    def __init__(self, problem: CalibrationProblem, path: str | os.PathLike[str] | None = None):
        self.problem = problem
        self.path = None if path is None else Path(path)
        self._values: dict[tuple[float, ...], np.ndarray] = {}
        self._unsaved = 0
        if self.path is not None and self.path.exists():
            self._load(self.path)

    def __len__(self) -> int:
        return len(self._values)

    def __contains__(self, u: tuple[float, ...]) -> bool:
        return u in self._values

    @property
    def unsaved(self) -> int:
        """Points stored since the last `save`."""
        return self._unsaved

    def get(self, u: tuple[float, ...]) -> np.ndarray | None:
        """The model vector stored at ``u`` (targets order, shape (m,)), or None."""
        return self._values.get(u)

    def put(self, u: tuple[float, ...], model: np.ndarray) -> None:
        """Store the model vector ``model``, shape (m,), at normalised point ``u``."""
        self._values[u] = np.asarray(model, dtype=float).copy()
        self._unsaved += 1

    def items(self) -> list[tuple[tuple[float, ...], np.ndarray]]:
        """Every stored (point, model vector), in the order they were stored."""
        return list(self._values.items())

    def save(self) -> None:
        """Write the memo to its file atomically, if it has one and anything is new."""
        if self.path is None or self._unsaved == 0:
            return
        points = [list(u) for u in self._values]
        values = [
            [v if math.isfinite(v) else None for v in m.tolist()] for m in self._values.values()
        ]
        atomic_write_json(
            self.path,
            {
                "format": MEMO_FORMAT,
                "version": _VERSION,
                "fingerprint": self.problem.fingerprint(),
                "parameters": list(self.problem.parameter_names),
                "targets": list(self.problem.target_names),
                "points": points,
                "values": values,
            },
        )
        self._unsaved = 0

    def _load(self, path: Path) -> None:
        data = read_json(path, "a calibration memo", max_bytes=_MAX_BYTES)
        if not isinstance(data, dict) or data.get("format") != MEMO_FORMAT:
            raise ValueError(f"{path} is not a calibration memo (no format {MEMO_FORMAT!r})")
        if data.get("version") != _VERSION:
            raise ValueError(f"{path}: memo version {data.get('version')!r}, expected {_VERSION}")
        if data.get("fingerprint") != self.problem.fingerprint():
            raise ValueError(
                f"{path} is the memo of another calibration problem (parameters, bounds or "
                "targets differ): give another memo path or delete it"
            )
        n, m = len(self.problem.parameters), len(self.problem.targets)
        points, values = data.get("points"), data.get("values")
        if (
            not isinstance(points, list)
            or not isinstance(values, list)
            or len(points) != len(values)
        ):
            raise ValueError(f"{path}: memo points and values do not pair up")
        for u, v in zip(points, values, strict=True):
            if not (isinstance(u, list) and len(u) == n and isinstance(v, list) and len(v) == m):
                raise ValueError(f"{path}: a memo entry has the wrong length")
            key = tuple(float(x) for x in u)
            if not all(math.isfinite(x) and 0.0 <= x <= 1.0 for x in key):
                raise ValueError(f"{path}: a memo point lies outside [0, 1]")
            self._values[key] = np.array([np.nan if x is None else float(x) for x in v])
