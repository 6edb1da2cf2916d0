"""The discretised path of the time-optimal planner (`microfab.trajectory.optimal`).

The planner's numerical ground, kept apart from the LPs that use it and from the public
`~microfab.trajectory.optimal.time_optimal`: the path interface it needs (`PathLike`),
the grid of arc lengths with the path's derivatives at its nodes (`_build_grid`), the
acceleration and jerk constraint operators on ``x = ṡ²`` (`_acc_operator`,
`_jerk_operator`), the traversal and knot times (`_travel_time`, `_midpoint_cubic`,
`_start_time`), and the backward/forward passes (numba) that find the greatest element of
the velocity/acceleration LP (`_greatest_va`). The method is described in
:mod:`microfab.trajectory.optimal`, which re-exports these names.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise
from typing import Protocol

import numpy as np
from numba import njit
from scipy import sparse
from scipy.optimize import brentq

__all__ = ["PathLike"]

_MIN_INTERVALS = 4  # at least this many grid intervals between two stops


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
