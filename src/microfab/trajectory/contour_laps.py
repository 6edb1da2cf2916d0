"""Drawing → time-based spline → sampled reference running laps of a closed contour.

Built for the laser-micromachining stage of seed 004 (its job, and the reference that
``microfab laser export`` writes for a real-time target), usable by any XY machine that
runs laps of a drawn contour. Seed 004 §IV.A: the drawing is parsed, its "coordinate data"
interpolated, and a time-based spline (eq. (1), `microfab.trajectory.spline.TimeSpline`)
turns the points into position, velocity and acceleration references for the controller.
The seed gives no speed, knot spacing or start-up; ours (assumed, stated here and in
`ContourMotion`):

* **Time law**: the stage rests on the contour, speeds up along it with the rate
  ``v (3τ² − 2τ³)`` over ``ramp_s`` (continuous acceleration, no jerk step at the joins),
  runs ``laps`` whole laps at the constant tangential speed ``v`` (the "constant
  tangential velocity" of seed 004 eq. (6)), slows down the same way and rests. Lap 1
  starts at the contour's start point when full speed is reached, so "after lap 1" is
  well defined; the ramps run over the contour before and after it.
* **Knots**: the spline passes through points of the exact contour at times of that law,
  one knot every ``knot_spacing_m`` of arc length at full speed (at most ``L / 64``
  apart; the ramps get the same time spacing). Measured on a 30 µm circle at 1 mm/s with
  1 µm knots: radius within 4 pm, tangential speed within 1e-8 inside a lap and 2e-5 at
  the joins with the ramps. End conditions: at rest (zero velocity and acceleration) at both ends.
* **Sampling**: at the controller's rate (10 kHz assumed, seed 004 gives none).

Corners: a time-based spline through a sharp corner at constant speed rounds it and needs
a large acceleration there; the limit check (`check_reference`) refuses what the stage
cannot do, naming axis, time, value and limit. Lower the speed or round the corners, or
run ``profile="limited"``: the laps are then planned by the project's time-optimal v/a/j
planner (`microfab.trajectory.optimal.time_optimal`) on the same path under Table I's
limits with the speed as a cap, so the stage keeps the requested speed where the limits
allow it and slows where they do not (at a sharp corner, to rest); it starts lap 1 from
rest at the contour's start point and rests after the last lap (no ramps over the
contour), and `ContourReference.slowdowns` says where and how much it slowed.
``profile="auto"`` keeps the constant speed when that reference is within the limits and
plans a limited one when it is not. The seed's own set-up (constant tangential speed,
eq. (6)) stays ``profile="constant"``, the default. At constant speed, the
rounding is the reference's own contour error, which no controller removes: on a 4 x 2 mm
rectangle at 1 mm/s it is 1.7 µm with 20 µm knots and 85 nm with 1 µm knots (the run's
largest contour error then 219 nm), so keep the knot spacing fine on drawings with
corners. How the contour correction hands its normal over at a corner (it fades out
with the speed and back in along the new normal) is in `microfab.control.contour`.

Limits checked before anything is emitted (seed 004 Table I): workspace (travel ±25 mm
assumed), speed 0.1 m/s, acceleration 5 m/s² (`MachineLimits.seed004_stage`, analytic
and sampled), and per axis the force the moving mass needs, ``M a``, against the 12 N
peak and its RMS over the whole reference against the 3 N continuous force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from microfab.core.limits import LimitViolation, MachineLimits, check_trajectory
from microfab.core.validate import check_int, check_nonnegative, check_positive
from microfab.geometry.path import Path
from microfab.trajectory.base import Trajectory
from microfab.trajectory.force_check import CONTINUOUS_FORCE_N, check_force
from microfab.trajectory.spline import TimeSpline

__all__ = [
    "PROFILES",
    "AccelerationLowered",
    "ContourMotion",
    "ContourReference",
    "Slowdown",
    "check_force",
    "check_reference",
    "contour_path",
    "contour_reference",
]

_MIN_KNOTS_PER_LAP = 64  # assumed: a coarser lap would show the spline's polygon
#: Most spline knots of one reference. Assumed bound of the work (the spline's banded solve
#: and its arrays grow with it; 1e6 knots: tens of MB): 1 µm knots allow 1 m of laps.
MAX_KNOTS = 1_000_000
MAX_ACCELERATION_M_S2 = 5.0  # seed 004 Table I (experiments/seed004_laser/paper.py)
#: How the laps are timed: "constant" (seed 004 eq. (6): constant tangential speed on the
#: time-based spline), "limited" (the v/a/j planner, the speed as a cap) or "auto"
#: (constant when that is within the limits, else limited).
PROFILES: tuple[str, ...] = ("constant", "limited", "auto")
#: Planner grid nodes per lap of a "limited" profile (corners are added; assumed: enough
#: that the 10 kHz samples between nodes stay within the limits on the test drawings).
_GRID_PER_LAP = 400
#: Most plans of a "limited" profile lowering the acceleration for the continuous force.
_FORCE_REPLANS = 6
#: Tangent turn that makes a junction a corner in the slow-down table, rad (assumed: a
#: milliradian, `microfab.geometry.path.Path.corners`' default).
_CORNER_ANGLE_RAD = 1e-3


@dataclass(frozen=True, kw_only=True)
class ContourMotion:
    """How the stage runs a closed contour (all assumed: seed 004 gives no speeds).

    Parameters
    ----------
    speed_m_s : float
        Tangential speed ``v`` on the laps, m/s (default 1 mm/s, issue 15's Fig. 3 speed).
    laps : int
        Whole laps at full speed (>= 1).
    ramp_s : float or None
        Duration of the speed-up and of the slow-down, s; default
        ``max(0.02 s, 3 v / (a_max / 2))`` with a_max = 5 m/s² (seed 004 Table I): the
        ramp then needs at most half the acceleration limit along the path.
    rest_s : float
        Rest before the ramp and after the slow-down, s (default 10 ms: the loop settles
        on the first point; the end rest shows the final error).
    knot_spacing_m : float
        Arc length between spline knots at full speed, m (default 1 µm; at most L/64).
    sample_rate_hz : float
        Controller rate, Hz (default 10 kHz, assumed: Ts = 100 µs).
    profile : {"constant", "limited", "auto"}
        ``"constant"``: the seed's constant tangential speed (eq. (6)); ``"limited"``: the
        v/a/j planner with ``speed_m_s`` as a cap (slows at corners; ``ramp_s`` and
        ``knot_spacing_m`` are then unused); ``"auto"``: constant when that reference is
        within the kinematic limits, else limited (the reference's ``motion`` says which).
    """

    speed_m_s: float = 1e-3
    laps: int = 3
    ramp_s: float | None = None
    rest_s: float = 0.01
    knot_spacing_m: float = 1e-6
    sample_rate_hz: float = 1e4
    profile: Literal["constant", "limited", "auto"] = "constant"

    def __post_init__(self) -> None:
        check_positive("speed_m_s", self.speed_m_s, "m/s")
        check_int("laps", self.laps, 1, "laps")
        if self.ramp_s is not None:
            check_positive("ramp_s", self.ramp_s, "s")
        check_nonnegative("rest_s", self.rest_s, "s")
        check_positive("knot_spacing_m", self.knot_spacing_m, "m")
        check_positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {', '.join(PROFILES)}, got {self.profile!r}")

    @property
    def ramp(self) -> float:
        """The ramp duration used, s."""
        if self.ramp_s is not None:
            return self.ramp_s
        return max(0.02, 3.0 * self.speed_m_s / (0.5 * MAX_ACCELERATION_M_S2))


@dataclass(frozen=True, kw_only=True)
class Slowdown:
    """One stretch of lap 1 that ran slower than the requested speed.

    Attributes
    ----------
    at_m : float
        Arc length from the start point at the stretch's slowest sample, m.
    speed_m_s : float
        The slowest speed there, m/s.
    corners : tuple of int
        The drawing's corners inside the stretch, numbered from 1 along the path from the
        start point (`corner_numbers`), in the order the stage meets them. Two or more:
        the corners are closer than the speed allows (the stage did not get back to
        speed between them). Empty: a slow-down on a curve, or the start from rest on a
        smooth contour.
    from_rest : bool
        The stretch holds the start of lap 1 from rest (or the stop after it).
    """

    at_m: float
    speed_m_s: float
    corners: tuple[int, ...] = ()
    from_rest: bool = False


@dataclass(frozen=True, kw_only=True)
class AccelerationLowered:
    """The acceleration a "limited" plan lowered to keep Table I's continuous force.

    Attributes
    ----------
    asked_m_s2 : float
        The acceleration limit planned first (Table I's 5 m/s²).
    used_m_s2 : float
        The limit of the plan used, m/s².
    axis : str
        The axis whose RMS force passed the continuous force at ``asked_m_s2``.
    asked_rms_force_n : float
        That axis's RMS force ``M a`` over the plan at ``asked_m_s2``, N.
    used_rms_force_n : float
        Its RMS force over the plan used, N.
    continuous_force_n : float
        The continuous force it is held to (Table I: 3 N).
    plans : int
        Plans made (the first included).
    """

    asked_m_s2: float
    used_m_s2: float
    axis: str
    asked_rms_force_n: float
    used_rms_force_n: float
    continuous_force_n: float
    plans: int


@dataclass(frozen=True, kw_only=True, eq=False)
class ContourReference:
    """A sampled reference along a closed contour.

    Attributes
    ----------
    path : Path
        The exact contour, m.
    motion : ContourMotion
        How it is run.
    spline : TimeSpline
        The time-based spline (seed 004 eq. (1); for a "limited" profile the planner's).
    trajectory : Trajectory
        Samples at ``motion.sample_rate_hz``: position (m), velocity (m/s), acceleration
        (m/s²), shape (n, 2); ``trajectory.s`` the arc length along the contour (m,
        unwrapped: it grows past L on later laps; negative during the speed-up).
    lap_starts, lap_ends : numpy.ndarray
        Sample index where each lap starts and where it ends (exclusive), shape (laps,);
        at constant speed every lap has the same number of samples.
    acceleration_lowered : AccelerationLowered or None
        What a "limited" plan lowered for the continuous force (None: nothing lowered).
    """

    path: Path
    motion: ContourMotion
    spline: TimeSpline
    trajectory: Trajectory
    lap_starts: np.ndarray
    lap_ends: np.ndarray
    acceleration_lowered: AccelerationLowered | None = None

    @property
    def lap_samples(self) -> int:
        """Samples of the first lap (of every lap at constant speed)."""
        return int(self.lap_ends[0] - self.lap_starts[0])

    @property
    def laps(self) -> slice:
        """Samples from the start of the first lap to the end of the last."""
        return slice(int(self.lap_starts[0]), int(self.lap_ends[-1]))

    def corner_positions(self) -> np.ndarray:
        """Arc length of the drawing's corners from the start point, m, ascending.

        Corner ``k`` of `Slowdown.corners` is entry ``k - 1`` (the start point, when it is
        a corner, is corner 1).
        """
        return np.sort(np.asarray(self.path.corners(_CORNER_ANGLE_RAD), dtype=float))

    def slowdowns(self, below: float = 0.9) -> list[Slowdown]:
        """Where lap 1 ran slower than the requested speed, how slow, and at which corners.

        Parameters
        ----------
        below : float
            A sample counts as slowed below ``below`` times the requested speed (0.9:
            the planner runs 1 % under its cap, its spline wavers a little).

        Returns
        -------
        list of Slowdown
            One per stretch of lap 1 that ran slower, in the order of the lap (a stretch
            over the end of the lap and its start is one, listed first); empty at
            constant speed. Every corner of the drawing the stage slowed at is named
            in exactly one of them; corners closer than the speed allows share one.
        """
        sl = self.lap(0)
        v = np.hypot(*np.asarray(self.trajectory.velocity)[sl].T)
        s = np.asarray(self.trajectory.s)[sl] if self.trajectory.s is not None else None
        slow = v < below * self.motion.speed_m_s
        if s is None or not slow.any():
            return []
        arc = s - s[0]
        length = float(self.path.length)
        corners = self.corner_positions()
        # a corner belongs to a stretch that reaches it to within a hundredth of a sample's
        # travel at the requested speed (assumed: the samples straddle every corner)
        tol = 0.01 * self.motion.speed_m_s * self.dt + 1e-12 * length
        edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
        spans = [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
        wrap = len(spans) > 1 and slow[0] and slow[-1]

        def inside(a: int, b: int) -> list[int]:
            lo, hi = arc[a] - tol, arc[b - 1] + tol
            return [k + 1 for k, c in enumerate(corners) if lo <= c <= hi or lo <= c + length <= hi]

        starts_at_rest = self.motion.profile == "limited"  # lap 1 starts from rest (notes)
        out: list[Slowdown] = []
        for a, b in spans:
            k = a + int(np.argmin(v[a:b]))
            out.append(Slowdown(at_m=float(arc[k]), speed_m_s=float(v[k]),
                                corners=tuple(inside(a, b)),
                                from_rest=starts_at_rest and a == 0))  # fmt: skip
        if wrap:  # the lap wraps: the stretch at its end and the one at its start are one
            last, first = out.pop(), out[0]
            slowest = last if last.speed_m_s < first.speed_m_s else first
            named = tuple(dict.fromkeys(last.corners + first.corners))
            out[0] = Slowdown(
                at_m=0.0 if slowest is last else first.at_m,
                speed_m_s=slowest.speed_m_s,
                corners=named,
                from_rest=first.from_rest,
            )
        return out

    @property
    def dt(self) -> float:
        """Sample time, s."""
        return float(self.trajectory.dt)

    def lap(self, i: int) -> slice:
        """Samples of lap ``i`` (from 0)."""
        return slice(int(self.lap_starts[i]), int(self.lap_ends[i]))


def _time_law(motion: ContourMotion, length: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Knot times (s) and arc lengths (m, unwrapped) of the time law; lap-1 start time."""
    v, tr = motion.speed_m_s, motion.ramp
    ramp_len = 0.5 * v * tr  # ∫ v (3τ² − 2τ³) dt over the ramp
    cruise = motion.laps * length / v
    dt_k = min(motion.knot_spacing_m, length / _MIN_KNOTS_PER_LAP) / v
    t0 = motion.rest_s
    t1 = t0 + tr  # lap 1 starts (s = 0)
    t2 = t1 + cruise
    t3 = t2 + tr
    with np.errstate(over="ignore"):
        n_knots = 2 * tr / dt_k + cruise / dt_k
    if not n_knots <= MAX_KNOTS:
        least = (2 * tr * v + motion.laps * length) / MAX_KNOTS
        raise ValueError(
            f"knot_spacing_m = {motion.knot_spacing_m:g} m gives {n_knots:.3g} spline knots "
            f"over the laps and ramps; the most is {MAX_KNOTS:.0e}: choose at least "
            f"{least:.3g} m (knot_spacing_um = {least * 1e6:.3g} in a job file)"
        )
    n_r = max(math.ceil(tr / dt_k), 3)
    n_c = max(math.ceil(cruise / dt_k), 2)

    def up(tau: np.ndarray) -> np.ndarray:  # ∫ (3τ² − 2τ³) dτ, τ in [0, 1]
        return tau**3 - 0.5 * tau**4

    tau_r = np.linspace(0.0, 1.0, n_r + 1)
    t_up = t0 + tau_r * tr
    s_up = -ramp_len + v * tr * up(tau_r)
    t_cr = np.linspace(t1, t2, n_c + 1)[1:]
    s_cr = v * (t_cr - t1)
    t_dn = t2 + tau_r[1:] * tr
    s_dn = motion.laps * length + v * tr * (tau_r[1:] - up(tau_r[1:]))
    t = np.concatenate([[0.0] if t0 > 0 else [], t_up, t_cr, t_dn])
    s = np.concatenate([[-ramp_len] if t0 > 0 else [], s_up, s_cr, s_dn])
    if motion.rest_s > 0:
        t = np.append(t, t3 + motion.rest_s)
        s = np.append(s, s[-1])
    return t, s, t1


def contour_path(drawing: str, contour: int = 0) -> Path:
    """Closed contour number ``contour`` of a drawing source (m).

    Parameters
    ----------
    drawing : str
        A drawing source for `microfab.geometry.load.load_drawing` (a DXF/SVG file or a
        shape such as ``circle:radius=30e-6``), m.
    contour : int
        Which closed contour, in the drawing's order, from 0.

    Raises
    ------
    ValueError
        When the drawing has no closed contour, or fewer than ``contour + 1``.
    """
    from microfab.geometry.load import load_drawing

    closed = load_drawing(drawing).closed
    if not closed:
        raise ValueError(f"the drawing {drawing!r} has no closed contour to run")
    check_int("contour", contour, 0)
    if contour >= len(closed):
        raise ValueError(
            f"the drawing {drawing!r} has {len(closed)} closed contour(s); contour = "
            f"{contour} does not exist (count from 0)"
        )
    return closed[contour]


def contour_reference(
    path: Path,
    motion: ContourMotion | None = None,
    masses_kg: tuple[float, float] | None = None,
) -> ContourReference:
    """The sampled reference that runs ``motion.laps`` laps of a closed contour.

    Parameters
    ----------
    path : Path
        A closed contour, m.
    motion : ContourMotion, optional
        Speed, laps, ramps, knots, rate (defaults: see `ContourMotion`).
    masses_kg : tuple of float, optional
        Moving mass per axis, kg. A "limited" profile then also keeps the RMS force
        within Table I's 3 N continuous force (it plans with a lower acceleration until
        it does), and "auto" checks the constant reference's forces too.

    Returns
    -------
    ContourReference

    Raises
    ------
    ValueError
        If the path is not closed.
    """
    m = motion or ContourMotion()
    if not path.closed:
        raise ValueError(
            "the seed 004 reference runs laps of a closed contour; this path is open "
            "(close it in the drawing, or pick a closed contour)"
        )
    if m.profile == "auto":
        ref = contour_reference(path, replace(m, profile="constant"))
        try:
            if masses_kg is None:
                check_trajectory(ref.trajectory, MachineLimits.seed004_stage())
            else:
                check_reference(ref, MachineLimits.seed004_stage(), masses_kg)
        except LimitViolation:
            return _limited_reference(path, replace(m, profile="limited"), masses_kg)
        return ref
    if m.profile == "limited":
        return _limited_reference(path, m, masses_kg)
    L = float(path.length)
    t, s, t1 = _time_law(m, L)
    pts = path.point(np.mod(s, L))
    # rest at the ends: two equal points in a row are a rest, which the "rest" spline
    # cannot take (its first and last intervals get the extra breakpoints); drop the
    # duplicated rest knots and hold the ends by the spline's own end conditions.
    keep = np.ones(t.size, dtype=bool)
    if m.rest_s > 0:
        keep[0] = keep[-1] = False
    spline = TimeSpline.fit(t[keep], pts[keep], bc="rest", axes=("x", "y"))
    traj = spline.sample(m.sample_rate_hz, s_knots=s[keep], s_times=t[keep])
    if m.rest_s > 0:
        traj = _pad_rest(traj, m.rest_s)
    dt = float(traj.dt)
    lap_samples = round(L / m.speed_m_s / dt)
    first = round(t1 / dt)
    starts = first + np.round(np.arange(m.laps) * L / m.speed_m_s / dt).astype(np.int64)
    return ContourReference(
        path=path,
        motion=m,
        spline=spline,
        trajectory=traj,
        lap_starts=starts,
        lap_ends=starts + int(lap_samples),
    )


def _limited_reference(
    path: Path, m: ContourMotion, masses_kg: tuple[float, float] | None = None
) -> ContourReference:
    """The laps planned by the v/a/j planner under Table I, ``m.speed_m_s`` as a cap.

    With ``masses_kg``, a plan whose RMS force on an axis passes the continuous force is
    planned again with the acceleration limit lowered by the square of the excess (the
    RMS of a corner-bound plan grows about as the square root of its acceleration).
    """
    from microfab.geometry.path import concatenate
    from microfab.trajectory.optimal import PlanningError, time_optimal

    L = float(path.length)
    laps = concatenate([path] * m.laps)
    table = MachineLimits.seed004_stage()
    accel = MAX_ACCELERATION_M_S2
    first: tuple[int, float] | None = None  # axis and RMS force of the first plan, if too high
    rms = np.zeros(2)
    plans = 0
    used = accel
    for _ in range(_FORCE_REPLANS):
        plans += 1
        used = accel
        limits = replace(table, acceleration=(accel, accel))
        try:
            res = time_optimal(
                laps,
                limits,
                n_grid=_GRID_PER_LAP * m.laps,
                sample_rate_hz=m.sample_rate_hz,
                feed=m.speed_m_s,
            )
        except PlanningError as exc:
            raise ValueError(f"the limited profile could not be planned: {exc}") from exc
        if masses_kg is None:
            break
        acc = np.asarray(res.trajectory.acceleration)
        rms = np.sqrt(np.mean((acc * np.asarray(masses_kg)) ** 2, axis=0))
        excess = float(np.max(rms)) / CONTINUOUS_FORCE_N
        if excess <= 1.0:
            break
        if first is None:
            first = (int(np.argmax(rms)), float(np.max(rms)))
        accel *= 0.95 / excess**2
    traj = res.trajectory
    s = np.asarray(traj.s)
    # lap i runs from the first sample at or past i L to the first at or past (i + 1) L
    bounds = np.searchsorted(s, np.arange(m.laps + 1) * L * (1 - 1e-12), side="left")
    if m.rest_s > 0:
        bounds = bounds + round(m.rest_s * m.sample_rate_hz)
        traj = _pad_rest(traj, m.rest_s)
    return ContourReference(
        path=path,
        motion=m,
        spline=res.spline,
        trajectory=traj,
        lap_starts=bounds[:-1].astype(np.int64),
        lap_ends=bounds[1:].astype(np.int64),
        acceleration_lowered=None
        if first is None
        else AccelerationLowered(
            asked_m_s2=MAX_ACCELERATION_M_S2,
            used_m_s2=used,
            axis="xy"[first[0]],
            asked_rms_force_n=first[1],
            used_rms_force_n=float(rms[first[0]]),
            continuous_force_n=CONTINUOUS_FORCE_N,
            plans=plans,
        ),
    )


def _pad_rest(traj: Trajectory, rest_s: float) -> Trajectory:
    """``traj`` (starting at ``rest_s``) with the rests before and after it sampled."""
    dt = float(traj.dt)
    n = round(rest_s / dt)
    pos = np.asarray(traj.position)
    z = np.zeros((n, pos.shape[1]))

    def pad(a: np.ndarray | None, first: np.ndarray, last: np.ndarray) -> np.ndarray | None:
        if a is None:
            return None
        return np.concatenate([np.broadcast_to(first, (n, *a.shape[1:])), a,
                               np.broadcast_to(last, (n, *a.shape[1:]))])  # fmt: skip

    s = None if traj.s is None else pad(np.asarray(traj.s), traj.s[0], traj.s[-1])
    return Trajectory(
        dt=dt,
        position=pad(pos, pos[0], pos[-1]),
        velocity=pad(traj.velocity, z[0], z[0]),
        acceleration=pad(traj.acceleration, z[0], z[0]),
        jerk=pad(traj.jerk, z[0], z[0]),
        axes=traj.axes,
        at_rest=True,
        s=s,
    )


def check_reference(
    ref: ContourReference, limits: MachineLimits, masses_kg: tuple[float, float]
) -> None:
    """All the limit checks of the module notes on a reference (raises `LimitViolation`)."""
    check_trajectory(ref.trajectory, limits)
    assert ref.trajectory.acceleration is not None
    check_force(ref.trajectory.acceleration, masses_kg, ref.dt)
