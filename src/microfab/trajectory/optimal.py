"""Time-optimal traversal of a path under per-axis velocity, acceleration and jerk limits.

Method
------
The path ``q(s)`` (arc length ``s``, ``|q'| = 1``) is traversed with the path speed
``ṡ(s)``; the decision variables are ``x_k = ṡ²`` on a grid ``s_0 = 0 < … < s_{N-1} = L``
(uniform, with the path's corners and segment junctions inserted as nodes; uniform
nodes closer than ``Δs/4`` to an inserted one are dropped, and every stretch between
two stops gets at least 4 intervals).

* **Stops.** ``x = 0`` at both ends and at every corner: a jump of the tangent direction
  needs zero speed under a finite acceleration. Between two stops lies a *segment*.
* **Velocity.** ``|q'_i| ṡ ≤ v_i``  ⇒  ``x_k ≤ (v_i / |q'_i(s_k)|)²``; an optional path
  speed cap ``feed`` gives ``x_k ≤ feed²``.
* **Acceleration.** ``ẍ_i = q'_i s̈ + q''_i ṡ²`` with ``s̈ = x'/2``. Taking ``s̈``
  constant on each interval, ``x' = (x_{k+1} - x_k) / Δs_k``; the constraint
  ``|q'_i x'/2 + q''_i x| ≤ a_i`` is imposed at both ends of every interval (path terms
  taken just inside the interval, so a curvature jump at a node is seen from both
  sides). It is linear in ``x``.
* **Jerk.** ``j_i = q'_i s⃛ + 3 q''_i ṡ s̈ + q'''_i ṡ³`` and ``s⃛ = ṡ x''/2`` give
  ``j_i = ṡ (q'_i x''/2 + 1.5 q''_i x' + q'''_i x)``, so at every node between stops
  ``|q'_i x''/2 + 1.5 q''_i x' + q'''_i x| ≤ j_i / √x`` with three-point (non-uniform)
  differences for ``x'`` and ``x''``. The right side is convex in ``x``, so its tangent at
  the previous iterate ``x̄``, ``j_i (3 / (2√x̄) - x / (2 x̄^{3/2}))``, lies below it:
  imposing the tangent is a convex *restriction* and keeps every iterate feasible for
  the (discrete) jerk constraint. Two local additions:

  - a jump ``Δ`` of ``q''`` at a junction (line → arc) is a jump of the normal
    acceleration, i.e. an infinite jerk at any non-zero speed; the C² reference spreads
    it over about one interval, so ``0.634 Δ / Δs`` is added to ``q'''`` at the
    junction's node and its neighbours (see :func:`_build_grid`). The speed at such a
    junction therefore depends on the grid (it tends to zero as ``Δs → 0``, as it must);
  - leaving a stop at constant path jerk ``σ`` (``s = σt³/6``) reaches ``ṡ`` at ``Δs``
    with ``σ = (2/9) ṡ³ / Δs²``, which caps the first node next to a stop at
    ``x ≤ (4.5 j_i Δs² / |q'_i|)^{2/3}``.
* **Objective.** The traversal time ``T = Σ 2Δs_k / (√x_k + √x_{k+1})`` (constant
  ``s̈`` per interval) decreases in every ``x_k``. Without a jerk limit one LP maximising
  a positively weighted sum of ``x`` (each node's share of the length) solves the
  problem: the feasible set is closed under the element-wise maximum, hence has a
  greatest element, wherever each acceleration row has one positive coefficient
  (``|q''_i| Δs < |q'_i| / 2``; on a curve, near a point where an axis' tangent
  component vanishes, a row may have two, and the LP then weighs the nodes against each
  other). With a jerk limit, a
  sequential LP minimises the linearisation of ``T`` at ``x̄`` under the tangent
  constraints, then does an exact line search on the convex ``T`` between ``x̄`` and the
  LP solution (both inside the LP's polytope, hence the whole segment), until ``T``
  improves by less than ``1e-4`` relative or ``max_iter`` LPs. The start is the
  velocity/acceleration optimum scaled by the largest ``c ≤ 1`` that makes it
  jerk-feasible (``x → c x`` scales the acceleration terms by ``c``, the jerk by
  ``c^{3/2}``); a failing LP ends the iteration at the last feasible iterate.
* **Reference.** Knot times from ``x``: without a jerk limit ``Δt_k = 2Δs_k / (√x_k +
  √x_{k+1})`` (constant ``s̈``, exact for bang-bang profiles); with one, Simpson's rule on
  ``1/ṡ`` with ``x`` at the interval midpoint from the cubic through the four nodes
  around it, and, next to a stop, a jerk ramp followed by constant acceleration
  (:func:`_start_time`). The grid points ``q(s_k)`` at the times ``t_k`` are then
  interpolated by seed 004's time-based cubic spline (seed 004 eq. (1),
  :class:`~microfab.trajectory.spline.TimeSpline`), one spline per segment, at rest at
  its stops (``bc="clamped"``: zero velocity; with a jerk limit ``bc="rest"``: zero
  velocity *and* acceleration, with the extra break where the jerk ramp ends), and the
  segment splines are concatenated: the machine stands still exactly at every stop.
* **Verification.** The spline is not the discrete profile: it overshoots the
  discretised constraints, most where the profile switches (bang-bang acceleration or
  jerk). Its exact per-piece maxima are compared with the limits; where a limit is
  exceeded by ``r = actual / limit > 1``, the bound of that constraint on the offending
  interval and its neighbours is multiplied by ``max((1 - margin) / r, 1/2)`` and the
  problem is solved again, for at most ``max_rounds`` rounds. Whatever still exceeds
  after the last round is removed by stretching that segment's time by
  ``max(r_v, r_a^{1/2}, r_j^{1/3})``, which scales velocity, acceleration and jerk
  exactly. The spline is then sampled at ``sample_rate_hz`` and must pass
  :func:`~microfab.core.limits.check_trajectory` (workspace, analytic values and
  finite differences of the samples), else :class:`PlanningError` is raised.
* **Margin.** The LP plans with ``(1 - margin) · limit`` for every limit (velocity,
  acceleration, jerk and feed), so the spline has room to overshoot the discrete profile
  slightly; the emitted trajectory never exceeds the machine limits themselves. ``feed``
  is a process setting, not a machine limit: the spline's path speed is not verified
  against it beyond this margin.

The LP solver is swappable: any object with ``solve(c, A_ub, b_ub, bounds) -> x``
(:class:`HighsLP`, SciPy's HiGHS, by default). A solver whose ``solve`` also takes a
keyword ``x0`` receives a starting point for the velocity/acceleration LP: its greatest
element, found directly by a backward and a forward pass over the grid (each
acceleration row bounds one node by an increasing function of its neighbour, the way
TOPP-RA computes its controllable sets). :class:`HighsLP` keeps that LP's HiGHS model
between the verification rounds, which change only some bounds, and hot-starts from the
last basis (:class:`~microfab.trajectory.highs.HighsSession`); the answer is HiGHS's
optimal vertex either way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.core.validate import check_in_range, check_int, check_nonnegative, check_positive
from microfab.trajectory.base import Trajectory
from microfab.trajectory.optimal_grid import _MIN_INTERVALS as _MIN_INTERVALS
from microfab.trajectory.optimal_grid import PathLike, _build_grid, _Grid
from microfab.trajectory.optimal_grid import _acc_operator as _acc_operator
from microfab.trajectory.optimal_grid import _greatest_va as _greatest_va
from microfab.trajectory.optimal_grid import _jerk_operator as _jerk_operator
from microfab.trajectory.optimal_grid import _max_first as _max_first
from microfab.trajectory.optimal_grid import _midpoint_cubic as _midpoint_cubic
from microfab.trajectory.optimal_grid import _start_time as _start_time
from microfab.trajectory.optimal_grid import _travel_time as _travel_time
from microfab.trajectory.optimal_grid import _va_vertex as _va_vertex
from microfab.trajectory.optimal_problem import _TIME_RTOL as _TIME_RTOL
from microfab.trajectory.optimal_problem import HighsLP, LPSolver, PlanningError, _Problem
from microfab.trajectory.optimal_problem import _takes_keyword as _takes_keyword
from microfab.trajectory.spline import TimeSpline

if TYPE_CHECKING:
    pass

__all__ = [
    "HighsLP",
    "LPSolver",
    "PathLike",
    "PlanningError",
    "SegmentReport",
    "TimeOptimalResult",
    "time_optimal",
]


@dataclass(frozen=True, kw_only=True, eq=False)
class SegmentReport:
    """How hard one segment (between two stops) uses the machine.

    Parameters
    ----------
    s_start, s_end : float
        Arc-length range, m.
    duration : float
        Time spent on it, s.
    utilisation : float
        Largest ``|value| / limit`` over axes and quantities (velocity, acceleration,
        jerk, and path speed over ``feed`` when given), from the spline's exact maxima.
    active : str
        The quantity reaching ``utilisation``, e.g. ``"acceleration y"`` or ``"feed"``.
    time_scale : float
        Factor by which the segment's time was stretched after verification (1 if not).
    """

    s_start: float
    s_end: float
    duration: float
    utilisation: float
    active: str
    time_scale: float = 1.0

    def __post_init__(self) -> None:
        if not self.s_end > self.s_start:
            raise ValueError(
                f"segment must end after it starts, got [{self.s_start}, {self.s_end}] m"
            )
        check_positive("segment duration", self.duration, "s")
        check_nonnegative("utilisation", self.utilisation, "(fraction)")
        if not self.time_scale >= 1.0:
            raise ValueError(f"time_scale must be >= 1, got {self.time_scale}")


@dataclass(frozen=True, kw_only=True, eq=False)
class TimeOptimalResult:
    """The time-optimal reference along a path.

    Parameters
    ----------
    s : numpy.ndarray, shape (N,)
        Grid of arc lengths, m.
    sdot : numpy.ndarray, shape (N,)
        Path speed ``ṡ`` at the grid nodes, m/s.
    t_knots : numpy.ndarray, shape (N,)
        Time at each grid node, s.
    stops : numpy.ndarray
        Grid indices where the machine stands still (ends and corners).
    spline : TimeSpline
        The reference, a time-based spline through ``q(s_k)`` at ``t_k``.
    trajectory : Trajectory
        The spline sampled at ``sample_rate_hz``, with ``s``; it passed ``check_trajectory``.
    duration : float
        ``t_knots[-1]``, s.
    iterations : int
        LPs solved in all.
    rounds : int
        Verification rounds (solve, fit, compare with the limits).
    segments : tuple of SegmentReport
        One per segment between stops.
    """

    s: np.ndarray
    sdot: np.ndarray
    t_knots: np.ndarray
    stops: np.ndarray
    spline: TimeSpline
    trajectory: Trajectory
    duration: float
    iterations: int
    rounds: int
    segments: tuple[SegmentReport, ...]
    meta: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = np.shape(self.s)
        for name, unit in (("s", "m"), ("sdot", "m/s"), ("t_knots", "s")):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.ndim != 1 or arr.shape != n:
                raise ValueError(f"{name} ({unit}) must have shape {n}, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} holds NaN or inf ({unit})")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if np.any(self.sdot < 0):
            raise ValueError(f"sdot must be >= 0 m/s, got {float(np.min(self.sdot))} m/s")
        check_positive("duration", self.duration, "s")

    @property
    def utilisation(self) -> np.ndarray:
        """Per-segment utilisation (largest ``|value| / limit``)."""
        return np.array([seg.utilisation for seg in self.segments])

    @property
    def active(self) -> tuple[str, ...]:
        """Per-segment active constraint."""
        return tuple(seg.active for seg in self.segments)


def _segment_bounds(stop: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(stop)
    return [(int(a), int(b)) for a, b in pairwise(idx)]


def _fit_segments(
    g: _Grid,
    t: np.ndarray,
    ramp: np.ndarray,
    segs: list[tuple[int, int]],
    bc: str,
    axes: tuple[str, ...],
) -> list[TimeSpline]:
    """One spline per segment, times from 0; with ``bc="rest"`` a break ends each ramp."""
    out = []
    for a, b in segs:
        ts = t[a : b + 1] - t[a]
        breaks = None
        if bc == "rest":
            h0, h1 = ts[1] - ts[0], ts[-1] - ts[-2]
            f0, f1 = ramp[a] / h0, ramp[b - 1] / h1
            # the jerk ramp ends inside the interval; a pure ramp (f ≈ 1) needs no break
            f0 = 0.5 if not f0 < 0.99 else max(f0, 1e-3)
            f1 = 0.5 if not f1 < 0.99 else max(f1, 1e-3)
            breaks = (ts[0] + f0 * h0, ts[-1] - f1 * h1)
        out.append(TimeSpline.fit(ts, g.q[a : b + 1], bc=bc, axes=axes, rest_breaks=breaks))
    return out


def _ratios(sp: TimeSpline, limits: MachineLimits) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-piece ratios |value| / limit, max over axes, for velocity, acceleration, jerk."""
    v, _, a, _, j, _ = sp.piece_maxima()
    rv = np.max(v / np.asarray(limits.velocity), axis=1)
    ra = np.max(a / np.asarray(limits.acceleration), axis=1)
    rj = np.max(j / np.asarray(limits.jerk), axis=1)
    return rv, ra, rj


