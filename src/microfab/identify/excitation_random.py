"""Seeded random motion for the black-box XY stage (seed 002 §III-C 1), within limits.

Seed 002 §III-C 1 identifies its linear model on "randomly generated trajectories, yielding
6×10⁶ points in total", "randomly changing the velocity, acceleration, and jerk" so that
they hold "curves of different radii, traversed at different speeds and appearing in
different locations within the workspace, as well as sharp transitions in acceleration and
jerk", "for a particular set of constraints on velocity and acceleration" (the seed's
range reaches 5 m/s², §III-D). The seed does not say how; this is our construction.

Construction (per axis, independently; both axes start at rest at the origin)
---------------------------------------------------------------------------
The acceleration is **piecewise linear and continuous**, so the jerk is piecewise
constant: a run is a list of segments ``(t_k, d_k, x_k, v_k, a_k, j_k)`` and the position
in a segment is the cubic ``x_k + v_k τ + a_k τ²/2 + j_k τ³/6``. At each knot a candidate
segment is drawn:

- its duration: with probability ``p_sharp`` a *sharp* one, log-uniform in
  ``sharp_s`` (0.5-5 ms: the acceleration swings by up to ``2 a_peak`` within a few
  samples, the seed's "sharp transitions in acceleration and jerk"), else log-uniform in
  ``slow_s`` (10-500 ms: curves, cruising, slow swings);
- its end acceleration: with probability ``p_bang`` exactly ``±a_peak`` (so the peak is
  reached often), else uniform in ``[-a_peak, a_peak]``.

``|a| ≤ a_peak`` holds by construction (a linear interpolation between knots within it).
The velocity cap and the workspace need feedback; a candidate is accepted only if

1. over the segment ``|v| ≤ v_cap`` and the position stays in the workspace less a
   margin (extrema in closed form: the velocity where ``a = 0``, the position where
   ``v = 0``), and
2. its end state is **safe**: the *brake* from there (`_brake_plan`: the acceleration
   ramped to 0 at jerk ``j_brake``, then a trapezoid or triangle of acceleration within
   ``a_peak`` that brings the velocity to 0 with the acceleration back at 0) stays within
   the same bounds.

The start (rest at the origin) is safe, and every accepted state is safe, so when none of
``n_try`` candidates is accepted the brake itself is executed (and ends at rest; at rest
already, a dwell is executed instead). An axis stops drawing once the brake from its state
plus the move home would end after the run's length (a candidate is refused when it
would); it brakes, then makes a quintic rest-to-rest move back to the origin
(`home_move`), the machine's rest position, so consecutive runs chain on a real machine.
A run is exactly ``round(run_s / dt)`` samples; an axis home early rests there.

Sampled at ``dt``, the first and second differences of the samples are weighted means of
the velocity and of the acceleration over one or two samples, so the sampled command
obeys the same bounds (what `microfab.core.limits.check_trajectory` checks).

Per run, the levels are drawn from the run's seed (`RandomDesign`): ``a_peak`` is
``a_max`` for half the runs and uniform in ``[0.2, 1] a_max`` for the rest (data at every
acceleration level up to ``a_max``, as Fig. 9 needs); ``v_cap`` log-uniform in
``v_range``; the brake's ramp time uniform in ``brake_ramp_s``.

The knot loop is a numba kernel (`random_axis_segments`); its ``py_func`` is the pure
Python reference (same draws from the same `numpy.random.Generator`), checked by the
tests. Sampling the segments is vectorised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from microfab.core.validate import check_in_range, check_int, check_positive

__all__ = [
    "HOME",
    "QUINTIC_ACC_PEAK",
    "QUINTIC_VEL_PEAK",
    "ROUNDING_ROOM",
    "RandomDesign",
    "draw_levels",
    "home_move",
    "quintic",
    "random_axis_segments",
    "random_command",
    "sample_segments",
]

#: Where every run starts and ends, m: the twin's rest position (``XYStagePlant.init``).
#: The knot loop works from and back to it, as the origin.
HOME = (0.0, 0.0)
#: Peak of ``q'(u)`` for the quintic ``q(u) = 10u³ − 15u⁴ + 6u⁵`` (at u = 1/2).
QUINTIC_VEL_PEAK = 1.875
#: Peak of ``|q''(u)|`` for the same quintic (at u = 1/2 ± √3/6): ``10/√3``.
QUINTIC_ACC_PEAK = 10.0 / math.sqrt(3.0)

#: Relative room left under ``a_peak`` and ``v_cap`` when planning: the sampled positions
#: carry ~1e-16 m of rounding, ~1e-7 m/s² in a second difference at 100 µs.
ROUNDING_ROOM = 1e-6

_N_SEG = 6  # columns of a segment row: t, duration, x, v, a, jerk


@dataclass(frozen=True, kw_only=True)
class RandomDesign:
    """How random runs are drawn (module docstring); all values assumed, see each.

    Parameters
    ----------
    run_s : tuple of float
        Range of a run's planned length, s (default 20-60 s: Fig. 6 shows runs of a few
        tens of seconds' worth of workspace crossings; assumed).
    v_max : float
        Largest velocity cap of a run, m/s (default Table I's 1.5 m/s; with 5 m/s² over
        the ±0.19 m workspace about 1.3 m/s is reachable).
    v_range_low : float
        Smallest velocity cap of a run, m/s (default 0.1 m/s, assumed: slow fine work).
    a_low_share : float
        Lowest ``a_peak / a_max`` of a run whose level is drawn (default 0.2, assumed).
    p_full : float
        Share of runs at ``a_peak = a_max`` (default 0.5, assumed).
    sharp_s, slow_s : tuple of float
        Duration ranges of sharp and slow segments, s (defaults 0.5-5 ms and 10-500 ms,
        assumed; log-uniform).
    p_sharp : float
        Probability of a sharp segment (default 0.2, assumed).
    p_bang : float
        Probability that a knot's acceleration is ``±a_peak`` (default 0.25, assumed).
    brake_ramp_s : tuple of float
        Range of the brake's acceleration ramp time, s (default 5-30 ms, assumed); the
        brake jerk is ``a_peak`` over it.
    margin_m : float
        Distance kept from the workspace's ends, m (default 5 mm, assumed).
    n_try : int
        Candidates drawn at a knot before braking (default 8, assumed).
    """

    run_s: tuple[float, float] = (20.0, 60.0)
    v_max: float = 1.5  # seed 002 Table I: maximum velocity 1.5 m/s
    v_range_low: float = 0.1
    a_low_share: float = 0.2
    p_full: float = 0.5
    sharp_s: tuple[float, float] = (0.5e-3, 5e-3)
    slow_s: tuple[float, float] = (10e-3, 0.5)
    p_sharp: float = 0.2
    p_bang: float = 0.25
    brake_ramp_s: tuple[float, float] = (5e-3, 30e-3)
    margin_m: float = 5e-3
    n_try: int = 8

    def __post_init__(self) -> None:
        for name, (lo, hi), unit in (
            ("run_s", self.run_s, "s"),
            ("sharp_s", self.sharp_s, "s"),
            ("slow_s", self.slow_s, "s"),
            ("brake_ramp_s", self.brake_ramp_s, "s"),
        ):
            check_positive(f"{name}[0]", lo, unit)
            check_positive(f"{name}[1]", hi, unit)
            if lo > hi:
                raise ValueError(
                    f"{name} must be (low, high) with low <= high, got {(lo, hi)} {unit}"
                )
        check_in_range("v_max", self.v_max, 0.0, 1.5, "m/s (seed 002 Table I)", low_closed=False)
        check_in_range("v_range_low", self.v_range_low, 0.0, self.v_max, "m/s", low_closed=False)
        check_in_range("a_low_share", self.a_low_share, 0.0, 1.0, "", low_closed=False)
        for name in ("p_full", "p_sharp", "p_bang"):
            check_in_range(name, getattr(self, name), 0.0, 1.0)
        check_in_range("margin_m", self.margin_m, 0.0, 0.05, "m")
        check_int("n_try", self.n_try, 1)


# --- the knot loop -------------------------------------------------------------------------


@njit(cache=True)
def _extrema(
    x: float, v: float, a: float, j: float, d: float
) -> tuple[float, float, float, float, float, float]:
    """End state and extrema over one constant-jerk segment.

    Returns ``(x1, v1, a1, x_min, x_max, |v|_max)`` for the segment of duration ``d`` (s)
    from ``(x, v, a)`` (m, m/s, m/s²) at jerk ``j`` (m/s³).
    """
    x1 = x + d * (v + d * (0.5 * a + d * j / 6.0))
    v1 = v + d * (a + 0.5 * d * j)
    a1 = a + d * j
    vmax = max(abs(v), abs(v1))
    xmin = min(x, x1)
    xmax = max(x, x1)
    if j != 0.0:
        ts = -a / j
        if 0.0 < ts < d:
            vmax = max(vmax, abs(v + ts * (a + 0.5 * ts * j)))
        disc = a * a - 2.0 * j * v  # roots of v + a t + j t²/2 (stable for tiny j)
        if disc >= 0.0:
            q = -0.5 * (a + math.copysign(math.sqrt(disc), a))
            r1 = 2.0 * q / j  # j != 0 here
            r2 = v / q if q != 0.0 else 0.0
            for t in (r1, r2):
                if 0.0 < t < d:
                    xt = x + t * (v + t * (0.5 * a + t * j / 6.0))
                    xmin = min(xmin, xt)
                    xmax = max(xmax, xt)
    elif a != 0.0:
        t = -v / a
        if 0.0 < t < d:
            xt = x + t * (v + 0.5 * t * a)
            xmin = min(xmin, xt)
            xmax = max(xmax, xt)
    return x1, v1, a1, xmin, xmax, vmax


@njit(cache=True)
def _brake_plan(v: float, a: float, jb: float, ab: float, out: np.ndarray) -> int:
    """The brake from ``(v, a)`` to rest: up to 4 ``(duration, jerk)`` rows into ``out``.

    The acceleration is ramped to 0 at jerk ``jb`` (m/s³), then a trapezoid (peak ``ab``,
    m/s²) or a triangle of acceleration against the velocity left brings it to 0.
    """
    m = 0
    if a != 0.0:
        tau = abs(a) / jb
        out[m, 0] = tau
        out[m, 1] = -jb if a > 0.0 else jb
        m += 1
        v = v + 0.5 * a * tau
    if v != 0.0:
        s = 1.0 if v > 0.0 else -1.0
        w = abs(v)
        if w >= ab * ab / jb:
            tr = ab / jb
            th = w / ab - tr
            out[m, 0] = tr
            out[m, 1] = -s * jb
            m += 1
            if th > 0.0:
                out[m, 0] = th
                out[m, 1] = 0.0
                m += 1
            out[m, 0] = tr
            out[m, 1] = s * jb
            m += 1
        else:
            tr = math.sqrt(w / jb)
            out[m, 0] = tr
            out[m, 1] = -s * jb
            out[m + 1, 0] = tr
            out[m + 1, 1] = s * jb
            m += 2
    return m


@njit(cache=True)
def _brake_ok(
    x: float,
    v: float,
    a: float,
    jb: float,
    ab: float,
    lo: float,
    hi: float,
    vcap: float,
    plan: np.ndarray,
) -> tuple[bool, float, float]:
    """Whether the brake from ``(x, v, a)`` stays in ``[lo, hi]`` and ``|v| <= vcap``.

    Also returns the brake's duration (s) and where it stops (m).
    """
    m = _brake_plan(v, a, jb, ab, plan)
    ok = True
    t = 0.0
    for i in range(m):
        d = plan[i, 0]
        x, v, a, xmin, xmax, vmx = _extrema(x, v, a, plan[i, 1], d)
        t += d
        if xmin < lo or xmax > hi or vmx > vcap:
            ok = False
    return ok, t, x


@njit(cache=True)
def _append(
    seg: np.ndarray, n: int, t: float, d: float, x: float, v: float, a: float, j: float
) -> int:
    seg[n, 0] = t
    seg[n, 1] = d
    seg[n, 2] = x
    seg[n, 3] = v
    seg[n, 4] = a
    seg[n, 5] = j
    return n + 1


@njit(cache=True)
def _home_time(x: float, vcap: float, ab: float) -> float:
    """Duration (s) of the quintic move from ``x`` (m) to 0 within ``vcap`` and ``ab``."""
    d = abs(x)
    return max(QUINTIC_VEL_PEAK * d / vcap, math.sqrt(QUINTIC_ACC_PEAK * d / ab))


@njit(cache=True)
def _execute_brake(
    seg: np.ndarray,
    n: int,
    t: float,
    x: float,
    v: float,
    a: float,
    jb: float,
    ab: float,
    plan: np.ndarray,
) -> tuple[int, float, float]:
    """Append the brake from ``(x, v, a)``; return rows used, the time and place at rest."""
    m = _brake_plan(v, a, jb, ab, plan)
    for i in range(m):
        n = _append(seg, n, t, plan[i, 0], x, v, a, plan[i, 1])
        x, v, a, _, _, _ = _extrema(x, v, a, plan[i, 1], plan[i, 0])
        t += plan[i, 0]
    return n, t, x


@njit(cache=True)
def random_axis_segments(
    rng: np.random.Generator,
    seg: np.ndarray,
    params: np.ndarray,
) -> tuple[int, float, float]:
    """Draw one axis's segments from rest at 0 until the planned end; then brake to rest.

    Parameters
    ----------
    rng : numpy.random.Generator
        The axis's generator (4 draws per candidate).
    seg : numpy.ndarray, shape (capacity, 6)
        Filled with ``(t, duration, x, v, a, jerk)`` rows (s, s, m, m/s, m/s², m/s³).
    params : numpy.ndarray, shape (13,)
        ``[run_s, a_peak, v_cap, j_brake, lo, hi, p_sharp, p_bang, sharp_lo, sharp_hi,
        slow_lo, slow_hi, n_try]`` in s, m/s², m/s, m/s³, m, m, -, -, s, s, s, s, -.

    Returns
    -------
    (int, float, float)
        Rows used, the time the axis is at rest (s) and where (m).
    """
    run_s, ab, vcap, jb, lo, hi = params[0], params[1], params[2], params[3], params[4], params[5]
    p_sharp, p_bang = params[6], params[7]
    l_sharp0, l_sharp1 = math.log(params[8]), math.log(params[9])
    l_slow0, l_slow1 = math.log(params[10]), math.log(params[11])
    n_try = int(params[12])
    cap = seg.shape[0] - 8
    plan = np.empty((4, 2))
    t = 0.0
    x = 0.0
    v = 0.0
    a = 0.0
    n = 0
    while n < cap:
        accepted = False
        late = False
        for _ in range(n_try):
            u_kind = rng.random()
            u_dur = rng.random()
            u_bang = rng.random()
            u_acc = rng.random()
            if u_kind < p_sharp:
                d = math.exp(l_sharp0 + (l_sharp1 - l_sharp0) * u_dur)
            else:
                d = math.exp(l_slow0 + (l_slow1 - l_slow0) * u_dur)
            if u_bang < p_bang:
                a1 = ab if u_acc >= 0.5 else -ab
            else:
                a1 = ab * (2.0 * u_acc - 1.0)
            j = (a1 - a) / d
            x1, v1, a1e, xmin, xmax, vmx = _extrema(x, v, a, j, d)
            if xmin < lo or xmax > hi or vmx > vcap:
                continue
            safe, tb, xb = _brake_ok(x1, v1, a1e, jb, ab, lo, hi, vcap, plan)
            if not safe:
                continue
            if t + d + tb + _home_time(xb, vcap, ab) > run_s:  # would not be home in time
                late = True
                continue
            n = _append(seg, n, t, d, x, v, a, j)
            t += d
            x, v, a = x1, v1, a1
            accepted = True
            break
        if accepted:
            continue
        if late:
            break
        if v == 0.0 and a == 0.0:  # at rest already: dwell
            d = math.exp(l_slow0 + (l_slow1 - l_slow0) * rng.random())
            if t + d + _home_time(x, vcap, ab) > run_s:
                break
            n = _append(seg, n, t, d, x, 0.0, 0.0, 0.0)
            t += d
        else:  # the brake from a safe state, which fits in time (checked when accepted)
            n, t, x = _execute_brake(seg, n, t, x, v, a, jb, ab, plan)
            v = 0.0
            a = 0.0
    n, t, x = _execute_brake(seg, n, t, x, v, a, jb, ab, plan)
    return n, t, x


# --- sampling --------------------------------------------------------------------------------


def quintic(u: np.ndarray) -> np.ndarray:
    """``10u³ − 15u⁴ + 6u⁵`` on ``u`` clipped to [0, 1]: rest to rest, zero end accelerations."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 + u * (-15.0 + 6.0 * u))


