"""Constant path speed from rest to rest within the limits (`trajectory.cruise`)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import MachineLimits, check_trajectory
from microfab.geometry.airfoil import airfoil_path
from microfab.geometry.shapes import circle, rectangle, regular_polygon
from microfab.geometry.text import text_layer
from microfab.trajectory.cruise import cruise

LIMITS = MachineLimits.seed002_stage()  # seed 002 Table I: 1.5 m/s, 40 m/s²
FS = 10_000.0


def _drawings() -> dict[str, object]:
    out = {
        "rounded rectangle": rectangle(0.05, 0.03, corner_radius=0.005),
        "airfoil e344": airfoil_path("e344", chord=0.1),
    }
    for i, c in enumerate(text_layer("Rb8", height=0.02).contours):
        out[f"letter contour {i}"] = c
    return out


DRAWINGS = _drawings()


@pytest.mark.parametrize("name", list(DRAWINGS))
@pytest.mark.parametrize("speed", [0.02, 0.3, 3.0])
def test_every_drawing_runs_within_the_limits(name: str, speed: float) -> None:
    path = DRAWINGS[name]
    traj = cruise(path, LIMITS, speed=speed, sample_rate_hz=FS)
    check_trajectory(traj, LIMITS)  # raises on any violation
    assert traj.at_rest
    np.testing.assert_allclose(traj.velocity[[0, -1]], 0.0, atol=1e-12)
    speeds = np.linalg.norm(traj.velocity, axis=1)
    assert speeds.max() <= speed * (1 + 1e-9)
    assert traj.duration >= path.length / speed
    np.testing.assert_allclose(traj.position[-1], path.point(np.array([path.length]))[0], atol=1e-9)


def test_holds_the_speed_on_a_long_smooth_path_and_ramps_at_the_limit() -> None:
    path = circle(0.05)
    traj = cruise(path, LIMITS, speed=0.2, sample_rate_hz=FS)
    assert traj.meta["share_at_speed"] > 0.95
    assert traj.meta["corner_stops"] == 0
    # ramp from rest: half the acceleration limit is tangential, v = sqrt(2 a s)
    t_ramp = 0.2 / (0.5 * 40.0)
    k = int(0.5 * t_ramp * FS)
    assert np.linalg.norm(traj.velocity[k]) == pytest.approx(20.0 * k / FS, rel=0.02)


def test_stops_at_every_corner() -> None:
    path = rectangle(0.02, 0.01)  # four sharp corners, the start mid-edge
    traj = cruise(path, LIMITS, speed=0.1, sample_rate_hz=FS)
    assert traj.meta["corner_stops"] == 4
    for sc in path.corners():
        k = int(np.argmin(np.abs(traj.s - sc)))
        assert np.linalg.norm(traj.velocity[k]) < 0.01


def test_slows_where_the_curvature_needs_it() -> None:
    # a 1 mm circle at 1 m/s needs 1000 m/s². Per axis the centripetal share is
    # v² |q''_i| <= 20 m/s², |q''_i| <= 1/r: at least sqrt(20 * 1e-3) = 0.14 m/s, at most
    # (curvature on a diagonal, |q''_i| = 1/(r sqrt 2)) 0.168 m/s
    traj = cruise(circle(1e-3), LIMITS, speed=1.0, sample_rate_hz=FS)
    top = np.linalg.norm(traj.velocity, axis=1).max()
    assert np.sqrt(20.0 * 1e-3) * 0.999 <= top <= np.sqrt(20.0 * 1e-3 * np.sqrt(2)) * 1.001
    check_trajectory(traj, LIMITS)


def test_refuses_bad_arguments() -> None:
    with pytest.raises(ValueError, match="speed"):
        cruise(circle(0.01), LIMITS, speed=0.0, sample_rate_hz=FS)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        cruise(circle(0.01), LIMITS, speed=0.1, sample_rate_hz=-1.0)


@pytest.mark.parametrize("turn", [0.1 * k for k in (7, 14, 25)])
def test_a_corner_within_rounding_of_a_grid_node_keeps_the_time_finite(turn: float) -> None:
    # these turns put a corner of the hexagon ~1 ulp from a uniform grid node; both
    # nodes had zero speed and the interval between them took ~1e283 s
    path = regular_polygon(6, 0.03).rotated(turn)
    path = path.translated(-path.start)
    limits = MachineLimits(workspace=LIMITS.workspace, velocity=(1.5, 1.5), acceleration=(5.0, 5.0))
    traj = cruise(path, limits, speed=0.5, sample_rate_hz=FS)
    check_trajectory(traj, limits)
    # six sides from rest to rest at 2.5 m/s² tangential: each at most 2 sqrt(L / a)
    assert traj.duration < 6 * 2 * np.sqrt(0.03 / 2.5) + 0.01
    assert traj.meta["corner_stops"] == 5


@pytest.mark.parametrize("radius", [0.15, 0.05, 0.18])
@pytest.mark.parametrize("speed", [1.5, 2.0, 1.4999])
def test_asked_for_the_limit_or_above_it_stays_within_it_with_no_allowance(
    radius: float, speed: float
) -> None:
    """Issue 32 class 7: a circle at (or above) 1.5 m/s was refused by the guard at 1.5 m/s:
    the bounds held at the grid nodes, an axis' share of the tangent grew between them."""
    traj = cruise(circle(radius), LIMITS, speed=speed, sample_rate_hz=FS)
    check_trajectory(traj, LIMITS, rtol=0.0)  # no rounding allowance on the analytic values
    vmax = np.max(np.abs(traj.velocity), axis=0)
    assert np.all(vmax <= np.asarray(LIMITS.velocity))
    if radius == 0.15:  # where the velocity limit, not the curvature, sets the speed
        assert np.max(vmax) > 0.999 * min(speed, 1.5)  # slowed by a hair, not by a factor


def test_corner_stops_closer_than_the_grid_spacing_are_planned() -> None:
    """A long run then a zigzag of 10 µm teeth: on a 0.5 mm grid the stops sit next to
    each other, and an interval from rest to rest had an infinite time (numpy then refused
    'Maximum allowed size exceeded'); a node between two stops plans it."""
    from microfab.geometry.path import Path

    teeth = [(0.05 + 1e-5 * k, 1e-5 * (k % 2)) for k in range(1, 201)]
    path = Path.polyline([(0.0, 0.0), (0.05, 0.0), *teeth])
    limits = MachineLimits.seed002_stage()
    traj = cruise(path, limits, speed=0.05, sample_rate_hz=2000.0)
    check_trajectory(traj, limits)
    assert np.isfinite(traj.duration) and traj.meta["corner_stops"] >= 150
    assert traj.s is not None and traj.s[-1] == pytest.approx(path.length, rel=1e-9)


def test_a_velocity_limit_far_below_the_speed_is_sized_before_planning() -> None:
    """The sample budget uses the top speed the limits allow, not the asked speed (make
    fuzz: --speed 0.05 with --vmax 1e-6 planned 8e7 samples for minutes)."""
    import dataclasses

    slow = dataclasses.replace(LIMITS, velocity=(1e-6, 1e-6))
    with pytest.raises(ValueError, match=r"at 1\.41421e-06 m/s .* samples a reference may"):
        cruise(circle(0.005), slow, speed=0.05, sample_rate_hz=2000.0)