def time_optimal(
    path: PathLike,
    limits: MachineLimits,
    *,
    n_grid: int = 1000,
    sample_rate_hz: float = 10_000.0,
    feed: float | None = None,
    margin: float = 0.01,
    solver: LPSolver | None = None,
    max_iter: int = 30,
    max_rounds: int = 12,
) -> TimeOptimalResult:
    """Time-optimal reference along ``path`` under per-axis v, a and j limits.

    See the module docstring for the method.

    Parameters
    ----------
    path : PathLike
        The path (:class:`microfab.geometry.path.Path`), arc-length parametrised, m.
    limits : MachineLimits
        Per-axis velocity, acceleration and (optional) jerk limits; axes whose jerk
        limit is infinite get no jerk constraint.
    n_grid : int
        Number of uniform grid nodes (corners and junctions are added), >= 10.
    sample_rate_hz : float
        Sample rate of the emitted trajectory, Hz.
    feed : float, optional
        Path speed cap, m/s.
    margin : float
        Planning margin in ``[0, 0.5)``: the LP uses ``(1 - margin) · limit``.
    solver : LPSolver, optional
        LP solver; :class:`HighsLP` by default.
    max_iter : int
        Largest number of sequential-LP iterations per solve (jerk-limited case).
    max_rounds : int
        Largest number of verification rounds (solve, fit the spline, shrink bounds
        where the spline exceeds a limit).

    Returns
    -------
    TimeOptimalResult

    Raises
    ------
    ValueError
        Bad arguments (naming the quantity, value and unit).
    LimitViolation
        A grid point of the path lies outside the workspace.
    PlanningError
        No trajectory within the limits could be produced.
    """
    check_int("n_grid", n_grid, 10)
    check_positive("sample_rate_hz", sample_rate_hz, "Hz")
    if feed is not None:
        check_positive("feed", feed, "m/s")
    check_in_range("margin", margin, 0.0, 0.5, "(fraction of each limit)", high_closed=False)
    check_int("max_iter", max_iter, 1)
    check_int("max_rounds", max_rounds, 1)
    if not isinstance(limits, MachineLimits):
        raise ValueError(f"limits must be MachineLimits, got {type(limits).__name__}")
    check_positive("path length", path.length, "m")
    n_axes = len(limits.axes)
    probe = path.evaluate(np.array([0.0]), 0)[0]
    if np.shape(probe)[-1] != n_axes:
        raise ValueError(f"path has {np.shape(probe)[-1]} coordinates, limits have {n_axes} axes")
    lp = solver if solver is not None else HighsLP()

    g = _build_grid(path, int(n_grid))
    _check_workspace(g.q, limits)
    prob = _Problem(g=g, limits=limits, feed=feed, margin=float(margin), solver=lp)
    N = g.s.size
    segs = _segment_bounds(g.stop)
    bc = "rest" if prob.has_jerk else "clamped"
    vmul, amul, jmul = np.ones(N), np.ones(N - 1), np.ones(N)
    x: np.ndarray | None = None
    rounds = 0
    for rounds in range(1, max_rounds + 1):  # noqa: B007 - rounds is reported
        if prob.has_jerk:
            if x is None:
                start = prob.solve_va(vmul, amul, jmul)
            else:
                start = x
            start = start * prob.feasible_scale(start, vmul, amul, jmul)
            x = prob.solve_jerk(start, vmul, amul, jmul, max_iter)
        else:
            x = prob.solve_va(vmul, amul)
        t, ramp = prob.knot_times(x, jmul)
        if not np.all(np.isfinite(t)):
            raise PlanningError(
                "the limits allow no motion that can be timed (the path speed underflows to "
                f"zero): velocity {limits.velocity} m/s, acceleration {limits.acceleration} "
                f"m/s^2, jerk {limits.jerk} m/s^3; declare limits the machine really has"
            )
        splines = _fit_segments(g, t, ramp, segs, bc, limits.axes)
        worst = 0.0
        # per-round shrink factors (the smallest asked for), applied once
        fv, fa, fj = np.ones(N), np.ones(N - 1), np.ones(N)
        keep = 1 - margin
        for (a, _b), sp in zip(segs, splines, strict=True):
            rv, ra, rj = _ratios(sp, limits)
            # piece -> grid interval (extra "rest" breakpoints map into their interval)
            mids = 0.5 * (sp.knots[:-1] + sp.knots[1:]) + t[a]
            k = np.clip(np.searchsorted(t, mids, side="right") - 1, 0, N - 2)
            for ratio, fac, lo, hi in ((rv, fv, 0, 2), (ra, fa, -1, 2), (rj, fj, -1, 3)):
                bad = np.flatnonzero(ratio > 1.0)
                if bad.size == 0:
                    continue
                worst = max(worst, float(np.max(ratio[bad])))
                f = np.maximum(keep / ratio[bad], 0.5)  # at most halve a bound per round
                for kb, fb in zip(k[bad], f, strict=True):
                    sl = slice(max(kb + lo, 0), kb + hi)
                    fac[sl] = np.minimum(fac[sl], fb)
        vmul *= fv
        amul *= fa
        jmul *= fj
        if worst <= 1.0:
            break
    assert x is not None

    # last resort: stretch the time of segments that still exceed a limit
    scales: list[float] = []
    fitted: list[TimeSpline] = []
    t_new = np.zeros(N)
    sdot = np.sqrt(np.maximum(x, 0.0))
    for (a, b), sp in zip(segs, splines, strict=True):
        rv, ra, rj = _ratios(sp, limits)
        lam = max(1.0, float(np.max(rv)), float(np.max(ra)) ** 0.5, float(np.max(rj)) ** (1 / 3))
        if lam > 1.0:
            lam *= 1 + 1e-9
            sp = sp.scaled_time(lam)
        scales.append(lam)
        fitted.append(sp)
        t_new[a + 1 : b + 1] = t_new[a] + (t[a + 1 : b + 1] - t[a]) * lam
        sdot[a : b + 1] /= lam
    joined = TimeSpline.concatenate(fitted)
    spline = TimeSpline(
        knots=joined.knots - joined.knots[0],
        alpha=joined.alpha,
        beta=joined.beta,
        gamma=joined.gamma,
        delta=joined.delta,
        axes=joined.axes,
        bc=joined.bc,
        meta={"generator": "time_optimal", "margin": float(margin)},
    )
    traj = spline.sample(sample_rate_hz, s_knots=g.s, s_times=t_new)
    try:
        check_trajectory(traj, limits)
    except LimitViolation as err:
        raise PlanningError(f"time_optimal could not stay within the limits: {err}") from err
    reports = _segment_reports(g, spline, traj, t_new, segs, scales, limits, feed)
    return TimeOptimalResult(
        s=readonly(g.s, dtype=None),
        sdot=readonly(sdot, dtype=None),
        t_knots=readonly(t_new, dtype=None),
        stops=readonly(np.flatnonzero(g.stop), dtype=None),
        spline=spline,
        trajectory=traj,
        duration=float(t_new[-1]),
        iterations=prob.lp_count,
        rounds=rounds,
        segments=tuple(reports),
        meta={"margin": float(margin), "feed": feed, "jerk_limited": prob.has_jerk},
    )


