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

import inspect
import warnings
from dataclasses import dataclass, field
from itertools import pairwise
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numba import njit
from scipy import sparse
from scipy.optimize import brentq, linprog, minimize_scalar

from microfab.core.arrays import readonly
from microfab.core.interrupt import interruptible
from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.core.validate import check_in_range, check_int, check_nonnegative, check_positive
from microfab.trajectory.base import Trajectory
from microfab.trajectory.highs import HighsSession
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

_TIME_RTOL = 1e-4  # stop the sequential LP when T improves by less than this, relative
_MIN_INTERVALS = 4  # at least this many grid intervals between two stops


class PlanningError(RuntimeError):
    """The planner could not produce a trajectory within the limits."""


class PathLike(Protocol):
    """What the planner needs from a path (:class:`microfab.geometry.path.Path`)."""

    @property
    def length(self) -> float:
        """Arc length, m."""
        ...

    @property
    def closed(self) -> bool:
        """Whether the path ends where it starts."""
        ...

    def evaluate(self, s: np.ndarray, order: int = 3) -> list[np.ndarray]:
        """``[q, dq, d2q, d3q][: order + 1]`` at arc lengths ``s``, each (n, 2)."""
        ...

    def corners(self, angle_tol: float = 1e-3) -> np.ndarray:
        """Arc lengths where the tangent direction jumps by more than ``angle_tol`` rad."""
        ...

    def junctions(self) -> np.ndarray:
        """Arc lengths of all interior segment junctions."""
        ...


class LPSolver(Protocol):
    """A linear-program solver: minimise ``c @ x`` s.t. ``A_ub @ x <= b_ub``, bounds.

    A solver whose ``solve`` also accepts a keyword ``x0`` is given a starting point for
    the velocity/acceleration LP (see the module notes); others are called as below.
    """

    def solve(
        self,
        c: np.ndarray,
        A_ub: sparse.csr_matrix,
        b_ub: np.ndarray,
        bounds: np.ndarray,
    ) -> np.ndarray:
        """Return the minimiser ``x``; raise :class:`PlanningError` if there is none."""
        ...


@dataclass(frozen=True, kw_only=True)
class HighsLP:
    """SciPy's HiGHS LP solver (:func:`scipy.optimize.linprog`, ``method="highs"``).

    Parameters
    ----------
    time_limit : float, optional
        Wall-time limit per LP, s.
    """

    time_limit: float | None = None
    _session: HighsSession = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.time_limit is not None and not self.time_limit > 0:
            raise ValueError(f"time_limit must be positive, got {self.time_limit} s")
        object.__setattr__(self, "_session", HighsSession(self.time_limit))

    def solve(
        self,
        c: np.ndarray,
        A_ub: sparse.csr_matrix,
        b_ub: np.ndarray,
        bounds: np.ndarray,
        x0: np.ndarray | None = None,
    ) -> np.ndarray:
        """Minimise ``c @ x`` subject to ``A_ub @ x <= b_ub`` and ``bounds`` (n, 2).

        With a starting point ``x0``, or the same ``A_ub`` object as the previous call
        that had one, the LP goes to a kept HiGHS model (warm start, see
        :class:`~microfab.trajectory.highs.HighsSession`); otherwise to
        :func:`scipy.optimize.linprog`. Not thread-safe: one instance per thread.
        """
        session = self._session
        if session.available and (x0 is not None or session.holds(A_ub)):
            try:
                x, status = session.solve(c, A_ub, b_ub, bounds, x0)
            except (AttributeError, TypeError) as exc:  # bindings of another HiGHS: linprog
                session.broken = True
                warnings.warn(
                    f"HiGHS bindings unusable ({exc}); solving with linprog", stacklevel=2
                )
            else:
                if x is None:
                    raise PlanningError(f"HiGHS LP failed: {status}")
                return x
        options: dict[str, object] = {}
        if self.time_limit is not None:
            options["time_limit"] = float(self.time_limit)
        res = interruptible(
            linprog, c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method="highs", options=options
        )  # Ctrl-C is a KeyboardInterrupt, never a failed LP
        if res.status != 0 or res.x is None:
            raise PlanningError(f"HiGHS LP failed: {res.message}")
        return np.asarray(res.x, dtype=float)


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