def home_move(distance_m: float, v_cap: float, a_cap: float) -> float:
    """Shortest duration (s) of a quintic move over ``distance_m`` within ``v_cap``, ``a_cap``."""
    d = abs(float(distance_m))
    return max(QUINTIC_VEL_PEAK * d / v_cap, math.sqrt(QUINTIC_ACC_PEAK * d / a_cap))


def sample_segments(seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Positions (m) of constant-jerk segments at times ``t`` (s); held after the last one.

    Parameters
    ----------
    seg : numpy.ndarray, shape (n, 6)
        Rows ``(t, duration, x, v, a, jerk)`` in time order, contiguous.
    t : numpy.ndarray, shape (m,)
        Sample times, s, from 0.
    """
    k = np.clip(np.searchsorted(seg[:, 0], t, side="right") - 1, 0, seg.shape[0] - 1)
    tau = np.minimum(t - seg[k, 0], seg[k, 1])  # hold at the end of the last segment
    return seg[k, 2] + tau * (seg[k, 3] + tau * (0.5 * seg[k, 4] + tau * seg[k, 5] / 6.0))


def draw_levels(rng: np.random.Generator, design: RandomDesign, a_max: float) -> dict[str, float]:
    """The run's levels: ``run_s``, ``a_peak``, ``v_cap``, ``brake_ramp_s`` (module doc)."""
    full = rng.random() < design.p_full
    share = 1.0 if full else rng.uniform(design.a_low_share, 1.0)
    lo, hi = design.run_s
    return {
        "run_s": float(rng.uniform(lo, hi)),
        "a_peak": float(a_max * share),
        "v_cap": float(math.exp(rng.uniform(math.log(design.v_range_low), math.log(design.v_max)))),
        "brake_ramp_s": float(rng.uniform(*design.brake_ramp_s)),
    }


def random_command(
    levels: dict[str, float],
    seed: int,
    *,
    design: RandomDesign,
    workspace: tuple[tuple[float, float], ...],
    dt: float,
    python: bool = False,
) -> tuple[np.ndarray, dict[str, float]]:
    """One random run's command, from rest at `HOME` back to rest there (module doc).

    Parameters
    ----------
    levels : dict
        ``run_s`` (s), ``a_peak`` (m/s²), ``v_cap`` (m/s), ``brake_ramp_s`` (s).
    seed : int
        The run's seed (one generator per axis is spawned from it).
    design : RandomDesign
        Segment durations, probabilities, margin, candidates.
    workspace : tuple of (float, float)
        Per-axis ``(min, max)``, m.
    dt : float
        Sample time, s.
    python : bool
        Run the knot loop's pure Python reference instead of the kernel.

    Returns
    -------
    (numpy.ndarray, dict)
        The command, shape (round(run_s / dt), 2), m; and facts about it per axis: its
        segments, when its home move starts (s) and its duration (s).
    """
    n_samples = max(round(levels["run_s"] / dt), 2)
    run_s = (n_samples - 1) * dt  # every axis is home by the last sample
    # plan a hair inside the levels: the samples' rounding (~1e-16 m) stays within them
    ab = levels["a_peak"] * (1.0 - ROUNDING_ROOM)
    vcap = levels["v_cap"] * (1.0 - ROUNDING_ROOM)
    jb = ab / levels["brake_ramp_s"]
    cap = math.ceil(run_s / design.sharp_s[0]) + 64
    fn = random_axis_segments.py_func if python else random_axis_segments
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)]
    t = np.arange(n_samples) * dt
    cmd = np.empty((n_samples, 2))
    facts: dict[str, float] = {}
    for k, rng in enumerate(rngs):
        lo, hi = workspace[k]
        params = np.array(
            [
                run_s,
                ab,
                vcap,
                jb,
                lo + design.margin_m,
                hi - design.margin_m,
                design.p_sharp,
                design.p_bang,
                *design.sharp_s,
                *design.slow_s,
                design.n_try,
            ],
            dtype=float,
        )
        seg = np.zeros((cap, _N_SEG))
        n, t_rest, x_rest = fn(rng, seg, params)
        cmd[:, k] = sample_segments(np.ascontiguousarray(seg[: max(n, 1)]), t)
        d_home = home_move(x_rest, vcap, ab)  # the kernel's `_home_time`
        if d_home > 0:
            back = t > t_rest
            cmd[back, k] = x_rest * (1.0 - quintic((t[back] - t_rest) / d_home))
        ax = "xy"[k]
        facts[f"segments_{ax}"] = float(n)
        facts[f"home_from_s_{ax}"] = float(t_rest)
        facts[f"home_move_s_{ax}"] = float(d_home)
    return cmd, facts
