"""Constant path speed a machine can run from rest: ramps, curvature slow-downs, corner stops.

Seed 002 eq. (15), ``ρ(t) = Ξ(v t)``, is the baseline most users try first, but it jumps
from rest to full speed, which no finite acceleration limit admits
(:func:`microfab.trajectory.sampling.constant_speed`). `cruise` keeps the path speed at
``speed`` wherever the machine allows it and otherwise stays within the declared limits
(`microfab.core.limits.MachineLimits`):

- it starts and ends at rest, and stops at every corner (a junction where the tangent
  turns by more than ``corner_tol``), where an exact path needs the speed to vanish;
- per axis ``i``, the velocity ``ṡ |q'_i(s)|`` stays within ``v_max,i``;
- per axis, half of ``a_max,i`` is given to the centripetal part ``ṡ² |q''_i(s)|`` and
  half to the tangential part ``|s̈| |q'_i(s)|``, so their sum stays within the limit;
- the speed profile ``ṡ(s)`` is the largest one under those bounds with piecewise
  constant ``s̈`` (a forward pass from rest, a backward pass to rest), sampled exactly in
  time.

A declared jerk limit is not planned for (the tangential acceleration steps); the caller's
limit check refuses such a profile, and `microfab.trajectory.optimal.time_optimal` plans
with jerk.
"""

from __future__ import annotations

import math

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.core.validate import check_positive
from microfab.geometry.path import Path
from microfab.trajectory.base import MAX_SAMPLES, Trajectory

__all__ = ["cruise"]

#: Share of each axis's acceleration limit given to the tangential part (the rest is for
#: the centripetal part). Assumed: an even split keeps both bounds simple.
TANGENTIAL_SHARE = 0.5
#: Relative room left below a limit when the sampled profile had to be slowed (assumed:
#: far above rounding, far below anything a user would notice, 1 ppm).
SLOWDOWN_MARGIN = 1e-6


def _bounds(
    path: Path, s: np.ndarray, limits: MachineLimits, speed: float
) -> tuple[np.ndarray, np.ndarray]:
    """Speed bound (m/s) and tangential acceleration bound (m/s²) at each ``s``.

    Each is the tighter of the values just before and at ``s``, so that a junction where
    the curvature jumps is bounded by both of its sides.
    """
    vmax = np.asarray(limits.velocity, dtype=float)
    amax = np.asarray(limits.acceleration, dtype=float)
    eps = 1e-9 * max(path.length, 1e-12)
    v_cap = np.full(s.size, speed)
    a_tan = np.full(s.size, np.inf)
    for side in (np.maximum(s - eps, 0.0), s):
        _, d1, d2 = path.evaluate(side, 2)
        t = np.abs(d1)
        c = np.abs(d2)
        with np.errstate(divide="ignore", over="ignore"):  # inf: no bound from there
            v_axis = np.min(np.where(t > 0, vmax / t, np.inf), axis=1)
            v_curv = np.min(
                np.where(c > 0, np.sqrt((1 - TANGENTIAL_SHARE) * amax / c), np.inf), axis=1
            )
            a_side = np.min(np.where(t > 0, TANGENTIAL_SHARE * amax / t, np.inf), axis=1)
        v_cap = np.minimum(v_cap, np.minimum(v_axis, v_curv))
        a_tan = np.minimum(a_tan, a_side)
    return v_cap, a_tan


def _profile(s: np.ndarray, v_cap: np.ndarray, a_tan: np.ndarray) -> np.ndarray:
    """Largest speeds under ``v_cap`` reachable with ``|s̈| <= a_tan`` (forward, backward).

    In ``w = ṡ²`` the forward pass is ``w[k+1] = min(cap[k+1], w[k] + 2 a_k Δs_k)``, a
    min-plus scan: ``w[k] = B[k] + min_{j<=k} (cap[j] - B[j])`` with ``B`` the running sum
    of ``2 a Δs``, so both passes are one ``minimum.accumulate`` each.
    """
    w_cap = v_cap**2
    step = 2.0 * np.minimum(a_tan[:-1], a_tan[1:]) * np.diff(s)
    fwd = np.concatenate([[0.0], np.cumsum(step)])
    w = fwd + np.minimum.accumulate(w_cap - fwd)
    bwd = np.concatenate([np.cumsum(step[::-1])[::-1], [0.0]])  # sum of the steps from k on
    w = bwd + np.minimum.accumulate((w - bwd)[::-1])[::-1]
    return np.sqrt(np.maximum(w, 0.0))