# --------------------------------------------------------------------------- grid
@dataclass(frozen=True, kw_only=True, eq=False)
class _Grid:
    s: np.ndarray  # (N,)
    h: np.ndarray  # (N-1,)
    stop: np.ndarray  # bool (N,)
    q: np.ndarray  # (N, n) positions at nodes
    d1: np.ndarray  # (N, n) q' at nodes
    d1_in: np.ndarray  # (N-1, 2, n) q' just inside each interval: [start, end]
    d2_in: np.ndarray  # (N-1, 2, n) q''
    d2_node: np.ndarray  # (N, n) mean of the two one-sided q''
    d3_node: np.ndarray  # (N, n) q''', plus the spread jump of q'' at junctions


def _build_grid(path: PathLike, n_grid: int) -> _Grid:
    L = float(path.length)
    ds = L / (n_grid - 1)
    tol = ds / 4
    corners = np.sort(np.asarray(path.corners(), dtype=float).reshape(-1))
    corners = corners[(corners > 1e-12 * L) & (corners < L * (1 - 1e-12))]  # all are stops
    juncs = np.sort(np.asarray(path.junctions(), dtype=float).reshape(-1))
    juncs = juncs[(juncs > tol) & (juncs < L - tol)]
    special = list(corners)
    for sj in juncs:  # a junction close to a kept special node merges into it
        if not special or np.min(np.abs(np.asarray(special) - sj)) >= tol:
            special.append(float(sj))
    sp = np.sort(np.asarray(special, dtype=float))
    uni = np.linspace(0.0, L, n_grid)
    if sp.size:
        near = np.min(np.abs(uni[:, None] - sp[None, :]), axis=1) < tol
        near[0] = near[-1] = False
        uni = uni[~near]
    s = np.unique(np.concatenate([uni, sp]))
    s[0], s[-1] = 0.0, L
    # at least _MIN_INTERVALS intervals between consecutive stops
    stop_s = np.concatenate([[0.0], corners, [L]])
    extra: list[np.ndarray] = []
    for a, b in pairwise(stop_s):
        inside = np.count_nonzero((s > a) & (s < b))
        if inside + 1 < _MIN_INTERVALS:
            extra.append(np.linspace(a, b, _MIN_INTERVALS + 1)[1:-1])
    if extra:
        s = np.unique(np.concatenate([s, *extra]))
    stop = np.zeros(s.size, dtype=bool)
    stop[0] = stop[-1] = True
    if corners.size:
        stop[np.searchsorted(s, corners)] = True
    h = np.diff(s)
    eps = 1e-7 * h
    s_in = np.concatenate([s[:-1] + eps, s[1:] - eps])
    m = s.size - 1
    q, d1, _, d3 = (np.asarray(a, dtype=float) for a in path.evaluate(s, 3))
    _, d1i, d2i = (np.asarray(a, dtype=float) for a in path.evaluate(s_in, 2))
    d1_in = np.stack([d1i[:m], d1i[m:]], axis=1)
    d2_in = np.stack([d2i[:m], d2i[m:]], axis=1)
    d2_node = np.empty_like(q)
    d2_node[1:-1] = 0.5 * (d2_in[:-1, 1] + d2_in[1:, 0])
    d2_node[0], d2_node[-1] = d2_in[0, 0], d2_in[-1, 1]
    d3_node = d3.copy()
    if juncs.size:
        # A jump Δ of q'' at a junction is, in time, a jump of the normal acceleration; the
        # C² spline through the knots spreads a jump of its second derivative at a knot
        # over the two adjacent intervals with a third derivative of about
        # (1/2 + 1/(2(2 + √3))) Δ / h ≈ 0.634 Δ / h (from its moment equations
        # M_{k-1} + 4 M_k + M_{k+1} = 6 δ²y_k / h², whose decay ratio is √3 - 2). The
        # planner charges that q''' to the nearest node and its two neighbours.
        eps_j = 1e-7 * ds
        d2_r = np.asarray(path.evaluate(juncs + eps_j, 2)[2], dtype=float)
        d2_l = np.asarray(path.evaluate(juncs - eps_j, 2)[2], dtype=float)
        spread = 0.5 + 0.5 / (2.0 + np.sqrt(3.0))
        n_int = h.size
        for sj, jump in zip(juncs, d2_r - d2_l, strict=True):
            k = int(np.argmin(np.abs(s - sj)))
            around = (
                (k - 1, h[k - 1] if k >= 1 else np.inf),
                (k, 0.5 * (h[k - 1] + h[k]) if 0 < k < n_int else np.inf),
                (k + 1, h[k] if k < n_int else np.inf),
            )
            for m, hl in around:
                if 0 < m < s.size - 1 and not stop[m] and np.isfinite(hl):
                    d3_node[m] += spread * jump / hl
    return _Grid(
        s=s, h=h, stop=stop, q=q, d1=d1, d1_in=d1_in, d2_in=d2_in, d2_node=d2_node,
        d3_node=d3_node,
    )  # fmt: skip


