"""Two-dimensional dose of a gated Gaussian spot along a sampled path, and its cure threshold.

Seed 001 (compliant XY nanomanipulator MSL) writes closed contours with a 405 nm laser
diode focused to a spot of "around 3 microns" (§2) and cures lines of about 2.5 µm
(§4.2, Figs. 14-15). This module computes what the resin receives when the spot follows a
simulated or measured path with the gated, warming-up power of
:class:`microfab.process.laser.LaserDiode`; :mod:`microfab.process.cured_line` measures
the cured line.

Model
-----
The spot is a Gaussian of 1/e² intensity radius ``w`` (``spot_diameter_m / 2``): the
seed's "spot size around 3 microns" is read as the 1/e² intensity diameter, the usual
laser spot convention (ASSUMED reading; read as a FWHM it would give ``w = 2.55 µm``).
The dose (radiant exposure, J/m²) is::

    E(x, y) = ∫ P(t) G(x - x(t), y - y(t)) dt,   G(r) = 2 / (π w²) · exp(-2 r² / w²)

on a square grid of cell ``cell_fraction · w`` (default w/8 = 0.19 µm). The path is
piecewise linear between samples; the power of interval ``[t[k], t[k+1])`` is its mean
(:meth:`LaserDiode.power` with ``average=True``); each interval is split so that the
spot moves at most ``step_fraction · w`` per sub-step and integrated by the midpoint rule.
Only cells within ``reach_radii · w`` of the spot are updated (G there is below
``exp(-2 reach²)``, 1.5e-8 of its peak at 3 radii), with the separable factors
``exp(-2 dx² / w²) · exp(-2 dy² / w²)`` in a numba kernel.

The resin cures where ``E > E_th`` (a step working curve, as in
:mod:`microfab.process.exposure`, whose Jacobs line width this reproduces on a straight
line). ``E_th`` is not a resin constant here: :func:`calibrate_threshold` sets it so that
the nominal line (straight, constant speed, full power) is 2.5 µm wide (seed 001 Fig. 15).

Closing a loop
--------------
An ideal laser switched on and off at the same point of a closed contour leaves no gap:
each end contributes half the dose there. The cured line runs past a switch-off (and
before a switch-on) by the Gaussian tail ``δ = w / √2 · erfcinv(2 E_th / E_max)``
(0.51 µm for the nominal line). A laser whose dose-equivalent switch-on comes
``warmup_s`` late therefore leaves an uncured gap of about
``speed · warmup_s - 2 δ``, not ``speed · warmup_s``;
:func:`microfab.process.laser.straight_line_closing` computes gap and widths without that
approximation on a straight line, for comparison with the 2-D map measured by
:func:`microfab.process.cured_line.measure_loop`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from microfab.core.signals import check_time_base
from microfab.core.validate import (
    check_finite,
    check_in_range,
    check_int,
    check_positive,
)
from microfab.process.laser import LaserDiode

__all__ = [
    "SEED001_LINE_WIDTH_M",
    "SEED001_SPOT_DIAMETER_M",
    "DoseMap",
    "DoseSettings",
    "calibrate_threshold",
    "dose_map",
    "exposure_map",
]

#: Focused spot size, seed 001 §2 ("around 3 microns"), read as the 1/e² diameter.
SEED001_SPOT_DIAMETER_M = 3e-6
#: Cured line width, seed 001 §4.2 and Fig. 15 ("∼2.5 µm").
SEED001_LINE_WIDTH_M = 2.5e-6


@dataclass(frozen=True, kw_only=True)
class DoseSettings:
    """Spot and grid of a dose map.

    Parameters
    ----------
    spot_diameter_m : float
        1/e² intensity diameter of the Gaussian spot in m, > 0. Default 3 µm, seed 001 §2
        (the 1/e² reading is assumed; module notes).
    cell_fraction : float
        Grid cell as a fraction of the 1/e² radius, in (0, 1]; default 1/8 (0.19 µm for
        the seed's spot), ASSUMED: fine enough that the width of a 2.5 µm line is
        resolved to well under 1 % by the interpolated threshold crossings.
    reach_radii : float
        Cells farther than this many radii from the spot are not updated, in [2, 6];
        default 3 (truncated Gaussian below 1.5e-8 of its peak).
    step_fraction : float
        Largest spot move per integration sub-step, as a fraction of the radius, in
        (0, 1]; default 1/4.
    max_cells : int
        Largest grid (cells) accepted, >= 1; default 4e7 (320 MB of float64).
    """

    spot_diameter_m: float = SEED001_SPOT_DIAMETER_M  # seed 001 §2, 1/e² reading assumed
    cell_fraction: float = 0.125  # assumed (docstring)
    reach_radii: float = 3.0  # assumed (docstring)
    step_fraction: float = 0.25  # assumed (docstring)
    max_cells: int = 40_000_000

    def __post_init__(self) -> None:
        check_positive("spot_diameter_m", self.spot_diameter_m, "m")
        check_in_range("cell_fraction", self.cell_fraction, 0.0, 1.0, low_closed=False)
        check_in_range("reach_radii", self.reach_radii, 2.0, 6.0)
        check_in_range("step_fraction", self.step_fraction, 0.0, 1.0, low_closed=False)
        check_int("max_cells", self.max_cells, 1, "cells")

    @property
    def spot_radius_m(self) -> float:
        """1/e² intensity radius ``w`` in m."""
        return 0.5 * self.spot_diameter_m

    @property
    def cell_m(self) -> float:
        """Grid cell size in m."""
        return self.cell_fraction * self.spot_radius_m


def calibrate_threshold(
    *,
    power_w: float,
    speed_m_s: float,
    settings: DoseSettings | None = None,
    line_width_m: float = SEED001_LINE_WIDTH_M,
) -> float:
    """Cure threshold that makes the nominal line ``line_width_m`` wide.

    The nominal line is straight, written at constant speed and full power. Its dose
    across the line is ``E_max · exp(-2 y² / w²)`` with
    ``E_max = sqrt(2/π) · P / (w · v)`` (the Jacobs line exposure of
    :mod:`microfab.process.exposure`), so the width ``L`` at threshold ``E_th`` obeys
    ``L = w · sqrt(2 ln(E_max / E_th))``, inverted here:
    ``E_th = E_max · exp(-L² / (2 w²))``. For the seed's 3 µm spot and 2.5 µm line
    ``E_th / E_max = exp(-25/18) = 0.249``. The 2-D map reproduces the width to the grid's
    accuracy (``tests/process/test_dose.py``).

    Parameters
    ----------
    power_w : float
        Full optical power in W, > 0.
    speed_m_s : float
        Nominal writing speed in m/s, > 0 (the threshold holds for this speed: a slower
        spot cures a wider line).
    settings : DoseSettings, optional
        Spot (default: seed 001's 3 µm).
    line_width_m : float, optional
        Target width in m, > 0; default 2.5 µm (seed 001 Fig. 15).

    Returns
    -------
    float
        ``E_th`` in J/m².
    """
    p = check_positive("power_w", power_w, "W")
    v = check_positive("speed_m_s", speed_m_s, "m/s")
    width = check_positive("line_width_m", line_width_m, "m")
    w = (settings or DoseSettings()).spot_radius_m
    e_max = math.sqrt(2.0 / math.pi) * p / (w * v)
    return e_max * math.exp(-(width**2) / (2.0 * w**2))


@dataclass(frozen=True)
class DoseMap:
    """Dose on a grid.

    Attributes
    ----------
    dose_j_m2 : numpy.ndarray, shape (ny, nx)
        Dose in J/m²; row ``j`` is ``y_m[j]``, column ``i`` is ``x_m[i]``.
    x_m : numpy.ndarray, shape (nx,)
        Cell centres along x in m.
    y_m : numpy.ndarray, shape (ny,)
        Cell centres along y in m.
    cell_m : float
        Cell size in m.
    spot_radius_m : float
        1/e² radius of the spot that wrote it, m.
    """

    dose_j_m2: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    cell_m: float
    spot_radius_m: float

    @property
    def extent_m(self) -> tuple[float, float, float, float]:
        """Outer edges ``(x_min, x_max, y_min, y_max)`` in m (for ``imshow(origin="lower")``)."""
        h = 0.5 * self.cell_m
        return (
            float(self.x_m[0] - h),
            float(self.x_m[-1] + h),
            float(self.y_m[0] - h),
            float(self.y_m[-1] + h),
        )

    def cured(self, threshold_j_m2: float) -> np.ndarray:
        """Cured cells, bool shape (ny, nx): dose above ``threshold_j_m2`` (J/m², > 0)."""
        th = check_positive("threshold_j_m2", threshold_j_m2, "J/m²")
        return self.dose_j_m2 > th

    def sample(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Dose at points by bilinear interpolation between cell centres, J/m².

        Parameters
        ----------
        px, py : numpy.ndarray
            Point coordinates in m, same shape. Outside the grid the dose is 0 (the grid
            holds every cell within the spot's reach of the lit path).

        Returns
        -------
        numpy.ndarray
            Dose in J/m², the shape of ``px``.
        """
        px = np.asarray(px, dtype=float)
        py = np.asarray(py, dtype=float)
        d = np.pad(self.dose_j_m2, 1)  # zero ring: points just outside fade to 0
        fx = (px - self.x_m[0]) / self.cell_m + 1.0
        fy = (py - self.y_m[0]) / self.cell_m + 1.0
        nyp, nxp = d.shape
        inside = (fx >= 0) & (fx < nxp - 1) & (fy >= 0) & (fy < nyp - 1)
        fx = np.where(inside, fx, 0.0)
        fy = np.where(inside, fy, 0.0)
        i = np.minimum(fx.astype(np.intp), nxp - 2)
        j = np.minimum(fy.astype(np.intp), nyp - 2)
        ax = fx - i
        ay = fy - j
        val = (
            d[j, i] * (1 - ax) * (1 - ay)
            + d[j, i + 1] * ax * (1 - ay)
            + d[j + 1, i] * (1 - ax) * ay
            + d[j + 1, i + 1] * ax * ay
        )
        return np.where(inside, val, 0.0)


@njit(cache=True)
def _deposit(
    x: np.ndarray,
    y: np.ndarray,
    p: np.ndarray,
    dt: float,
    x0: float,
    y0: float,
    cell: float,
    w: float,
    reach: float,
    step: float,
    dose: np.ndarray,
) -> None:
    """Add ``∫ P G dt`` of each lit interval to ``dose`` (ny, nx) in place (midpoint rule)."""
    ny, nx = dose.shape
    norm = 2.0 / (math.pi * w * w)
    inv = 2.0 / (w * w)
    r = reach * w
    half = math.ceil(r / cell) + 1
    gx = np.empty(2 * half + 2)
    gy = np.empty(2 * half + 2)
    for k in range(x.size - 1):
        if p[k] <= 0.0:
            continue
        dx = x[k + 1] - x[k]
        dy = y[k + 1] - y[k]
        m = max(1, math.ceil(math.sqrt(dx * dx + dy * dy) / step))
        wgt = p[k] * dt / m * norm
        for s in range(m):
            f = (s + 0.5) / m
            px = x[k] + f * dx
            py = y[k] + f * dy
            i0 = max(0, math.ceil((px - r - x0) / cell - 0.5))
            i1 = min(nx - 1, math.floor((px + r - x0) / cell - 0.5))
            j0 = max(0, math.ceil((py - r - y0) / cell - 0.5))
            j1 = min(ny - 1, math.floor((py + r - y0) / cell - 0.5))
            if i1 < i0 or j1 < j0:
                continue
            for i in range(i0, i1 + 1):
                u = x0 + (i + 0.5) * cell - px
                gx[i - i0] = math.exp(-inv * u * u)
            for j in range(j0, j1 + 1):
                u = y0 + (j + 0.5) * cell - py
                gy[j - j0] = wgt * math.exp(-inv * u * u)
            for j in range(j0, j1 + 1):
                c = gy[j - j0]
                for i in range(i0, i1 + 1):
                    dose[j, i] += c * gx[i - i0]


def _signal(name: str, value: np.ndarray, n: int, unit: str) -> np.ndarray:
    """A finite float array of shape (n,), else ValueError naming the sample."""
    a = np.asarray(value, dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},) like the time base, got {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{name} must be finite; sample {i} is {a[i]} {unit}")
    return a


def dose_map(
    t: np.ndarray,
    x_m: np.ndarray,
    y_m: np.ndarray,
    power_w: np.ndarray,
    *,
    settings: DoseSettings | None = None,
    bounds_m: tuple[float, float, float, float] | None = None,
) -> DoseMap:
    """Dose of a Gaussian spot moving along a sampled path with a sampled power.

    Parameters
    ----------
    t : numpy.ndarray, shape (n_samples,)
        Sample times in s, uniform, at least 2.
    x_m, y_m : numpy.ndarray, shape (n_samples,)
        Spot position in m (linear between samples).
    power_w : numpy.ndarray, shape (n_samples,)
        Mean power over ``[t[k], t[k+1])`` in W, >= 0 (the last sample is not used):
        :meth:`LaserDiode.power` with ``average=True``, or see :func:`exposure_map`.
    settings : DoseSettings, optional
        Spot and grid (default: seed 001's 3 µm spot, cell w/8).
    bounds_m : tuple of 4 float, optional
        ``(x_min, x_max, y_min, y_max)`` of the grid in m; default the lit path plus the
        spot's reach. The grid is snapped to multiples of the cell size.

    Returns
    -------
    DoseMap
        The dose in J/m² and its cell centres.

    Raises
    ------
    ValueError
        On an empty or non-uniform time base, non-finite positions or power, negative
        power, malformed bounds, or a grid larger than ``settings.max_cells``.
    """
    st = settings or DoseSettings()
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"the path must hold at least 2 samples (t shape {t.shape})")
    _, dt = check_time_base(t)
    n = t.size
    x = _signal("x_m", x_m, n, "m")
    y = _signal("y_m", y_m, n, "m")
    p = _signal("power_w", power_w, n, "W")
    if (p < 0).any():
        i = int(np.flatnonzero(p < 0)[0])
        raise ValueError(f"power_w must be >= 0; sample {i} is {p[i]} W")
    w, cell = st.spot_radius_m, st.cell_m
    if bounds_m is None:
        lit = np.flatnonzero(p[:-1] > 0)
        idx = np.unique(np.concatenate((lit, lit + 1))) if lit.size else np.arange(n)
        pad = (st.reach_radii + 1.0) * w
        bounds = (
            float(x[idx].min()) - pad,
            float(x[idx].max()) + pad,
            float(y[idx].min()) - pad,
            float(y[idx].max()) + pad,
        )
    else:
        if len(bounds_m) != 4:
            raise ValueError(f"bounds_m must be (x_min, x_max, y_min, y_max) in m, got {bounds_m}")
        bounds = tuple(check_finite("bounds_m", b, "m") for b in bounds_m)
        if not (bounds[1] > bounds[0] and bounds[3] > bounds[2]):
            raise ValueError(f"bounds_m must have x_min < x_max and y_min < y_max, got {bounds_m}")
    x0 = math.floor(bounds[0] / cell) * cell
    y0 = math.floor(bounds[2] / cell) * cell
    nx = math.ceil((bounds[1] - x0) / cell)
    ny = math.ceil((bounds[3] - y0) / cell)
    if nx * ny > st.max_cells:
        raise ValueError(
            f"dose grid of {nx} x {ny} cells exceeds max_cells = {st.max_cells}; "
            f"raise cell_fraction (now {st.cell_fraction:g}) or max_cells, or narrow bounds_m"
        )
    dose = np.zeros((ny, nx))
    _deposit(x, y, p, dt, x0, y0, cell, w, st.reach_radii, st.step_fraction * w, dose)
    return DoseMap(
        dose_j_m2=dose,
        x_m=x0 + (np.arange(nx) + 0.5) * cell,
        y_m=y0 + (np.arange(ny) + 0.5) * cell,
        cell_m=cell,
        spot_radius_m=w,
    )


def exposure_map(
    t: np.ndarray,
    x_m: np.ndarray,
    y_m: np.ndarray,
    gate: np.ndarray,
    laser: LaserDiode,
    *,
    settings: DoseSettings | None = None,
    bounds_m: tuple[float, float, float, float] | None = None,
) -> DoseMap:
    """Dose of the gated laser along a sampled path.

    Parameters
    ----------
    t, x_m, y_m : numpy.ndarray, shape (n_samples,)
        Sample times (s, uniform) and spot position (m).
    gate : numpy.ndarray, shape (n_samples,)
        Switch command (bool or 0/1), held over each sample interval.
    laser : LaserDiode
        Power, dead time and warm-up.
    settings, bounds_m
        As in :func:`dose_map`.

    Returns
    -------
    DoseMap
        ``dose_map(t, x_m, y_m, laser.power(t, gate, average=True), ...)``.
    """
    power = laser.power(t, gate, average=True)
    return dose_map(t, x_m, y_m, power, settings=settings, bounds_m=bounds_m)
