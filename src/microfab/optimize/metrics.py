"""Deviation norms of seed 002 (eqs. 16-18) by exact foot-point projection.

For output samples ``φ_1 … φ_M`` (m) and the exact contour ``Ξ``:

* ``L1 = (1/M) Σ min_s ‖φ_i - Ξ(s)‖₂`` (eq. 16);
* ``L2 = sqrt((1/M) Σ min_s ‖φ_i - Ξ(s)‖₂²)`` (eq. 17, "rms");
* ``L∞ = max_i min_s ‖φ_i - Ξ(s)‖₂`` (eq. 18).

``min_s`` is `microfab.geometry.project.project_points` (exact on lines, arcs and curves,
vectorised). Table III's improvement is ``100 (baseline - ours) / baseline`` per norm.
"""

from __future__ import annotations

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
    """L1, L2 and L∞ of eqs. (16)-(18), m, over ``n`` samples."""

    l1: float
    l2: float
    linf: float
    n: int

    @classmethod
    def of(cls, path: Path, points: np.ndarray) -> DeviationNorms:
        """The norms of ``points`` (M, 2), m, against ``path``."""
        d = deviations(path, points)
        return cls(float(d.mean()), float(np.sqrt(np.mean(d**2))), float(d.max()), int(d.size))

    def improvement_over(self, baseline: DeviationNorms) -> dict[str, float]:
        """Table III: ``100 (baseline - self) / baseline`` per norm, %."""
        return {k: 100.0 * (getattr(baseline, k) - getattr(self, k)) / getattr(baseline, k)
                for k in ("l1", "l2", "linf")}  # fmt: skip

    def as_dict(self) -> dict[str, float]:
        """JSON form, m."""
        return {"l1": self.l1, "l2": self.l2, "linf": self.linf, "n": self.n}