def _check_workspace(q: np.ndarray, limits: MachineLimits) -> None:
    for k, ax in enumerate(limits.axes):
        lo, hi = limits.workspace[k]
        if np.min(q[:, k]) < lo or np.max(q[:, k]) > hi:
            raise LimitViolation(
                f"axis {ax}: the path spans [{np.min(q[:, k]):.6g}, {np.max(q[:, k]):.6g}] m, "
                f"outside the workspace [{lo:.6g}, {hi:.6g}] m"
            )


def _segment_reports(
    g: _Grid,
    spline: TimeSpline,
    traj: Trajectory,
    t: np.ndarray,
    segs: list[tuple[int, int]],
    scales: list[float],
    limits: MachineLimits,
    feed: float | None,
) -> list[SegmentReport]:
    v, _, a, _, j, _ = spline.piece_maxima()
    mids = 0.5 * (spline.knots[:-1] + spline.knots[1:])
    speed = np.linalg.norm(np.asarray(traj.velocity), axis=1)
    ts = traj.time
    out = []
    for (ia, ib), lam in zip(segs, scales, strict=True):
        sel = (mids >= t[ia]) & (mids <= t[ib])
        best, name = 0.0, ""
        for qty, arr, lim in (
            ("velocity", v, limits.velocity),
            ("acceleration", a, limits.acceleration),
            ("jerk", j, limits.jerk),
        ):
            r = np.max(arr[sel] / np.asarray(lim), axis=0)
            i = int(np.argmax(r))
            if r[i] > best:
                best, name = float(r[i]), f"{qty} {limits.axes[i]}"
        if feed is not None:
            w = (ts >= t[ia]) & (ts <= t[ib])
            r = float(np.max(speed[w])) / feed if np.any(w) else 0.0
            if r > best:
                best, name = r, "feed"
        out.append(
            SegmentReport(
                s_start=float(g.s[ia]),
                s_end=float(g.s[ib]),
                duration=float(t[ib] - t[ia]),
                utilisation=best,
                active=name,
                time_scale=float(lam),
            )
        )
    return out