# --------------------------------------------------------------------------- operators
def _acc_operator(g: _Grid) -> sparse.csr_matrix:
    """Rows (interval k, end e, axis i) of ``q'_i x'/2 + q''_i x_e``; shape (4(N-1)·n/2…)."""
    m, n_ax = g.h.size, g.q.shape[1]
    k = np.repeat(np.arange(m), 2 * n_ax)
    e = np.tile(np.repeat([0, 1], n_ax), m)
    i = np.tile(np.arange(n_ax), 2 * m)
    rows = np.arange(k.size)
    d1 = g.d1_in[k, e, i]
    d2 = g.d2_in[k, e, i]
    half = d1 / (2 * g.h[k])
    c_k = -half + np.where(e == 0, d2, 0.0)
    c_k1 = half + np.where(e == 1, d2, 0.0)
    return sparse.csr_matrix(
        (np.concatenate([c_k, c_k1]), (np.concatenate([rows, rows]), np.concatenate([k, k + 1]))),
        shape=(k.size, g.s.size),
    )


def _jerk_operator(
    g: _Grid, limited: np.ndarray
) -> tuple[sparse.csr_matrix, np.ndarray, np.ndarray]:
    """Rows (node k, axis i) of ``q'_i x''/2 + 1.5 q''_i x' + q'''_i x`` at non-stop nodes.

    Only axes with ``limited[i]`` (a finite jerk limit) get rows.
    """
    axes = np.flatnonzero(limited)
    nodes = np.flatnonzero(~g.stop)
    k = np.repeat(nodes, axes.size)
    i = np.tile(axes, nodes.size)
    h0, h1 = g.h[k - 1], g.h[k]
    # three-point non-uniform differences
    dm, d0, dp = -h1 / (h0 * (h0 + h1)), (h1 - h0) / (h0 * h1), h0 / (h1 * (h0 + h1))
    em, e0, ep = 2 / (h0 * (h0 + h1)), -2 / (h0 * h1), 2 / (h1 * (h0 + h1))
    a1, a2, a3 = g.d1[k, i], g.d2_node[k, i], g.d3_node[k, i]
    cm = 0.5 * a1 * em + 1.5 * a2 * dm
    c0 = 0.5 * a1 * e0 + 1.5 * a2 * d0 + a3
    cp = 0.5 * a1 * ep + 1.5 * a2 * dp
    rows = np.arange(k.size)
    op = sparse.csr_matrix(
        (
            np.concatenate([cm, c0, cp]),
            (np.tile(rows, 3), np.concatenate([k - 1, k, k + 1])),
        ),
        shape=(k.size, g.s.size),
    )
    return op, k, i


