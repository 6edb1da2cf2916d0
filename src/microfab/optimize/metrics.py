"""Deviation norms of seed 002 (eqs. 16-18) by exact foot-point projection.

For output samples ``φ_1 … φ_M`` (m) and the exact contour ``Ξ``:

* ``L1 = (1/M) Σ min_s ‖φ_i - Ξ(s)‖₂`` (eq. 16);
* ``L2 = sqrt((1/M) Σ min_s ‖φ_i - Ξ(s)‖₂²)`` (eq. 17, "rms");
* ``L∞ = max_i min_s ‖φ_i - Ξ(s)‖₂`` (eq. 18).

``min_s`` is `microfab.geometry.project.project_points` (exact on lines, arcs and curves,
vectorised). Table III's improvement is ``100 (baseline - ours) / baseline`` per norm.
`DeviationNorms` holds the three (and the tail's L∞ where the run's end is scored apart);
``microfab optimize`` and the ``stage-reference-opt`` job
(`microfab.machines.xy_stage.reference`) score with it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microfab.geometry.path import Path
from microfab.geometry.project import project_points

__all__ = ["DeviationNorms", "deviations", "projected_speed"]


def deviations(path: Path, points: np.ndarray) -> np.ndarray:
    """``min_s ‖φ_i - Ξ(s)‖₂`` of each point, shape (M,), m.

    Parameters
    ----------
    path : Path
        The contour, m.
    points : numpy.ndarray
        Shape (M, 2), m, finite.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] == 0:
        raise ValueError(f"points must be (M, 2) with M >= 1, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    return np.abs(np.asarray(project_points(path, pts).distance, dtype=float))


def projected_speed(path: Path, points: np.ndarray, dt: float) -> np.ndarray:
    """Speed of the foot point along the contour, ``Δs / dt``, shape (M - 1,), m/s.

    On a closed contour the step across ``s = S`` is unwrapped (the shorter way round).
    Seed 002 Fig. 12, bottom panel.
    """
    s = np.asarray(project_points(path, np.asarray(points, dtype=float)).s, dtype=float)
    ds = np.diff(s)
    length = float(path.length)
    if np.linalg.norm(path.end - path.start) < 1e-9:
        ds = (ds + length / 2) % length - length / 2
    return ds / dt


@dataclass(frozen=True)
class DeviationNorms:
    """L1, L2 and L∞ of eqs. (16)-(18), m, over ``n`` samples.

    ``tail_linf`` is the L∞ of the samples after those ``n`` (the input held after ``T``,
    scored apart from the run, seed 002 §V), m, where they were scored; else None.
    """

    l1: float
    l2: float
    linf: float
    n: int
    tail_linf: float | None = None

    @classmethod
    def of(cls, path: Path, points: np.ndarray, tail_from: int | None = None) -> DeviationNorms:
        """The norms of ``points`` (M, 2), m, against ``path``.

        With ``tail_from`` the norms are over rows ``0 … tail_from - 1`` and the rows
        after them are the tail (`tail_linf`, 0 when there are none).
        """
        d = deviations(path, points)
        run = d if tail_from is None else d[:tail_from]
        tail = None if tail_from is None else d[tail_from:]
        return cls(
            float(np.mean(run)),
            float(np.sqrt(np.mean(run**2))),
            float(np.max(run)),
            int(run.size),
            None if tail is None else (float(np.max(tail)) if tail.size else 0.0),
        )

    @classmethod
    def from_dict(cls, data: dict[str, float]) -> DeviationNorms:
        """Back from `as_dict`."""
        tail = data.get("tail_linf")
        return cls(data["l1"], data["l2"], data["linf"], int(data["n"]), tail)

    @classmethod
    def pooled(cls, parts: Sequence[DeviationNorms]) -> DeviationNorms:
        """Several outputs scored one after another, as one (``tail_linf`` None).

        L1 and L2 over all their samples, the largest L∞ (seed 002 Figs. 16-17: the
        letters traced in turn).
        """
        n = np.array([p.n for p in parts], dtype=float)
        l1 = np.array([p.l1 for p in parts])
        l2 = np.array([p.l2 for p in parts])
        linf = np.array([p.linf for p in parts])
        return cls(
            float(np.sum(n * l1) / n.sum()),
            float(math.sqrt(np.sum(n * l2**2) / n.sum())),
            float(linf.max()),
            int(n.sum()),
        )

    def improvement_over(self, baseline: DeviationNorms) -> dict[str, float]:
        """Table III: ``100 (baseline - self) / baseline`` per norm, %."""
        return {k: 100.0 * (getattr(baseline, k) - getattr(self, k)) / getattr(baseline, k)
                for k in ("l1", "l2", "linf")}  # fmt: skip

    def as_dict(self) -> dict[str, float]:
        """JSON form, m (``tail_linf`` only where scored)."""
        out = {"l1": self.l1, "l2": self.l2, "linf": self.linf}
        if self.tail_linf is not None:
            out["tail_linf"] = self.tail_linf
        return {**out, "n": self.n}