def _sample(
    path: Path, s: np.ndarray, v: np.ndarray, sample_rate_hz: float
) -> tuple[np.ndarray, ...]:
    """Sample the speed profile ``v`` at the knots ``s`` (constant s̈ between knots)."""
    ds = np.diff(s)
    dt_seg = 2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-300)  # constant s̈ on each piece
    t_knots = np.concatenate([[0.0], np.cumsum(dt_seg)])
    acc = np.where(dt_seg > 0, (v[1:] - v[:-1]) / np.where(dt_seg > 0, dt_seg, 1.0), 0.0)
    duration = float(t_knots[-1])
    n = max(math.ceil(duration * sample_rate_hz) + 1, 2)
    dt = duration / (n - 1)
    t = np.arange(n) * dt
    k = np.clip(np.searchsorted(t_knots, t, side="right") - 1, 0, ds.size - 1)
    tau = t - t_knots[k]
    sd = np.clip(v[k] + acc[k] * tau, 0.0, None)
    ss = np.minimum(s[k] + v[k] * tau + 0.5 * acc[k] * tau**2, s[k + 1])
    ss[-1] = s[-1]
    sd[-1] = 0.0
    sdd = acc[k]
    q, d1, d2, d3 = path.evaluate(ss, 3)
    return ss, sd, sdd, dt, q, d1, d2, d3


