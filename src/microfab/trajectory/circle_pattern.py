"""The circle-field pattern as a reference: circles in a field, each after a move and a pause.

The job of the seed 001 nanomanipulator (§4.2): `microfab nanomanipulator analyze` checks
a measured trace against it, and the nanomanipulator job, its controller comparisons and
its calibration run it on the twin.

The stage starts at rest at the field centre. For each circle it moves to the circle's start
point (a minimum-jerk move, assumed: the seed shows no transfer), pauses (seed 001 §4.2:
"there is a pause before fabricating every circle", so the contour error starts from zero),
then spins up, runs the circle for a number of periods (counter-clockwise, angle 0 at the
first period's first sample) and spins down. Positions are
in mm (the twin's unit); `PatternReference.trajectory` gives the same in m for the limit
check of `microfab.core.limits.check_trajectory`. The seed's numbers are those of seed 001
(``shared/seeds/001_44fdd8e8f587fd7f.txt``), each with its section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microfab.core.signals import period_samples
from microfab.core.validate import check_in_range, check_int, check_positive
from microfab.trajectory.base import Trajectory

__all__ = [
    "MAX_PATTERN_SAMPLES",
    "PatternConfig",
    "PatternReference",
    "circle_centres",
    "pattern_reference",
]

#: Most samples a whole pattern may hold (1e8: about 3 h at 10 kHz, 12 GiB of position,
#: velocity and acceleration); checked from the durations before anything is allocated.
MAX_PATTERN_SAMPLES = 1e8

N_CIRCLES = 4  # seed 001 §4.2: four circle patterns in one operation
CIRCLE_DIAMETER_MM = 0.15  # seed 001 §4.2: circular contour of diameter 0.15 mm
FIELD_MM = 0.5  # seed 001 §4.2: working range of the manipulator about 0.5 mm
TRAVEL_MM = 1.5  # seed 001 §2: working range up to ±1.5 mm per axis


@dataclass(frozen=True, kw_only=True)
class PatternConfig:
    """The circles of a job.

    Parameters
    ----------
    n_circles : int
        Circles (seed 001 §4.2: four), placed on a grid filling the field.
    diameter_mm : float
        Circle diameter, mm (seed 001 §4.2: 0.15 mm).
    field_mm : float
        Side of the square field the circles fill, mm (seed 001 §4.2: about 0.5 mm).
    period_s : float
        Time per circle, s (assumed 1 s: the seed gives no speed; 0.47 mm/s on the 0.15 mm
        circle).
    periods : int
        Periods run per circle (the gate needs a converged period, then exposes one).
    pause_s : float
        Pause at the start point before each circle, s (assumed 0.2 s).
    move_s : float
        Duration of the minimum-jerk move to each circle's start point, s (assumed 0.3 s).
    ramp_s : float
        Spin-up before the first period and spin-down after the last, s (assumed 0.25 s:
        the seed's circle starts from a pause; a ramp keeps the reference's acceleration
        finite).
    """

    n_circles: int = N_CIRCLES
    diameter_mm: float = CIRCLE_DIAMETER_MM
    field_mm: float = FIELD_MM
    period_s: float = 1.0
    periods: int = 6
    pause_s: float = 0.2
    move_s: float = 0.3
    ramp_s: float = 0.25

    def __post_init__(self) -> None:
        check_int("n_circles", self.n_circles, 1, "circles")
        check_positive("diameter_mm", self.diameter_mm, "mm")
        check_in_range("field_mm", self.field_mm, self.diameter_mm, 2 * TRAVEL_MM, "mm")
        check_positive("period_s", self.period_s, "s")
        check_int("periods", self.periods, 1, "periods")
        check_positive("pause_s", self.pause_s, "s")
        check_positive("move_s", self.move_s, "s")
        check_positive("ramp_s", self.ramp_s, "s")


def circle_centres(config: PatternConfig) -> np.ndarray:
    """Centres of the circles, mm, shape (n_circles, 2): a near-square grid in the field.

    With four circles of 0.15 mm in a 0.5 mm field the centres are (±0.175, ±0.175) mm, so
    the circles touch the field's edges.
    """
    n = config.n_circles
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    free = config.field_mm - config.diameter_mm

    def spots(m: int) -> np.ndarray:
        return np.zeros(1) if m == 1 else np.linspace(-free / 2, free / 2, m)

    xs, ys = spots(cols), spots(rows)[::-1]
    grid = [(x, y) for y in ys for x in xs]
    return np.array(grid[:n], dtype=float)


@dataclass(frozen=True, kw_only=True, eq=False)
class PatternReference:
    """A job's reference and where its circles lie in it.

    Attributes
    ----------
    dt : float
        Sample time, s.
    position, velocity, acceleration : numpy.ndarray
        Reference, mm, mm/s, mm/s², shape (n_samples, 2).
    centres : numpy.ndarray
        Circle centres, mm, shape (n_circles, 2).
    radius_mm : float
        Circle radius, mm.
    period_samples : int
        Samples per circle period.
    starts : tuple of int
        First sample of each circle's first period.
    periods : int
        Periods per circle.
    """

    dt: float
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    centres: np.ndarray
    radius_mm: float
    period_samples: int
    starts: tuple[int, ...]
    periods: int

    @property
    def n_samples(self) -> int:
        """Samples in the job."""
        return int(self.position.shape[0])

    @property
    def windows(self) -> tuple[tuple[int, int], ...]:
        """``(first sample, periods)`` of each circle (the RC's active windows)."""
        return tuple((s, self.periods) for s in self.starts)

    def circle_slice(self, i: int) -> slice:
        """Samples of circle ``i`` (all its periods)."""
        s = self.starts[i]
        return slice(s, s + self.periods * self.period_samples)

    def trajectory(self) -> Trajectory:
        """The reference in m (for `check_trajectory`), at rest before and after."""
        return Trajectory(
            dt=self.dt,
            position=self.position * 1e-3,
            velocity=self.velocity * 1e-3,
            acceleration=self.acceleration * 1e-3,
            axes=("x", "y"),
            at_rest=True,
        )


def _min_jerk(p0: np.ndarray, p1: np.ndarray, n: int, dt: float) -> tuple[np.ndarray, ...]:
    """A rest-to-rest quintic move over ``n`` samples: position, velocity, acceleration."""
    T = n * dt
    tau = np.arange(n) / n
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    ds = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / T
    dds = (60 * tau - 180 * tau**2 + 120 * tau**3) / T**2
    d = (p1 - p0)[None, :]
    return p0[None, :] + s[:, None] * d, ds[:, None] * d, dds[:, None] * d


def _spin(w: float, n_ramp: int, n_run: int, dt: float) -> tuple[np.ndarray, ...]:
    """Angle, rate and angular acceleration: spin-up, ``n_run`` samples at ``w``, spin-down.

    The rate follows ``w (3τ² − 2τ³)`` over each ramp (continuous acceleration at the
    joins), and the angle is 0 at the first sample at full rate.
    """
    Tr = n_ramp * dt
    tau = np.arange(n_ramp) / n_ramp
    up = 3 * tau**2 - 2 * tau**3
    d_up = (6 * tau - 6 * tau**2) / Tr
    i_up = (tau**3 - tau**4 / 2) * Tr  # ∫ up dt from 0
    rate = np.concatenate([w * up, np.full(n_run, w), w * (1.0 - up)])
    accel = np.concatenate([w * d_up, np.zeros(n_run), -w * d_up])
    run_angle = w * np.arange(n_run) * dt
    ramp_angle = w * Tr / 2  # ∫ of the whole ramp
    down = n_run * w * dt + w * (tau * Tr - i_up)
    angle = np.concatenate([w * i_up - ramp_angle, run_angle, down])
    return angle, rate, accel


def pattern_reference(config: PatternConfig, dt: float) -> PatternReference:
    """The whole job's reference: move, pause and circle, for every circle.

    Parameters
    ----------
    config : PatternConfig
        The circles.
    dt : float
        Sample time, s; the period must be a whole number of samples.

    Raises
    ------
    ValueError
        When the period is not a whole number of samples (the repetitive controller's
        memory needs one), or a duration is shorter than a sample.
    """
    check_positive("dt", dt, "s")
    n_period = period_samples(config.period_s, dt)  # the RC's memory needs whole samples
    per_circle = (config.move_s + config.pause_s + 2 * config.ramp_s) / dt + (
        n_period * config.periods
    )
    total = config.n_circles * per_circle
    if not total <= MAX_PATTERN_SAMPLES:
        raise ValueError(
            f"the pattern would be {total:.3g} samples ({config.n_circles} circles of "
            f"{per_circle:.3g}); the most is {MAX_PATTERN_SAMPLES:.0e}: fewer circles or "
            "periods, or shorter moves, pauses and ramps"
        )
    n_move = max(round(config.move_s / dt), 1)
    n_pause = max(round(config.pause_s / dt), 1)
    n_ramp = max(round(config.ramp_s / dt), 1)
    R = config.diameter_mm / 2
    w = 2 * math.pi / config.period_s
    theta, dtheta, ddtheta = _spin(w, n_ramp, n_period * config.periods, dt)
    pos, vel, acc, starts = [], [], [], []
    here = np.zeros(2)
    count = 0
    centres = circle_centres(config)
    radial = np.column_stack([np.cos(theta), np.sin(theta)])  # the same for every circle
    tangent = np.column_stack([-radial[:, 1], radial[:, 0]])
    ring_v = R * dtheta[:, None] * tangent
    ring_a = R * ddtheta[:, None] * tangent - (R * dtheta**2)[:, None] * radial
    z = np.zeros((n_pause, 2))
    for c in centres:
        ring = c[None, :] + R * radial
        p, v, a = _min_jerk(here, ring[0], n_move, dt)
        hold = np.repeat(ring[:1], n_pause, axis=0)
        pos += [p, hold, ring]
        vel += [v, z, ring_v]
        acc += [a, z, ring_a]
        starts.append(count + n_move + n_pause + n_ramp)
        count += n_move + n_pause + ring.shape[0]
        here = ring[-1]
    end = np.repeat(here[None, :], n_pause, axis=0)
    pos.append(end)
    vel.append(np.zeros_like(end))
    acc.append(np.zeros_like(end))
    return PatternReference(
        dt=dt,
        position=np.vstack(pos),
        velocity=np.vstack(vel),
        acceleration=np.vstack(acc),
        centres=centres,
        radius_mm=R,
        period_samples=n_period,
        starts=tuple(starts),
        periods=config.periods,
    )
