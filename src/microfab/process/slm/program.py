"""`VectorPath`: a scan program as a continuous chain of jump and mark vectors.

What an SLM scanner is told to do, in m at the work plane: the points the scanner passes
(its start, then the end of each vector) and which vectors are marks (laser on) or jumps
(laser off). Consecutive marks form a polyline, whose junctions are corners. Built from a
hatch (`VectorPath.from_scan_vectors`), from contours (`VectorPath.from_polylines`) or by
joining programs (`VectorPath.concatenate`); timed by
`microfab.process.slm.timing.rtc_timeline`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.arrays import readonly

__all__ = ["VectorPath"]


@dataclass(frozen=True, eq=False)
class VectorPath:
    """A scan program: a continuous chain of jump and mark vectors, in m.

    Parameters
    ----------
    points : numpy.ndarray
        Shape (n + 1, 2): the scanner's start, then the end of each vector, m.
    is_mark : numpy.ndarray
        Shape (n,), bool: True for a mark (laser on), False for a jump. Consecutive marks
        form a polyline (their junctions are corners).
    """

    points: np.ndarray
    is_mark: np.ndarray

    def __post_init__(self) -> None:
        P = readonly(self.points)
        m = readonly(self.is_mark, dtype=bool)
        if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] < 1 or not np.all(np.isfinite(P)):
            raise ValueError(f"points must be a finite (n + 1, 2) array in m, got {P.shape}")
        if m.shape != (P.shape[0] - 1,):
            raise ValueError(f"is_mark needs one flag per vector ({P.shape[0] - 1}), got {m.shape}")
        object.__setattr__(self, "points", P)
        object.__setattr__(self, "is_mark", m)

    @classmethod
    def from_scan_vectors(cls, vectors: Any, start: Any = None) -> VectorPath:
        """From `microfab.geometry.hatch.ScanVectors` (its initial jump, if any, included).

        Parameters
        ----------
        vectors : ScanVectors
            Marks and the jumps between them.
        start : array_like, optional
            Scanner position before, m; a jump to the first mark is added (unless it has an
            initial jump already).
        """
        vec, mark = vectors.vectors()
        if vec.shape[0] == 0:
            p = np.zeros((1, 2)) if start is None else np.asarray(start, float).reshape(1, 2)
            return cls(p, np.zeros(0, dtype=bool))
        pts = np.vstack([vec[:1, 0], vec[:, 1]])
        if start is not None and vectors.initial_jump is None:
            pts = np.vstack([np.asarray(start, float).reshape(1, 2), pts])
            mark = np.concatenate([[False], mark])
        return cls(pts, mark)

    @classmethod
    def from_polylines(
        cls, polylines: list[np.ndarray], start: Any = (0.0, 0.0), closed: bool = True
    ) -> VectorPath:
        """Marks along each polyline (closed: back to its first point), jumps between them.

        Parameters
        ----------
        polylines : list of numpy.ndarray
            Vertices of each polyline, shape (k >= 2, 2), m, without the repeated first point.
        start : array_like
            Scanner position before the first jump, m.
        closed : bool
            Whether each polyline closes on its first vertex.
        """
        pts = [np.asarray(start, float).reshape(1, 2)]
        flags: list[np.ndarray] = []
        for poly in polylines:
            v = np.asarray(poly, dtype=float)
            if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 2:
                raise ValueError(f"a polyline needs (k >= 2, 2) vertices, got {v.shape}")
            ring = np.vstack([v, v[:1]]) if closed else v
            pts.append(ring)
            flags.append(np.concatenate([[False], np.ones(ring.shape[0] - 1, dtype=bool)]))
        return cls(np.vstack(pts), np.concatenate(flags) if flags else np.zeros(0, bool))

    @staticmethod
    def concatenate(paths: list[VectorPath]) -> VectorPath:
        """The paths one after the other, a jump between the end of one and the next start."""
        if not paths:
            raise ValueError("concatenate needs at least one VectorPath")
        pts = [paths[0].points]
        flags = [paths[0].is_mark]
        for p in paths[1:]:
            pts.append(p.points)
            flags.append(np.concatenate([[False], p.is_mark]))
        return VectorPath(np.vstack(pts), np.concatenate(flags))

    def __len__(self) -> int:
        return int(self.is_mark.size)

    @property
    def lengths(self) -> np.ndarray:
        """Length of each vector, m, shape (n,)."""
        return np.hypot(*np.diff(self.points, axis=0).T)

    @property
    def n_marks(self) -> int:
        """Number of mark vectors."""
        return int(self.is_mark.sum())

    @property
    def n_jumps(self) -> int:
        """Number of jump vectors."""
        return len(self) - self.n_marks

    def summary(self) -> dict[str, float]:
        """Counts and lengths (m) of marks and jumps."""
        L = self.lengths
        return {
            "n_marks": self.n_marks,
            "n_jumps": self.n_jumps,
            "mark_length_m": float(L[self.is_mark].sum()),
            "jump_length_m": float(L[~self.is_mark].sum()),
        }
