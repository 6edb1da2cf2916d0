"""Axis tracking errors and the exact contour error of any contouring machine.

The figures of merit of seed 004 (laser micromachining stage: Fig. 3, Figs. 4 and 7), for
a twin run or a measured trace of any XY machine that follows a drawn contour:

* Axis errors ``e = r − y`` per axis (Fig. 3): the fraction of samples under the seed's
  "generally lower than 0.5 µm" and the peak ("reaching 0.8 µm at the peak points").
* Contour error: the signed distance of each measured (or true) position to the exact
  drawing (`microfab.geometry.project.project_points`: the foot point on the contour, not
  the reference point of the same time, which mixes lag along the path into it). Per lap:
  maximum and RMS (Fig. 7: "after lap 1 the correction cuts the maximum ≥ 2x").
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from microfab.core.validate import check_positive
from microfab.geometry.path import Path
from microfab.geometry.project import project_points

__all__ = [
    "AXIS_BAND_M",
    "AxisErrors",
    "ContourErrors",
    "axis_errors",
    "contour_errors",
    "laps_along",
]

#: Default band of `axis_errors`, m: seed 004 §IV.A, "errors are generally lower than
#: 0.5 µm" (experiments/seed004_laser/paper.py, FIG3_TYPICAL_ERROR_M).
AXIS_BAND_M = 0.5e-6


@dataclass(frozen=True, kw_only=True)
class AxisErrors:
    """Tracking errors per axis over a stretch of samples (seed 004 Fig. 3).

    Attributes
    ----------
    fraction_below : tuple of float
        Fraction of samples with ``|e| < band_m``, per axis (x, y).
    peak_m : tuple of float
        Largest ``|e|`` per axis, m.
    rms_m : tuple of float
        RMS per axis, m.
    band_m : float
        The band, m (seed 004 §IV.A: 0.5 µm).
    """

    fraction_below: tuple[float, float]
    peak_m: tuple[float, float]
    rms_m: tuple[float, float]
    band_m: float


def axis_errors(
    reference: np.ndarray, measured: np.ndarray, band_m: float = AXIS_BAND_M
) -> AxisErrors:
    """`AxisErrors` of ``reference − measured``, both m, shape (n, 2)."""
    r = np.asarray(reference, dtype=float)
    y = np.asarray(measured, dtype=float)
    if r.shape != y.shape or r.ndim != 2 or r.shape[1] != 2 or r.shape[0] == 0:
        raise ValueError(
            f"reference and measured must both be shaped (n >= 1, 2) in m, got {r.shape} "
            f"and {y.shape}"
        )
    check_positive("band_m", band_m, "m")
    e = np.abs(r - y)
    return AxisErrors(
        fraction_below=tuple(float(v) for v in np.mean(e < band_m, axis=0)),  # type: ignore[arg-type]
        peak_m=tuple(float(v) for v in e.max(axis=0)),  # type: ignore[arg-type]
        rms_m=tuple(float(v) for v in np.sqrt(np.mean(e**2, axis=0))),  # type: ignore[arg-type]
        band_m=band_m,
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class ContourErrors:
    """Contour error of a trace against the exact drawing.

    Attributes
    ----------
    error_m : numpy.ndarray
        Signed distance to the contour per sample, m, shape (n,) (sign: see
        `microfab.geometry.project.project_points`).
    lap_max_m : numpy.ndarray
        Largest ``|error|`` per lap, m, shape (laps,).
    lap_rms_m : numpy.ndarray
        RMS per lap, m, shape (laps,).
    """

    error_m: np.ndarray
    lap_max_m: np.ndarray
    lap_rms_m: np.ndarray

    def after_first_lap_max(self) -> float:
        """Largest ``|error|`` over the laps after the first, m (Fig. 7)."""
        if self.lap_max_m.size < 2:
            raise ValueError("needs at least two laps")
        return float(self.lap_max_m[1:].max())

    def steady_max(self) -> float:
        """`after_first_lap_max` when there are two laps or more, else the one lap's max, m.

        The figure the reports quote: lap 1 starts from the ramp's transient.
        """
        if self.lap_max_m.size >= 2:
            return self.after_first_lap_max()
        return float(self.lap_max_m.max())

    def rms(self) -> float:
        """RMS over the laps: the root of the mean of the laps' mean squares, m."""
        return float(np.sqrt(np.mean(self.lap_rms_m**2)))

    @property
    def steady_label(self) -> str:
        """How `steady_max` was taken, for labels."""
        return "max after lap 1" if self.lap_max_m.size >= 2 else "max"


def contour_errors(
    path: Path, positions: np.ndarray, laps: list[slice] | tuple[slice, ...]
) -> ContourErrors:
    """`ContourErrors` of measured points against a path, per lap.

    Parameters
    ----------
    path : Path
        The exact contour (open or closed), m.
    positions : numpy.ndarray
        Measured (or true) positions, m, shape (n, 2).
    laps : sequence of slice
        The samples of each lap (one slice for a whole open path), at least one.

    Returns
    -------
    ContourErrors
        The signed error per sample and the figures per lap.
    """
    p = np.asarray(positions, dtype=float)
    err = np.asarray(project_points(path, p).distance, dtype=float)
    lap_max = np.array([np.max(np.abs(err[s])) for s in laps])
    lap_rms = np.array([np.sqrt(np.mean(err[s] ** 2)) for s in laps])
    return ContourErrors(error_m=err, lap_max_m=lap_max, lap_rms_m=lap_rms)


def laps_along(path: Path, reference: np.ndarray) -> tuple[slice, ...]:
    """Full laps along a reference's unwrapped arc length on a closed contour.

    Parameters
    ----------
    path : Path
        The contour, m.
    reference : numpy.ndarray
        Reference positions on (or near) it, m, shape (n, 2).

    Returns
    -------
    tuple of slice
        The samples of each full lap (a partial last lap is not counted); one slice over
        everything for an open path or a reference under one lap.
    """
    n = reference.shape[0]
    if not path.closed:
        return (slice(0, n),)
    L = float(path.length)
    s = np.asarray(project_points(path, reference).s, dtype=float)
    ds = np.diff(s)
    ds = ds - L * np.round(ds / L)  # unwrap across the start point (either direction)
    run = np.concatenate([[0.0], np.cumsum(np.abs(ds))])
    k = np.floor(run / L).astype(np.int64)
    edges = np.concatenate([[0], np.flatnonzero(np.diff(k)) + 1])
    laps = [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]
    return tuple(laps) or (slice(0, n),)
