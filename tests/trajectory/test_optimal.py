"""Time-optimal path parameterisation: never above a limit, at a limit where it can be."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from scipy.optimize import brentq

from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.report.geometry import fig_profile
from microfab.trajectory.base import Trajectory
from microfab.trajectory.optimal import (
    HighsLP,
    PlanningError,
    TimeOptimalResult,
    time_optimal,
)

STAGE = MachineLimits.seed002_stage()  # seed 002 Table I: 1.5 m/s, 40 m/s², ±0.19 m


# --------------------------------------------------------------------------- test paths
# Small arc-length-parametrised paths with the interface of microfab.geometry.path.Path:
# length, closed, evaluate(s, order) -> [q, q', q'', q'''], corners(), junctions().
class LinePath:
    def __init__(self, p0: tuple[float, float], p1: tuple[float, float]) -> None:
        self.p0 = np.asarray(p0, dtype=float)
        d = np.asarray(p1, dtype=float) - self.p0
        self.length = float(np.linalg.norm(d))
        self.u = d / self.length
        self.closed = False

    def evaluate(self, s: np.ndarray, order: int = 3) -> list[np.ndarray]:
        sv = np.asarray(s, dtype=float)[:, None]
        z = np.zeros((sv.shape[0], 2))
        return [self.p0 + sv * self.u, z + self.u, z, z][: order + 1]

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        return np.array([])

    def junctions(self) -> np.ndarray:
        return np.array([])


class CirclePath:
    """Counter-clockwise from angle 0: q = c + r (cos φ, sin φ), φ = s / r."""

    def __init__(self, r: float, center: tuple[float, float] = (0.0, 0.0)) -> None:
        self.r = r
        self.c = np.asarray(center, dtype=float)
        self.length = 2 * np.pi * r
        self.closed = True

    def evaluate(self, s: np.ndarray, order: int = 3) -> list[np.ndarray]:
        ph = np.asarray(s, dtype=float) / self.r
        cs, sn = np.cos(ph)[:, None], np.sin(ph)[:, None]
        r = self.r
        out = [
            self.c + r * np.hstack([cs, sn]),
            np.hstack([-sn, cs]),
            -np.hstack([cs, sn]) / r,
            np.hstack([sn, -cs]) / r**2,
        ]
        return out[: order + 1]

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        return np.array([])

    def junctions(self) -> np.ndarray:
        return np.array([])


class PolylinePath:
    """Straight edges through the vertices; every vertex with a turn is a corner."""

    def __init__(self, pts: list[tuple[float, float]], closed: bool) -> None:
        p = np.asarray(pts, dtype=float)
        if closed:
            p = np.vstack([p, p[:1]])
        d = np.diff(p, axis=0)
        self.lens = np.linalg.norm(d, axis=1)
        self.dirs = d / self.lens[:, None]
        self.p = p
        self.starts = np.concatenate([[0.0], np.cumsum(self.lens)])
        self.length = float(self.starts[-1])
        self.closed = closed

    def evaluate(self, s: np.ndarray, order: int = 3) -> list[np.ndarray]:
        sv = np.asarray(s, dtype=float)
        i = np.clip(np.searchsorted(self.starts, sv, side="right") - 1, 0, self.lens.size - 1)
        u = (sv - self.starts[i])[:, None]
        z = np.zeros((sv.size, 2))
        return [self.p[i] + u * self.dirs[i], self.dirs[i], z, z][: order + 1]

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        inner = self.starts[1:-1]
        cos = np.sum(self.dirs[:-1] * self.dirs[1:], axis=1)
        out = list(inner[np.arccos(np.clip(cos, -1, 1)) > angle_tol])
        if self.closed and np.arccos(np.clip(self.dirs[-1] @ self.dirs[0], -1, 1)) > angle_tol:
            out.insert(0, 0.0)
        return np.array(out)

    def junctions(self) -> np.ndarray:
        return self.starts[1:-1].copy()


def square(side: float) -> PolylinePath:
    return PolylinePath([(0, 0), (side, 0), (side, side), (0, side)], closed=True)


# --------------------------------------------------------------------------- checks
def fd_check(traj: Trajectory, limits: MachineLimits) -> None:
    """Independent check: finite differences of the samples, the machine at rest around."""
    x = np.asarray(traj.position)
    pad = 4
    xe = np.vstack([np.repeat(x[:1], pad, 0), x, np.repeat(x[-1:], pad, 0)])
    scale = float(np.max(np.abs(x)))
    for order, lim in ((1, limits.velocity), (2, limits.acceleration), (3, limits.jerk)):
        d = np.diff(xe, order, axis=0) / traj.dt**order
        rounding = 2**order * 4 * np.finfo(float).eps * scale / traj.dt**order
        assert np.all(np.abs(d) <= np.asarray(lim) * (1 + 1e-9) + rounding), order
    for name, arr, lim in (
        ("velocity", traj.velocity, limits.velocity),
        ("acceleration", traj.acceleration, limits.acceleration),
        ("jerk", traj.jerk, limits.jerk),
    ):
        assert arr is not None
        assert np.all(np.abs(arr) <= np.asarray(lim) * (1 + 1e-9)), name


def assert_within_limits(res: TimeOptimalResult, limits: MachineLimits) -> None:
    check_trajectory(res.trajectory, limits)
    fd_check(res.trajectory, limits)
    m = res.spline.max_abs()  # exact maxima of the emitted spline, between samples too
    assert np.all(m.velocity <= np.asarray(limits.velocity) * (1 + 1e-9))
    assert np.all(m.acceleration <= np.asarray(limits.acceleration) * (1 + 1e-9))
    assert np.all(m.jerk <= np.asarray(limits.jerk) * (1 + 1e-9))


def segment_utilisation(res: TimeOptimalResult, limits: MachineLimits) -> list[float]:
    """Largest |value| / limit on each stretch between stops, from the sampled trajectory."""
    tr = res.trajectory
    assert tr.s is not None and tr.velocity is not None
    assert tr.acceleration is not None and tr.jerk is not None
    stop_s = np.asarray(res.s)[np.asarray(res.stops)]
    out = []
    for a, b in pairwise(stop_s):
        w = (tr.s > a) & (tr.s < b)
        u = 0.0
        for arr, lim in (
            (tr.velocity, limits.velocity),
            (tr.acceleration, limits.acceleration),
            (tr.jerk, limits.jerk),
        ):
            u = max(u, float(np.max(np.abs(arr[w]) / np.asarray(lim))))
        out.append(u)
    return out


def scurve_time(length: float, v: float, a: float, j: float) -> float:
    """Rest-to-rest time of the jerk-limited (7-phase) point-to-point profile."""

    def ramp(vp: float) -> tuple[float, float]:  # time and distance from rest to speed vp
        if vp * j >= a * a:  # the acceleration limit is reached
            t = vp / a + a / j
        else:
            t = 2 * np.sqrt(vp / j)
        return t, 0.5 * vp * t

    t_a, d_a = ramp(v)
    if length >= 2 * d_a:
        return 2 * t_a + (length - 2 * d_a) / v
    vp = brentq(lambda u: 2 * ramp(u)[1] - length, 1e-12, v)
    return 2 * ramp(vp)[0]


def path_limits(direction: np.ndarray, limits: MachineLimits, margin: float) -> tuple[float, ...]:
    """Path speed, acceleration and jerk limits along a fixed unit direction."""
    u = np.abs(direction)
    out = []
    for lim in (limits.velocity, limits.acceleration, limits.jerk):
        with np.errstate(divide="ignore"):
            out.append((1 - margin) * float(np.min(np.asarray(lim) / u)))
    return tuple(out)


# --------------------------------------------------------------------------- tests
CASES = [
    ("line", lambda: LinePath((-0.05, -0.02), (0.06, 0.03))),
    ("circle", lambda: CirclePath(0.01)),
    ("square", lambda: square(0.02)),
]


@pytest.mark.parametrize("jerk", [None, 2e4], ids=["va", "jerk"])
@pytest.mark.parametrize(("name", "make"), CASES, ids=[c[0] for c in CASES])
def test_never_exceeds_a_limit_and_reaches_one_per_segment(name, make, jerk) -> None:
    limits = STAGE if jerk is None else STAGE.with_jerk(jerk)
    margin = 0.01
    res = time_optimal(make(), limits, n_grid=300, margin=margin)
    assert_within_limits(res, limits)
    # The planner aims at (1 - margin) * limit; where the spline overshoots the discrete
    # profile it shrinks the bound locally to (1 - margin) * limit / overshoot, so the peak
    # of a segment can land a little below the planned value (and the 10 kHz samples can
    # miss the exact peak): 0.03 covers both.
    util = segment_utilisation(res, limits)
    assert len(util) == len(res.segments)
    assert min(util) >= 1 - margin - 0.03
    assert all(seg.utilisation <= 1 + 1e-9 for seg in res.segments)


@pytest.mark.parametrize("jerk", [None, 2e4], ids=["va", "jerk"])
def test_stops_at_corners_and_ends(jerk) -> None:
    limits = STAGE if jerk is None else STAGE.with_jerk(jerk)
    path = PolylinePath([(0, 0), (0.02, 0), (0.03, 0.015), (0.0, 0.02)], closed=False)
    res = time_optimal(path, limits, n_grid=300)
    stop_s = np.asarray(res.s)[np.asarray(res.stops)]
    np.testing.assert_allclose(stop_s, [0.0, *path.corners(), path.length], atol=1e-12)
    t_stop = np.asarray(res.t_knots)[np.asarray(res.stops)]
    v = res.spline.evaluate(t_stop, 1)
    np.testing.assert_allclose(v, 0.0, atol=1e-9)
    assert np.all(np.asarray(res.sdot)[np.asarray(res.stops)] == 0.0)
    if jerk is not None:  # a jerk-limited machine also stops accelerating there
        np.testing.assert_allclose(res.spline.evaluate(t_stop, 2), 0.0, atol=1e-6)
    # the machine passes through the corners themselves
    corners = path.evaluate(path.corners(), 0)[0]
    np.testing.assert_allclose(res.spline.evaluate(t_stop[1:-1], 0), corners, atol=1e-12)
    assert_within_limits(res, limits)


@pytest.mark.parametrize("length", [0.12, 0.02], ids=["trapezoid", "triangle"])
def test_straight_line_bang_bang_time(length) -> None:
    u = np.array([np.cos(0.4), np.sin(0.4)])
    margin = 0.01
    path = LinePath((-0.05, -0.03), tuple(np.array([-0.05, -0.03]) + length * u))
    res = time_optimal(path, STAGE, n_grid=400, margin=margin)
    v, a, _ = path_limits(u, STAGE, margin)
    if length > v * v / a:  # trapezoid: accelerate, cruise, brake
        expected = length / v + v / a
    else:  # triangle: the top speed is not reached
        expected = 2 * np.sqrt(length / a)
    assert res.duration == pytest.approx(expected, rel=5e-3)
    assert_within_limits(res, STAGE)


@pytest.mark.parametrize(
    ("length", "jerk"), [(0.1, 2e4), (0.02, 2e3)], ids=["a-reached", "jerk-bound"]
)
def test_straight_line_jerk_limited_s_curve_time(length, jerk) -> None:
    limits = STAGE.with_jerk(jerk)
    u = np.array([np.cos(0.3), np.sin(0.3)])
    margin = 0.01
    path = LinePath((-0.05, -0.02), tuple(np.array([-0.05, -0.02]) + length * u))
    res = time_optimal(path, limits, n_grid=300, margin=margin)
    expected = scurve_time(length, *path_limits(u, limits, margin))
    assert res.duration == pytest.approx(expected, rel=2e-2)
    assert_within_limits(res, limits)


def test_circle_reaches_the_centripetal_limit() -> None:
    r, margin = 0.01, 0.01
    limits = MachineLimits(
        workspace=((-0.1, 0.1), (-0.1, 0.1)), velocity=(1.0, 1.0), acceleration=(10.0, 10.0)
    )
    path = CirclePath(r)
    res = time_optimal(path, limits, n_grid=401, margin=margin)
    tr = res.trajectory
    assert tr.s is not None and tr.velocity is not None and tr.acceleration is not None
    # halfway round (φ = π) the normal is the x axis: |a_x| = v²/r <= a_x limit
    i = int(np.argmin(np.abs(tr.s - path.length / 2)))
    speed = float(np.linalg.norm(tr.velocity[i]))
    v_c = np.sqrt(limits.acceleration[0] * r)
    assert speed <= v_c * (1 + 1e-9)
    assert speed == pytest.approx(np.sqrt(1 - margin) * v_c, rel=0.02)
    assert abs(tr.acceleration[i, 0]) == pytest.approx((1 - margin) * 10.0, rel=0.03)
    assert_within_limits(res, limits)


def test_matches_toppra_without_jerk() -> None:
    toppra = pytest.importorskip("toppra")
    import toppra.algorithm as algo
    import toppra.constraint as constraint
    from toppra.interpolator import AbstractGeometricPath

    class Wrapped(AbstractGeometricPath):  # the same exact path, for TOPP-RA
        def __init__(self, p: CirclePath) -> None:
            self.p = p

        def __call__(self, s: np.ndarray, order: int = 0) -> np.ndarray:
            return self.p.evaluate(np.atleast_1d(np.asarray(s, dtype=float)), 2)[order]

        @property
        def dof(self) -> int:
            return 2

        @property
        def path_interval(self) -> np.ndarray:
            return np.array([0.0, self.p.length])

    margin, n = 0.01, 400
    for path in (CirclePath(0.01), CirclePath(0.002, center=(0.01, 0.0))):
        res = time_optimal(path, STAGE, n_grid=n, margin=margin)
        v = (1 - margin) * np.asarray(STAGE.velocity)
        a = (1 - margin) * np.asarray(STAGE.acceleration)
        inst = algo.TOPPRA(
            [
                constraint.JointVelocityConstraint(v),
                constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
            ],
            Wrapped(path),
            gridpoints=np.linspace(0.0, path.length, n),
            solver_wrapper="seidel",
            parametrizer="ParametrizeConstAccel",
        )
        ref = inst.compute_trajectory(0.0, 0.0)
        assert ref is not None
        assert res.duration == pytest.approx(ref.duration, rel=2e-2)
    assert toppra is not None


def test_feed_caps_the_path_speed() -> None:
    feed = 0.3
    res = time_optimal(LinePath((0, 0), (0.1, 0.0)), STAGE, n_grid=200, feed=feed)
    tr = res.trajectory
    assert tr.velocity is not None
    speed = np.linalg.norm(tr.velocity, axis=1)
    assert speed.max() <= feed * (1 + 1e-9)
    assert speed.max() >= 0.98 * feed
    assert res.segments[0].active == "feed"


def test_solver_is_swappable() -> None:
    class Counting(HighsLP):
        calls = 0

        def solve(self, c, A_ub, b_ub, bounds):  # type: ignore[no-untyped-def]
            type(self).calls += 1
            return super().solve(c, A_ub, b_ub, bounds)

    path = square(0.01)
    res = time_optimal(path, STAGE.with_jerk(2e4), n_grid=120, solver=Counting())
    assert Counting.calls == res.iterations > 1

    class Broken:
        def solve(self, c, A_ub, b_ub, bounds):  # type: ignore[no-untyped-def]
            raise PlanningError("no LP today")

    with pytest.raises(PlanningError, match="no LP today"):
        time_optimal(path, STAGE, n_grid=120, solver=Broken())


def test_bad_input_is_refused() -> None:
    path = LinePath((0, 0), (0.01, 0))
    with pytest.raises(ValueError, match="n_grid"):
        time_optimal(path, STAGE, n_grid=5)
    with pytest.raises(ValueError, match=r"sample_rate_hz .* Hz"):
        time_optimal(path, STAGE, sample_rate_hz=0.0)
    with pytest.raises(ValueError, match=r"feed .* m/s"):
        time_optimal(path, STAGE, feed=-1.0)
    with pytest.raises(ValueError, match="margin"):
        time_optimal(path, STAGE, margin=0.7)
    with pytest.raises(ValueError, match="MachineLimits"):
        time_optimal(path, {"x": 1.0})  # type: ignore[arg-type]
    three = MachineLimits(
        workspace=((-1, 1),) * 3, velocity=(1,) * 3, acceleration=(1,) * 3, axes=("x", "y", "z")
    )
    with pytest.raises(ValueError, match="axes"):
        time_optimal(path, three)
    with pytest.raises(LimitViolation, match="workspace"):
        time_optimal(LinePath((0, 0), (0.5, 0)), STAGE, n_grid=50)


def test_result_fields_and_plot() -> None:
    from matplotlib.figure import Figure

    path = square(0.01)
    res = time_optimal(path, STAGE, n_grid=100)
    assert res.duration == pytest.approx(res.spline.duration)
    assert res.duration == pytest.approx(float(res.t_knots[-1]))
    assert np.all(np.diff(res.t_knots) > 0)
    assert res.trajectory.s is not None
    assert res.trajectory.s[-1] == pytest.approx(path.length)
    assert len(res.segments) == 4
    assert res.utilisation.shape == (4,)
    fig = fig_profile(res.trajectory, STAGE, knots=(res.s, res.sdot))
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 2


def test_shapes_from_geometry_module() -> None:
    shapes = pytest.importorskip("microfab.geometry.shapes")
    limits = STAGE.with_jerk(5e4)
    for path in (
        shapes.rectangle(0.02, 0.015, corner_radius=0.003),
        shapes.spiral(0.001, 0.0, 4 * np.pi),
    ):
        res = time_optimal(path, limits, n_grid=300)
        assert_within_limits(res, limits)
        assert min(segment_utilisation(res, limits)) >= 1 - 0.01 - 0.03


def test_jerk_limit_on_one_axis_only() -> None:
    limits = STAGE.with_jerk((2e4, float("inf")))
    res = time_optimal(square(0.02), limits, n_grid=300)
    assert_within_limits(res, limits)
    assert res.meta["jerk_limited"] is True
    assert min(segment_utilisation(res, limits)) >= 1 - 0.01 - 0.03


@pytest.mark.filterwarnings("error")
def test_limits_too_small_to_time_a_motion_are_a_planning_error() -> None:
    # vmax = 1e-308 m/s: the path speed underflowed to 0 and every time became inf,
    # with divide-by-zero warnings printed before the refusal
    tiny = MachineLimits(
        workspace=STAGE.workspace, velocity=(1e-308,) * 2, acceleration=(40.0,) * 2
    )
    with pytest.raises(PlanningError, match="allow no motion that can be timed"):
        time_optimal(LinePath((0.0, 0.0), (0.01, 0.0)), tiny, n_grid=20)


def test_start_time_with_a_jerk_so_large_the_ramp_rounds_away() -> None:
    """σ of 1e12-1e20: the root lies at the constant-acceleration end, where the excess
    rounds to zero or below (brentq refused 'f(a) and f(b) must have different signs')."""
    from microfab.trajectory.optimal import _start_time

    for sigma in (1e12, 1e16, 1e20):
        t, tau = _start_time(1e-4, 0.1, sigma)
        assert t == pytest.approx(2e-3, rel=1e-6) and 0 <= tau < 1e-9