def _excess(vel: np.ndarray, acc: np.ndarray, jerk: np.ndarray, limits: MachineLimits) -> float:
    """The time scaling ``k >= 0`` that brings every axis within its limits (<= 1: none)."""
    k = 0.0
    for arr, bound, power in (
        (vel, limits.velocity, 1.0),
        (acc, limits.acceleration, 2.0),
        (jerk, limits.jerk, 3.0),
    ):
        b = np.asarray(bound, dtype=float)
        peak = np.max(np.abs(arr), axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(np.isfinite(b) & (b > 0), peak / b, 0.0)
        k = max(k, float(np.max(ratio)) ** (1.0 / power))
    return k


def cruise(
    path: Path,
    limits: MachineLimits,
    *,
    speed: float,
    sample_rate_hz: float,
    corner_tol: float = 1e-3,
    grid_points: int | None = None,
) -> Trajectory:
    """Trace ``path`` at ``speed`` where the limits allow, from rest to rest (module doc).

    Parameters
    ----------
    path : Path
        The target geometry, m; traced once (a closed path from its start back to it).
    limits : MachineLimits
        Declared per-axis velocity and acceleration limits (2 axes).
    speed : float
        Cruise path speed, m/s.
    sample_rate_hz : float
        Sample rate of the returned trajectory, Hz.
    corner_tol : float, optional
        Tangent turn above which a junction is a corner (the machine stops there), rad.
    grid_points : int, optional
        Points of the speed profile along the path (default: one per sample at full
        speed, at least 2 000, at most 20 000).

    Returns
    -------
    Trajectory
        ``at_rest=True``, sampled at ``sample_rate_hz`` (the last sample on the end of the
        path), with ``meta`` holding the cruise speed and the share of the time spent at
        it.

    Raises
    ------
    ValueError
        A non-positive speed or sample rate, a path of zero length, or more than
        `MAX_SAMPLES` samples.
    """
    check_positive("speed", speed, "m/s")
    check_positive("sample_rate_hz", sample_rate_hz, "Hz")
    length = path.length
    if not length > 0:
        raise ValueError("the path has zero length")
    # the path speed never exceeds the axes' velocity limits together (|v| <= |v_max|): the
    # samples at that top speed are a lower bound, known before any profile is computed
    # (with --speed alone a 1e-6 m/s velocity limit planned 8e7 samples for minutes)
    vmax = np.asarray(limits.velocity, dtype=float)
    vmax = vmax[np.isfinite(vmax) & (vmax > 0)]
    top = min(speed, float(np.linalg.norm(vmax))) if vmax.size else speed
    with np.errstate(over="ignore"):
        count = length / top * sample_rate_hz  # samples at full speed, a lower bound
    if not count <= MAX_SAMPLES:
        raise ValueError(
            f"tracing {length:.6g} m at {top:g} m/s and {sample_rate_hz:g} Hz takes more "
            f"than the {MAX_SAMPLES:,} samples a reference may hold: raise the speed or the "
            "velocity limits, or lower the sample rate"
        )
    if grid_points is None:
        grid_points = int(np.clip(math.ceil(length * sample_rate_hz / speed), 2000, 20_000))
    s = np.linspace(0.0, length, grid_points)
    stops = np.sort(path.corners(corner_tol))
    stops = stops[(stops > 0) & (stops < length)]
    if stops.size:
        # a uniform node within rounding of a stop would get zero speed too, and the
        # interval between the two an absurd time: drop nodes closer than spacing/4
        j = np.searchsorted(stops, s)
        gap = np.minimum(
            np.abs(s - stops[np.maximum(j - 1, 0)]),
            np.abs(stops[np.minimum(j, stops.size - 1)] - s),
        )
        keep = gap > 0.25 * length / (grid_points - 1)
        keep[[0, -1]] = True
        s = s[keep]
    s = np.unique(np.concatenate([s, stops]))
    # two stops (or a stop and an end) next to each other on the grid would leave an
    # interval that starts and ends at rest, whose time is infinite (stops closer than the
    # grid's spacing: a drawing of thousands of small contours): a node between them
    rest = np.isin(s, stops)
    rest[[0, -1]] = True
    both = np.flatnonzero(rest[:-1] & rest[1:])
    if both.size:
        s = np.unique(np.concatenate([s, 0.5 * (s[both] + s[both + 1])]))
    if path.closed:
        s[-1] = np.nextafter(length, 0.0)  # stay on the last segment
    v_cap, a_tan = _bounds(path, s, limits, speed)
    v_cap[0] = v_cap[-1] = 0.0
    v_cap[np.isin(s, stops)] = 0.0
    v = _profile(s, v_cap, a_tan)
    # The bounds hold at the grid nodes; between two nodes an axis' share of the tangent
    # (and the curvature) may be a little larger. Sample, measure the largest ratio of an
    # axis' velocity, acceleration or jerk to its limit, and if it is above 1 slow the
    # whole profile by it (a time scaling: velocity / k, acceleration / k², jerk / k³):
    # what is emitted is within the limits by construction, not by the guard's rounding
    # allowance.
    for _ in range(4):
        ss, sd, sdd, dt, q, d1, d2, d3 = _sample(path, s, v, sample_rate_hz)
        vel = sd[:, None] * d1
        acc = sdd[:, None] * d1 + (sd**2)[:, None] * d2
        jerk = (3.0 * sd * sdd)[:, None] * d2 + (sd**3)[:, None] * d3
        k = _excess(vel, acc, jerk, limits)
        if k <= 1.0:
            break
        v = v / (k * (1.0 + SLOWDOWN_MARGIN))
    at_speed = float(np.mean(sd >= 0.999 * speed))
    return Trajectory(
        dt=dt,
        position=q,
        velocity=vel,
        acceleration=acc,
        jerk=jerk,
        s=ss,
        at_rest=True,
        meta={
            "generator": "cruise",
            "speed_m_s": speed,
            "share_at_speed": at_speed,
            "corner_stops": int(stops.size),
        },
    )
