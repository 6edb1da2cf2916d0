"""Seed 004 reference: time law, laps, spline accuracy, limit refusals."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation, MachineLimits
from microfab.geometry.path import Path
from microfab.geometry.shapes import circle, rectangle
from microfab.trajectory.contour_laps import (
    ContourMotion,
    check_force,
    check_reference,
    contour_reference,
)


def test_laps_run_at_constant_speed_on_the_exact_circle():
    R = 30e-6
    ref = contour_reference(circle(R), ContourMotion(speed_m_s=1e-3, laps=2))
    traj = ref.trajectory
    for i in range(2):
        lap = ref.lap(i)
        v = np.hypot(*traj.velocity[lap].T)
        # the spline's C² joins with the ramps leave 2e-5 at a lap's ends, 1e-8 inside
        np.testing.assert_allclose(v, 1e-3, rtol=5e-5)
        np.testing.assert_allclose(v[200:-200], 1e-3, rtol=1e-7)
        r = np.hypot(*traj.position[lap].T)
        assert np.max(np.abs(r - R)) < 1e-11  # the spline is on the circle to < 10 pm
    # lap 1 starts on the contour's start point, at full speed
    np.testing.assert_allclose(traj.position[ref.lap_starts[0]], circle(R).start, atol=2e-9)
    # at rest at both ends
    assert np.all(traj.velocity[0] == 0) and np.all(traj.velocity[-1] == 0)


def test_speed_ramp_respects_half_the_acceleration_limit_along_the_path():
    ref = contour_reference(circle(5e-3), ContourMotion(speed_m_s=0.05, laps=1))
    a = ref.trajectory.acceleration
    v = ref.trajectory.velocity
    speed = np.hypot(*v.T)
    tang = np.einsum("ij,ij->i", a, v) / np.maximum(speed, 1e-30)
    assert np.max(np.abs(tang)) <= 0.5 * 5.0 * 1.01


def test_open_paths_are_refused():
    with pytest.raises(ValueError, match="open"):
        contour_reference(Path.polyline([[0, 0], [1e-4, 0], [1e-4, 1e-4]]))


def test_limits_refuse_speed_and_force_naming_axis_time_value_limit():
    limits = MachineLimits.seed004_stage()
    fast = contour_reference(circle(10e-3), ContourMotion(speed_m_s=0.12, laps=1))
    with pytest.raises(LimitViolation, match=r"axis [xy]: .*velocity"):
        check_reference(fast, limits, (1.2, 0.6))
    # 0.05 m/s on a 1 mm radius: v²/R = 2.5 m/s² (within 5) but 3 kg x 2.5 = 7.5 N RMS > 3 N
    ok = contour_reference(circle(1e-3), ContourMotion(speed_m_s=0.05, laps=3))
    with pytest.raises(LimitViolation, match=r"RMS force .* continuous force 3 N"):
        check_reference(ok, limits, (3.0, 3.0))
    check_reference(ok, limits, (1.2, 0.6))  # the seed's masses pass
    a = np.zeros((10, 2))
    a[4, 1] = 30.0
    with pytest.raises(LimitViolation, match=r"axis y: force 18 N .* t = 0.0004 s .* 12 N"):
        check_force(a, (1.2, 0.6), 1e-4)


def test_a_sharp_corner_is_refused_at_speed():
    sq = rectangle(2e-3, 2e-3)
    with pytest.raises(LimitViolation, match="acceleration"):
        check_reference(
            contour_reference(sq, ContourMotion(speed_m_s=0.05, laps=1)),
            MachineLimits.seed004_stage(),
            (1.2, 0.6),
        )


def test_knots_are_counted_before_they_are_made() -> None:
    """Issue 32: knot_spacing_um = 1e-9 asked for a 149 GiB array."""
    from microfab.trajectory.contour_laps import MAX_KNOTS

    with pytest.raises(ValueError, match=r"spline knots over the laps and ramps; the most"):
        contour_reference(circle(1e-3), ContourMotion(knot_spacing_m=1e-15))
    assert MAX_KNOTS == 1_000_000


# ------------------------------------------------ corners by slowing down (profile="limited")
STAR = "star:points=5,radius=1.5e-3"  # 3 mm across, ten sharp corners, no fillets


def test_a_sharp_star_at_20_mm_s_is_refused_at_constant_speed() -> None:
    from microfab.core.limits import LimitViolation
    from microfab.trajectory.contour_laps import contour_path

    path = contour_path(STAR)
    motion = ContourMotion(speed_m_s=0.02, laps=2)
    with pytest.raises(LimitViolation, match="acceleration"):
        check_reference(contour_reference(path, motion), MachineLimits.seed004_stage(), (1.2, 0.6))


def test_a_sharp_star_at_20_mm_s_runs_limited_and_slows_only_at_its_corners() -> None:
    from microfab.trajectory.contour_laps import contour_path

    path = contour_path(STAR)
    ref = contour_reference(path, ContourMotion(speed_m_s=0.02, laps=2, profile="limited"))
    check_reference(ref, MachineLimits.seed004_stage(), (1.2, 0.6))  # the seed's masses
    tr = ref.trajectory
    s = np.asarray(tr.s)
    for i in range(2):  # each lap covers the contour once
        lap = s[ref.lap(i)]
        assert lap[0] == pytest.approx(i * path.length, abs=1e-6)
        assert lap[-1] == pytest.approx((i + 1) * path.length, abs=2e-6)
    v = np.hypot(*np.asarray(tr.velocity).T)
    assert v.max() <= 0.02 * 1.05  # the speed is a cap (the spline's overshoot: < 5 %)
    # it keeps the speed between the corners and slows at each of the ten
    slow = ref.slowdowns()
    assert len(slow) == 10
    corners = np.sort(path.corners(1e-3))
    for d in slow:
        assert np.min(np.abs(corners - d.at_m)) < 0.05 * path.length / 10
        assert d.speed_m_s < 0.2 * 0.02
    # each stretch names its one corner, and every corner is named once
    assert [d.corners for d in slow] == [(k,) for k in range(1, 11)]
    assert slow[0].from_rest and not any(d.from_rest for d in slow[1:])
    assert np.mean(v[ref.lap(1)] > 0.97 * 0.02) > 0.2


def test_a_circle_limited_keeps_its_speed_after_the_start() -> None:
    from microfab.trajectory.contour_laps import contour_path

    path = contour_path("circle:radius=1e-3")
    ref = contour_reference(path, ContourMotion(speed_m_s=0.005, laps=2, profile="limited"))
    check_reference(ref, MachineLimits.seed004_stage(), (1.2, 0.6))  # the seed's masses
    v = np.hypot(*np.asarray(ref.trajectory.velocity)[ref.lap(1)].T)
    assert np.mean(np.abs(v - 0.005) < 1e-4) > 0.9  # at speed on lap 2 but its slow-down


def test_auto_keeps_the_seed_s_constant_speed_where_it_is_within_the_limits() -> None:
    from microfab.trajectory.contour_laps import contour_path

    circle_ = contour_path("circle:radius=30e-6")
    ref = contour_reference(circle_, ContourMotion(speed_m_s=1e-3, laps=2, profile="auto"))
    assert ref.motion.profile == "constant"
    same = contour_reference(circle_, ContourMotion(speed_m_s=1e-3, laps=2))
    np.testing.assert_array_equal(ref.trajectory.position, same.trajectory.position)
    star_ = contour_path(STAR)
    ref = contour_reference(star_, ContourMotion(speed_m_s=0.02, laps=2, profile="auto"))
    assert ref.motion.profile == "limited"


def test_a_limited_plan_given_the_masses_keeps_the_continuous_force() -> None:
    """A 30 µm seven-point star at 20 mm/s is all corners: planned at 5 m/s² its RMS force
    is 5.4 N against Table I's 3 N continuous; with the masses the plan lowers its
    acceleration until it holds."""
    from microfab.trajectory.contour_laps import contour_path

    path = contour_path("star:points=7,radius=30e-6")
    motion = ContourMotion(speed_m_s=0.02, laps=2, profile="limited")
    masses = (1.2, 0.6)
    with pytest.raises(LimitViolation, match="continuous force"):
        check_reference(contour_reference(path, motion), MachineLimits.seed004_stage(), masses)
    ref = contour_reference(path, motion, masses)
    check_reference(ref, MachineLimits.seed004_stage(), masses)
    v = np.hypot(*np.asarray(ref.trajectory.velocity).T)
    assert v.max() < 0.5 * 0.02 and ref.slowdowns()  # it never reaches the speed asked


def test_a_sharp_hexagon_at_50_mm_s_names_each_of_its_six_corners_and_the_force_cut():
    """Issue 45: a regular hexagon of 1 mm sides at 50 mm/s. Its RMS force at 5 m/s² is
    4.53 N on x (the twin's 1.54 kg) against Table I's 3 N, so the plan lowers the
    acceleration to 2.08 m/s²; then corners 1 mm apart are closer than the stage needs to
    get back to 45 mm/s, and two slow-downs each cover two corners: every corner is named
    in exactly one slow-down, and the lowered acceleration is stated."""
    from microfab.trajectory.contour_laps import CONTINUOUS_FORCE_N, contour_path

    path = contour_path("polygon:n_sides=6,radius=1e-3")
    masses = (1.54, 0.88)  # the stage twin's true masses (data/lmw_stage.toml)
    ref = contour_reference(path, ContourMotion(speed_m_s=0.05, laps=1, profile="limited"), masses)
    check_reference(ref, MachineLimits.seed004_stage(), masses)
    slow = ref.slowdowns()
    named = [c for d in slow for c in d.corners]
    assert sorted(named) == [1, 2, 3, 4, 5, 6]  # each corner once
    assert len(slow) < 6 and any(len(d.corners) == 2 for d in slow)  # measured 4: 1, 2+3, 4, 5+6
    np.testing.assert_allclose(ref.corner_positions(), np.arange(6) * 1e-3, atol=1e-12)
    for d in slow:  # the slowest point of a stretch is one of its corners
        at = ref.corner_positions()[np.array(d.corners) - 1]
        assert np.min(np.abs(at - d.at_m)) < 1e-6
    low = ref.acceleration_lowered
    assert low is not None and low.axis == "x" and low.asked_m_s2 == 5.0
    assert low.asked_rms_force_n > CONTINUOUS_FORCE_N >= low.used_rms_force_n  # 4.53 / 2.37 N
    assert 1.0 < low.used_m_s2 < 0.5 * low.asked_m_s2  # measured 2.08 m/s²
    # without masses nothing is lowered, and the constant profile never slows
    assert contour_reference(path, ContourMotion(speed_m_s=0.05, laps=1, profile="limited")
                             ).acceleration_lowered is None  # fmt: skip
    assert contour_reference(circle(1e-3), ContourMotion(speed_m_s=1e-3, laps=1)).slowdowns() == []
