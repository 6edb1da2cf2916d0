"""Bounds of the parametric shapes: huge or non-finite parameters are refused quickly."""

from __future__ import annotations

import time

import pytest

from microfab.geometry.shapes import MAX_LOBES, MAX_SIDES, MAX_TURNS, lissajous, parse_shape


@pytest.mark.parametrize(
    "spec, match",
    [
        ("polygon:n_sides=1e7,radius=0.01", f"from 3 to {MAX_SIDES}"),  # was a hang
        ("polygon:n_sides=inf,radius=0.01", "n_sides"),  # was OverflowError
        ("polygon:n_sides=nan,radius=0.01", "n_sides"),  # was ValueError from int()
        ("polygon:n_sides=6.5,radius=0.01", "n_sides"),
        ("spiral:theta1=1e12", f"more than {MAX_TURNS} turns"),  # was a hang
        ("spiral:theta0=1e6,theta1=1000010", "turns"),  # was 12 s, then a refusal
        ("lissajous:fx=1e300,fy=1", f"between 1 and {MAX_LOBES}"),  # was OverflowError
        ("lissajous:fx=101,fy=1", "between 1 and"),
        ("lissajous:phase=inf", "phase"),
        ("circle:radius=0.01,theta0=inf", "theta0"),  # was a ValueError when drawn
    ],
)
def test_absurd_shape_parameters_are_refused_quickly(spec: str, match: str) -> None:
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=match):
        parse_shape(spec)
    assert time.perf_counter() - t0 < 2.0


def test_lissajous_with_a_large_phase_is_the_reduced_one() -> None:
    # sin(3t + 34102) lost precision: the fit never converged (21 s, then an error)
    t0 = time.perf_counter()
    far, near = lissajous(phase=34102.0), lissajous(phase=34102.0 % (2 * 3.141592653589793))
    assert time.perf_counter() - t0 < 2.0
    assert far.length == pytest.approx(near.length, rel=1e-9)