def _travel_time(x: np.ndarray, w: np.ndarray) -> float:
    """``Σ w_k / (√x_k + √x_{k+1})``: with ``w_k = 2Δs_k``, the time at constant ``s̈``."""
    r = np.sqrt(np.maximum(x, 0.0))
    den = r[:-1] + r[1:]
    with np.errstate(divide="ignore"):
        return float(np.sum(np.where(den > 0, w / den, np.inf)))


def _midpoint_cubic(s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` at each interval's midpoint from the cubic through the four nodes around it."""
    n = s.size
    out = 0.5 * (x[:-1] + x[1:])
    if n < 4:
        return out
    k = np.arange(n - 1)
    lo = np.clip(k - 1, 0, n - 4)
    idx = lo[:, None] + np.arange(4)[None, :]  # four nodes around each interval
    xs, ys = s[idx], x[idx]
    m = 0.5 * (s[:-1] + s[1:])
    val = np.zeros(n - 1)
    for j in range(4):
        w = np.ones(n - 1)
        for i in range(4):
            if i != j:
                w *= (m - xs[:, i]) / (xs[:, j] - xs[:, i])
        val += w * ys[:, j]
    return val


def _start_time(ds: float, v1: float, sigma: float) -> tuple[float, float]:
    """Time to cover ``ds`` from rest, arriving at speed ``v1``, at path jerk <= ``sigma``.

    The path acceleration ramps at ``σ`` up to ``a`` (for ``τ = a/σ``), then stays: the
    arrival speed is ``v1 = a (t - τ/2)`` and the distance ``D(a) = v1²/(2a) + a³/(24σ²)``,
    which decreases on ``(0, √(2σ v1)]``. Its root there gives ``t = v1/a + a/(2σ)``,
    between ``2 ds / v1`` (σ → ∞, constant acceleration) and ``3 ds / v1`` (the pure
    ramp ``s = σt³/6``, reached when ``σ = (2/9) v1³ / ds²``). Returns ``(t, τ)``.
    """
    if v1 <= 0:
        return np.inf, np.inf
    if not np.isfinite(sigma):
        return 2 * ds / v1, 0.0
    a_hi = np.sqrt(2 * sigma * v1)
    a_lo = v1 * v1 / (2 * ds)

    def excess(a: float) -> float:
        return v1 * v1 / (2 * a) + a**3 / (24 * sigma**2) - ds

    if a_lo >= a_hi or excess(a_hi) >= 0:
        return 3 * ds / v1, 3 * ds / v1
    if excess(a_lo) <= 0:  # σ so large that the ramp is lost in rounding: constant a
        a = a_lo
    else:
        a = float(brentq(excess, a_lo, a_hi, xtol=1e-14 * a_hi, rtol=1e-12))
    t = min(v1 / a + a / (2 * sigma), 3 * ds / v1)
    return t, min(a / sigma, t)


def _takes_keyword(fn: object, name: str) -> bool:
    """Whether the callable ``fn`` accepts the keyword argument ``name``."""
    try:
        params = inspect.signature(fn).parameters  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return name in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


@njit(cache=True)
def _max_first(lines: np.ndarray, m: int) -> float:
    """Largest ``x`` over the polygon ``a x + b y <= c`` (rows ``[a, b, c]`` of ``lines``).

    A two-variable LP solved by enumerating the vertices (the polygon holds ``(0, 0)``).
    """
    best = 0.0
    for i in range(m):
        for j in range(i + 1, m):
            a1, b1, c1 = lines[i, 0], lines[i, 1], lines[i, 2]
            a2, b2, c2 = lines[j, 0], lines[j, 1], lines[j, 2]
            det = a1 * b2 - a2 * b1
            scale = abs(a1 * b2) + abs(a2 * b1)
            if not abs(det) > 1e-12 * scale:
                continue
            x = (c1 * b2 - c2 * b1) / det
            y = (a1 * c2 - a2 * c1) / det
            if x <= best:
                continue
            ok = True
            for r in range(m):
                a, b, c = lines[r, 0], lines[r, 1], lines[r, 2]
                if a * x + b * y > c + 1e-12 * (abs(a * x) + abs(b * y) + abs(c)):
                    ok = False
                    break
            if ok:
                best = x
    return best


@njit(cache=True)
def _va_vertex(
    cap: np.ndarray, alpha: np.ndarray, beta: np.ndarray, bound: np.ndarray, per: int
) -> np.ndarray:
    """The passes of `_greatest_va` for ``0 <= x <= cap`` and the acceleration rows.

    Row ``r`` reads ``|alpha_r x_k + beta_r x_{k+1}| <= bound_r``; rows ``per * k`` to
    ``per * (k + 1) - 1`` belong to interval ``k``.
    """
    n = cap.size
    reach = np.empty(n)  # the largest x_k that the nodes after k can follow
    reach[n - 1] = cap[n - 1]
    lines = np.empty((2 * per + 4, 3))
    for k in range(n - 2, -1, -1):
        m = 0
        for r in range(per * k, per * (k + 1)):
            for sgn in (1.0, -1.0):
                lines[m, 0], lines[m, 1], lines[m, 2] = sgn * alpha[r], sgn * beta[r], bound[r]
                m += 1
        # x_k <= cap_k, x_{k+1} <= reach_{k+1}, both >= 0
        lines[m, 0], lines[m, 1], lines[m, 2] = 1.0, 0.0, cap[k]
        lines[m + 1, 0], lines[m + 1, 1], lines[m + 1, 2] = 0.0, 1.0, reach[k + 1]
        lines[m + 2, 0], lines[m + 2, 1], lines[m + 2, 2] = -1.0, 0.0, 0.0
        lines[m + 3, 0], lines[m + 3, 1], lines[m + 3, 2] = 0.0, -1.0, 0.0
        reach[k] = _max_first(lines, m + 4)
    x = np.empty(n)
    x[0] = reach[0]
    for k in range(n - 1):
        nxt = reach[k + 1]
        for r in range(per * k, per * (k + 1)):
            for sgn in (1.0, -1.0):
                a, b = sgn * alpha[r], sgn * beta[r]
                if b > 0.0:
                    nxt = min(nxt, (bound[r] - a * x[k]) / b)
        x[k + 1] = max(nxt, 0.0)
    return x


def _greatest_va(
    cap: np.ndarray, alpha: np.ndarray, beta: np.ndarray, bound: np.ndarray, per: int
) -> np.ndarray:
    """A starting vertex for the v/a LP: its optimum wherever a greatest element exists.

    A backward pass finds, interval by interval, the largest ``x_k`` that the rest of
    the path can follow (a two-variable LP per interval, by its vertices); a forward pass
    then takes at each node the largest value allowed after ``x_{k-1}``. Where every
    acceleration row has coefficients of opposite signs, each bounds one node by an
    increasing function of the other, the feasible set has a greatest element and this
    is it: it maximises every positively weighted sum, so it is the LP's optimum and the
    solver only certifies it (this is how TOPP-RA computes its controllable sets). Near
    an axis' turning point on a curve a row may bound both nodes; the vertex is then a
    good guess from which the solver iterates.
    """
    return _va_vertex(
        np.ascontiguousarray(cap, dtype=float),
        np.ascontiguousarray(alpha, dtype=float),
        np.ascontiguousarray(beta, dtype=float),
        np.ascontiguousarray(bound, dtype=float),
        int(per),
    )


# --------------------------------------------------------------------------- planner
class _Problem:
    """The discretised problem: constraint operators, bounds and the two solvers."""

    def __init__(
        self, g: _Grid, limits: MachineLimits, feed: float | None, margin: float, solver: LPSolver
    ) -> None:
        self.g, self.limits, self.feed, self.margin, self.solver = g, limits, feed, margin, solver
        self.lp_count = 0
        self.acc_op = _acc_operator(g)
        # the v/a LP's rows, built once: acc_op / limit, both signs, <= the multiplier
        base = self.acc_bound(np.ones(g.h.size))
        scaled = sparse.csr_matrix(self.acc_op.multiply(1.0 / base[:, None]))
        self.va_rows = sparse.vstack([scaled, -scaled]).tocsr()
        self.va_rows.data.setflags(write=False)
        self.va_weights = np.zeros(g.s.size)  # positive weights: node's share of the length
        self.va_weights[:-1] += 0.5 * g.h
        self.va_weights[1:] += 0.5 * g.h
        # a solver taking a starting point gets the greatest element (see _greatest_va)
        self.va_crash = _takes_keyword(solver.solve, "x0")
        if self.va_crash:
            coo = scaled.tocoo()
            lo = coo.col == coo.row // (2 * g.q.shape[1])  # coefficient of x_k (interval k)
            n_rows = scaled.shape[0]
            self.va_alpha = np.zeros(n_rows)
            self.va_beta = np.zeros(n_rows)
            np.add.at(self.va_alpha, coo.row[lo], coo.data[lo])
            np.add.at(self.va_beta, coo.row[~lo], coo.data[~lo])
        jerk = np.asarray(limits.jerk, dtype=float)
        self.has_jerk = bool(np.any(np.isfinite(jerk)))
        stop = g.stop
        # time weight of each interval: Δt = w / (√x_k + √x_{k+1}) for constant s̈
        self.tw = 2.0 * g.h
        self.jerk_op: sparse.csr_matrix | None = None
        self.jerk_k: np.ndarray | None = None
        self.jerk_i: np.ndarray | None = None
        if self.has_jerk:
            self.jerk_op, self.jerk_k, self.jerk_i = _jerk_operator(g, np.isfinite(jerk))
        # nodes next to a stop, and the length of the interval to it
        nxt = np.zeros(stop.size, dtype=bool)
        nxt[1:] |= stop[:-1]
        nxt[:-1] |= stop[1:]
        nxt &= ~stop
        self.near_stop = np.flatnonzero(nxt)
        h_to = np.full(stop.size, np.inf)
        h_to[1:] = np.where(stop[:-1], self.g.h, h_to[1:])
        h_to[:-1] = np.where(stop[1:], np.minimum(self.g.h, h_to[:-1]), h_to[:-1])
        self.h_to_stop = h_to[self.near_stop]

    # bounds of each constraint, with the per-node/interval multipliers
    def caps(self, vmul: np.ndarray, jmul: np.ndarray | None = None) -> np.ndarray:
        lim_v = (1 - self.margin) * np.asarray(self.limits.velocity)
        with np.errstate(divide="ignore"):
            per_axis = (lim_v[None, :] * vmul[:, None] / np.abs(self.g.d1)) ** 2
        cap = np.min(per_axis, axis=1)
        if self.feed is not None:
            cap = np.minimum(cap, ((1 - self.margin) * self.feed * vmul) ** 2)
        if self.has_jerk and jmul is not None:
            # leaving a stop at constant path jerk σ, s = σt³/6: σ = (2/9) ṡ³ / Δs², so
            # |q'_i| σ <= j_i caps x = ṡ² at the first node at (4.5 j_i Δs² / |q'_i|)^{2/3}
            k = self.near_stop
            lim_j = (1 - self.margin) * np.asarray(self.limits.jerk)[None, :] * jmul[k, None]
            with np.errstate(divide="ignore"):
                first = (4.5 * lim_j * self.h_to_stop[:, None] ** 2 / np.abs(self.g.d1[k])) ** (
                    2.0 / 3.0
                )
            cap[k] = np.minimum(cap[k], np.min(first, axis=1))
        cap[self.g.stop] = 0.0
        return cap

    def acc_bound(self, amul: np.ndarray) -> np.ndarray:
        n_ax = self.g.q.shape[1]
        lim = (1 - self.margin) * np.asarray(self.limits.acceleration)
        return (amul[:, None, None] * np.broadcast_to(lim, (amul.size, 2, n_ax))).reshape(-1)

    def jerk_bound(self, jmul: np.ndarray) -> np.ndarray:
        lim = (1 - self.margin) * np.asarray(self.limits.jerk)
        assert self.jerk_k is not None and self.jerk_i is not None
        return lim[self.jerk_i] * jmul[self.jerk_k]

    def knot_times(self, x: np.ndarray, jmul: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Times at the nodes, and the jerk-ramp duration in intervals touching a stop.

        Constant ``s̈`` per interval; next to a stop with a jerk limit, the path
        acceleration ramps from zero at the path jerk ``σ = min_i j_i / |q'_i|`` first
        (:func:`_start_time`). The ramp duration is NaN elsewhere.
        """
        with np.errstate(divide="ignore"):  # a speed that underflows: refused by the caller
            dt = self.tw / (np.sqrt(np.maximum(x[:-1], 0)) + np.sqrt(np.maximum(x[1:], 0)))
        ramp = np.full(dt.size, np.nan)
        if self.has_jerk:
            # s̈ varies within an interval: Simpson's rule on 1/ṡ, with x at the midpoint
            # from the cubic through the four surrounding nodes (kept between x_k, x_{k+1})
            xm = _midpoint_cubic(self.g.s, np.maximum(x, 0.0))
            lo = np.minimum(x[:-1], x[1:])
            hi = np.maximum(x[:-1], x[1:])
            xm = np.clip(xm, lo, hi)
            with np.errstate(divide="ignore"):
                inv = 1.0 / np.sqrt(np.maximum(x, 0.0))
                simpson = self.g.h / 6.0 * (inv[:-1] + 4.0 / np.sqrt(xm) + inv[1:])
            ok = np.isfinite(simpson)
            dt = np.where(ok, simpson, dt)
            lim_j = (1 - self.margin) * np.asarray(self.limits.jerk)
            for k, h in zip(self.near_stop, self.h_to_stop, strict=True):
                with np.errstate(divide="ignore"):
                    sigma = float(np.min(lim_j * jmul[k] / np.abs(self.g.d1[k])))
                t1, tau = _start_time(float(h), float(np.sqrt(max(x[k], 0.0))), sigma)
                iv = k - 1 if self.g.stop[k - 1] else k  # the interval to the stop
                dt[iv], ramp[iv] = t1, tau
        return np.concatenate([[0.0], np.cumsum(dt)]), ramp

    def solve_va(
        self, vmul: np.ndarray, amul: np.ndarray, jmul: np.ndarray | None = None
    ) -> np.ndarray:
        """The velocity/acceleration optimum: one LP, the greatest feasible ``x``."""
        cap = self.caps(vmul, jmul)
        mul = np.repeat(amul, 2 * self.g.q.shape[1])  # per row of acc_op
        b = np.concatenate([mul, mul])
        w = self.va_weights
        bounds = np.column_stack([np.zeros_like(cap), cap])
        if self.va_crash:
            x0 = _greatest_va(cap, self.va_alpha, self.va_beta, mul, 2 * self.g.q.shape[1])
            x = self.solver.solve(-w / w.max(), self.va_rows, b, bounds, x0=x0)
        else:
            x = self.solver.solve(-w / w.max(), self.va_rows, b, bounds)
        self.lp_count += 1
        return np.clip(x, 0.0, cap)

    def feasible_scale(
        self, x: np.ndarray, vmul: np.ndarray, amul: np.ndarray, jmul: np.ndarray
    ) -> float:
        """Largest ``c <= 1`` with ``c x`` inside every (discrete) constraint."""
        c = 1.0
        cap = self.caps(vmul, jmul)
        pos = x > 0
        if np.any(pos):
            c = min(c, float(np.min(cap[pos] / x[pos])))
        acc = np.abs(self.acc_op @ x)
        bound = self.acc_bound(amul)
        if np.any(acc > 0):
            c = min(c, float(np.min(bound[acc > 0] / acc[acc > 0])))
        if self.has_jerk:
            assert self.jerk_op is not None and self.jerk_k is not None
            jk = np.abs(self.jerk_op @ x) * np.sqrt(np.maximum(x[self.jerk_k], 0.0))
            jb = self.jerk_bound(jmul)
            if np.any(jk > 0):
                c = min(c, float(np.min((jb[jk > 0] / jk[jk > 0]) ** (2.0 / 3.0))))
        return max(c, 0.0) * (1 - 1e-9)

    def solve_jerk(
        self,
        x0: np.ndarray,
        vmul: np.ndarray,
        amul: np.ndarray,
        jmul: np.ndarray,
        max_iter: int,
    ) -> np.ndarray:
        """Sequential LP with tangent (convex-restriction) jerk constraints from feasible x0."""
        assert self.jerk_op is not None and self.jerk_k is not None
        g = self.g
        cap = self.caps(vmul, jmul)
        abound = self.acc_bound(amul)
        A_acc = self.acc_op.multiply(1.0 / abound[:, None]).tocsr()
        jb = self.jerk_bound(jmul)
        bounds = np.column_stack([np.zeros_like(cap), cap])
        x = x0.copy()
        T = _travel_time(x, self.tw)
        floor = 1e-9 * max(float(np.max(cap)), 1e-300)
        nk = self.jerk_k.size
        for _ in range(max_iter):
            xf = np.maximum(x, floor)
            # gradient of T: dT/dx_k = -sum_adjacent Δs / ((√x_k + √x_j)² √x_k)
            r = np.sqrt(xf)
            r[g.stop] = np.sqrt(np.maximum(x[g.stop], 0.0))
            den = (r[:-1] + r[1:]) ** 2
            grad = np.zeros_like(x)
            grad[:-1] -= 0.5 * self.tw / den / r[:-1].clip(np.sqrt(floor))
            grad[1:] -= 0.5 * self.tw / den / r[1:].clip(np.sqrt(floor))
            grad[g.stop] = 0.0
            # tangent of j/√x at x̄:  ±L(x) + j x_k / (2 x̄^{3/2}) <= 3 j / (2 √x̄), normalised
            xk = xf[self.jerk_k]
            rhs = 1.5 * jb / np.sqrt(xk)
            tang = sparse.csr_matrix(
                (0.5 * jb / xk**1.5 / rhs, (np.arange(nk), self.jerk_k)), shape=(nk, x.size)
            )
            Lr = self.jerk_op.multiply(1.0 / rhs[:, None]).tocsr()
            A = sparse.vstack([A_acc, -A_acc, Lr + tang, -Lr + tang]).tocsr()
            b = np.ones(A.shape[0])
            self.lp_count += 1
            try:
                x_lp = self.solver.solve(grad / np.max(np.abs(grad)), A, b, bounds)
            except PlanningError:
                break  # keep the last feasible iterate
            x_lp = np.clip(x_lp, 0.0, cap)
            d = x_lp - x

            def along(theta: float, x: np.ndarray = x, d: np.ndarray = d) -> float:
                return _travel_time(x + theta * d, self.tw)

            best = minimize_scalar(along, bounds=(0.0, 1.0), method="bounded")
            theta = float(best.x) if best.fun < along(1.0) else 1.0
            x_new = x + theta * d
            T_new = _travel_time(x_new, self.tw)
            if not T_new < T:
                break
            improved = (T - T_new) / T
            x, T = x_new, T_new
            if improved < _TIME_RTOL:
                break
        return x


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
