"""Cured-line measures on analytic dose maps (independent of the deposit kernel)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.process.cured_line import line_widths, measure_loop
from microfab.process.dose import DoseMap

W = 1.5e-6  # m, 1/e² radius of the seed 001 spot (§2, 1/e² reading)
CELL = W / 8
E0 = 4.0  # J/m², peak dose (any unit would do: only the ratio to the threshold matters)


def _grid(half_m: float) -> tuple[np.ndarray, np.ndarray]:
    c = (np.arange(-round(half_m / CELL), round(half_m / CELL)) + 0.5) * CELL
    return np.meshgrid(c, c)


def _map(dose: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> DoseMap:
    return DoseMap(dose_j_m2=dose, x_m=gx[0], y_m=gy[:, 0], cell_m=CELL, spot_radius_m=W)


def test_ridge_width_and_offset() -> None:
    gx, gy = _grid(20e-6)
    y0 = 0.3e-6  # line placed off the measured path
    dmap = _map(E0 * np.exp(-2 * (gy - y0) ** 2 / W**2), gx, gy)
    lw = line_widths(dmap, np.array([[-10e-6, 0.0], [10e-6, 0.0]]), 1.0, closed=False)
    expect = W * math.sqrt(2 * math.log(E0 / 1.0))  # 2.50 µm
    np.testing.assert_allclose(lw.width_m, expect, rtol=5e-3)
    np.testing.assert_allclose(lw.offset_m, y0, atol=CELL / 10)
    np.testing.assert_allclose(lw.normals, [[0.0, 1.0]] * lw.arc_m.size, atol=1e-12)
    none = line_widths(dmap, np.array([[-10e-6, 0.0], [10e-6, 0.0]]), 5.0, closed=False)
    assert (none.width_m == 0).all() and np.isnan(none.offset_m).all()


R0 = 30e-6  # m, ring radius


def _ring(*dips: tuple[float, float]) -> tuple[DoseMap, np.ndarray]:
    """Ring of radius R0, peak dose E0 across it, with V-shaped dips along it.

    Each dip ``(centre_m, half_m)`` scales the dose by ``min(1, |a - centre| / half)``,
    ``a`` the arc length from angle 0, so at threshold ``E0 / 4`` the uncured arc of a
    dip is ``half / 2`` on either side of its centre: ``half / 2`` long in all.
    """
    gx, gy = _grid(40e-6)
    dose = E0 * np.exp(-2 * (np.hypot(gx, gy) - R0) ** 2 / W**2)
    arc = np.mod(np.arctan2(gy, gx), 2 * math.pi) * R0
    length = 2 * math.pi * R0
    for centre, half in dips:
        d = np.abs(np.mod(arc - centre + length / 2, length) - length / 2)
        dose *= np.minimum(1.0, d / half)
    phi = np.linspace(0, 2 * math.pi, 3600, endpoint=False)
    return _map(dose, gx, gy), R0 * np.column_stack((np.cos(phi), np.sin(phi)))


def test_closed_ring() -> None:
    dmap, contour = _ring()
    m = measure_loop(dmap, contour, 1.0)
    assert m.closed and m.gap_m == 0.0 and m.uncured_m == 0.0
    assert m.mean_width_m == pytest.approx(W * math.sqrt(2 * math.log(E0)), rel=5e-3)


@pytest.mark.parametrize("closing_index", [0, 25, 3590])
def test_gap_at_the_closing_point(closing_index: int) -> None:
    # A 2 µm gap whose start lies 0.5 µm after the contour's point `closing_index`.
    centre = closing_index * 2 * math.pi * R0 / 3600 + 1.5e-6
    dmap, contour = _ring((centre, 4e-6))
    m = measure_loop(dmap, contour, 1.0, closing_index=closing_index)
    assert not m.closed
    assert m.gap_m == pytest.approx(2e-6, abs=CELL)
    assert m.uncured_m == pytest.approx(2e-6, abs=CELL)
    assert m.closing_width_m > 0  # the gap starts just after the closing point
    assert m.closing_min_width_m == 0.0


def test_gap_nearest_the_closing_point_is_reported() -> None:
    near = (5.5e-6, 2e-6)  # a 1 µm gap 5 µm after the closing point
    far = (math.pi * R0, 6e-6)  # a 3 µm gap on the far side
    m = measure_loop(_ring(near, far)[0], _ring()[1], 1.0)
    assert m.gap_m == pytest.approx(1e-6, abs=CELL)
    assert m.uncured_m == pytest.approx(4e-6, abs=2 * CELL)


def test_bad_inputs_refused() -> None:
    dmap, contour = _ring()
    with pytest.raises(ValueError, match="closing_index"):
        measure_loop(dmap, contour, 1.0, closing_index=contour.shape[0])
    with pytest.raises(ValueError, match="threshold_j_m2"):
        measure_loop(dmap, contour, 0.0)
    with pytest.raises(ValueError, match="path_xy_m"):
        line_widths(dmap, np.zeros((5, 3)), 1.0, closed=True)
    with pytest.raises(ValueError, match="distinct"):
        line_widths(dmap, np.zeros((5, 2)), 1.0, closed=True)
    bad = contour.copy()
    bad[3, 0] = np.inf
    with pytest.raises(ValueError, match="finite"):
        measure_loop(dmap, bad, 1.0)
