"""RTC vector timing: how long a scan head takes for a list of jump and mark vectors.

A ScanLab RTC board (seed 003 part 2 ref. [9], the RTC5 manual) runs on a 10 µs clock (the
*tick*). A vector of length ``L`` at speed ``v`` is emitted as ``n = ceil(L / (v T))``
set-position steps, one per tick (we take equal steps ``L / n``: assumed, the RTC's exact
last step is not documented in the seed), and is followed by a wait:

* **jump** (laser off, jump speed), then the *jump delay*;
* **mark** (laser on, mark speed), then the *mark delay* before a jump, or the *polygon
  delay* before the next mark of a polyline (a corner; optionally *variable*: scaled by
  the turning angle φ as ``φ / 180°``, a linear ``load_varpolydelay`` table, assumed);
* **laser on / off delays**: the laser switches on ``laser_on`` after the first step of a
  polyline and off ``laser_off`` after its last step; they run in parallel to the motion
  and the mark delay and add no time (they decide *where* the laser switches, which
  `microfab.process.slm.estimate` reports as a position error);
* **sky-writing** (RTC5 ``set_sky_writing_para`` / ``_mode``; ``n_prev``, ``n_post`` in
  ticks): mode 1 gives every mark a run-in of ``2 n_prev`` ticks (a forerun back along the
  mark and the run-up to its start, laser off) and a run-out of ``2 n_post`` ticks (past
  the end and back), and drops the mark and polygon delays; modes 2 and 3 give each
  polyline a run-in of ``n_prev`` and a run-out of ``n_post`` ticks (no forerun or
  retrace: the jumps go from run-out ends to run-in starts), mode 2 at every corner too
  (a sky-writing jump between them), mode 3 only at corners turning by more than
  ``limit_angle_deg`` (the others get the polygon delay, laser on).

Every time is a whole number of ticks: a delay that is not is refused, naming the nearest
multiple. Positions are in bit of the scanner field (``bit_size_m`` per bit).

`rtc_timeline` turns a `VectorPath` (`microfab.process.slm.program`, re-exported here)
into a `Timeline`: straight *segments* (``p0 -> p1`` in ``n`` ticks, then ``hold`` ticks at
``p1``) with their category, the laser on/off instants and targets, the total time and its
breakdown; `Timeline.command` writes out the set positions tick by tick.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.validate import check_in_range, check_int, check_nonnegative, check_positive
from microfab.process.slm.program import VectorPath

__all__ = [
    "CATEGORIES",
    "TICK_S",
    "RTCDelays",
    "RTCSettings",
    "ScanSpeeds",
    "SkyWriting",
    "Timeline",
    "VectorPath",
    "rtc_timeline",
    "ticks",
]

#: The RTC clock period, s: seed 003 part 2 §2 "fs = 1e-5" read as the period (RTC5: 10 µs).
TICK_S = 1e-5

#: Categories of the time breakdown, in report order.
CATEGORIES = ("mark", "jump", "sky_writing", "jump_delay", "mark_delay", "polygon_delay")

# segment kinds and hold kinds (codes in the Timeline arrays)
MARK, JUMP, SKY = 0, 1, 2
NO_HOLD, JUMP_DELAY, MARK_DELAY, POLYGON_DELAY = 0, 1, 2, 3
_MOTION_CATEGORY = {MARK: "mark", JUMP: "jump", SKY: "sky_writing"}
_HOLD_CATEGORY = {
    JUMP_DELAY: "jump_delay",
    MARK_DELAY: "mark_delay",
    POLYGON_DELAY: "polygon_delay",
}
_ROUND = 1e-9  # relative slack of a tick count (L / (v T) = 33.0000000001 is 33 ticks)


def ticks(name: str, value_s: float, tick_s: float = TICK_S) -> int:
    """``value_s`` as a whole number of ticks; a time between two ticks is refused.

    Parameters
    ----------
    name : str
        Name of the time, for the message.
    value_s : float
        The time, s (>= 0).
    tick_s : float
        The tick, s.

    Returns
    -------
    int
        ``value_s / tick_s``.

    Raises
    ------
    ValueError
        When ``value_s`` is negative, not finite, or not a multiple of the tick (to 1e-6
        of a tick); the message names the nearest multiple.

    Examples
    --------
    >>> ticks("jump delay", 750e-6)
    75
    >>> ticks("jump delay", 250e-6)
    25

    ``ticks("jump delay", 755e-6)`` raises "jump delay = 755 µs is not a whole number of
    10 µs RTC ticks; the nearest is 750 µs (75 ticks) or 760 µs".
    """
    v = check_nonnegative(name, value_s, "s")
    k = v / tick_s
    near = round(k)
    if abs(k - near) > 1e-6:
        lo, hi = math.floor(k), math.ceil(k)
        best, other = (lo, hi) if k - lo <= hi - k else (hi, lo)
        raise ValueError(
            f"{name} = {v * 1e6:.6g} µs is not a whole number of {tick_s * 1e6:g} µs RTC "
            f"ticks; the nearest is {best * tick_s * 1e6:.6g} µs ({best} ticks) or "
            f"{other * tick_s * 1e6:.6g} µs"
        )
    return int(near)


#: Speeds accepted at the work plane, m/s. Assumed: galvo scanners mark and jump at mm/s to
#: tens of m/s; outside 0.1 mm/s to 1 km/s the value is in the wrong unit (and at 1e-300
#: m/s one vector's ticks overflow).
SPEED_RANGE_M_S = (1e-4, 1e3)


@dataclass(frozen=True, kw_only=True)
class ScanSpeeds:
    """Mark and jump speeds at the work plane.

    Parameters
    ----------
    mark_m_s : float
        Mark (scan) speed, m/s (0.6, assumed: the seed gives none; a usual SLM speed).
    jump_m_s : float
        Jump speed, m/s (5, assumed: the seed gives none; a usual galvo jump speed).
    """

    mark_m_s: float = 0.6  # assumed, see above
    jump_m_s: float = 5.0  # assumed, see above

    def __post_init__(self) -> None:
        lo, hi = SPEED_RANGE_M_S
        for name, v in (("mark speed mark_m_s", self.mark_m_s), ("jump speed jump_m_s",
                                                                  self.jump_m_s)):  # fmt: skip
            check_positive(name, v, "m/s")
            if not lo <= v <= hi:
                raise ValueError(
                    f"{name} = {v:g} m/s is outside {lo:g} to {hi:g} m/s (galvo scanners mark "
                    "and jump at mm/s to tens of m/s); check the unit"
                )


@dataclass(frozen=True, kw_only=True)
class RTCDelays:
    """The RTC's fixed waits, s, each a whole number of 10 µs ticks.

    Parameters
    ----------
    jump_s : float
        Jump delay after every jump (seed 003 part 2 §4: 750 µs without the input shaper,
        250 µs with it).
    mark_s : float
        Mark delay after the last mark of a polyline (assumed 500 µs: the twin's position
        lag is 454 µs, ``a1 / a0`` of the seed's model, so the mirror reaches the end of a
        mark about then, plus 50 µs).
    polygon_s : float
        Polygon delay at a polyline corner (assumed 50 µs).
    laser_on_s : float
        Laser on delay after the first step of a polyline (assumed 100 µs).
    laser_off_s : float
        Laser off delay after the last step of a polyline (assumed 450 µs: the twin's
        position lag rounded to ticks).
    variable_polygon : bool
        Scale the polygon delay by the turning angle, ``φ / 180°`` (rounded up to ticks).

    Raises
    ------
    ValueError
        On a negative time or one that is not a whole number of ticks (naming the nearest).
    """

    jump_s: float = 750e-6  # seed 003 part 2 §4 (without the shaper)
    mark_s: float = 500e-6  # assumed, see above
    polygon_s: float = 50e-6  # assumed
    laser_on_s: float = 100e-6  # assumed
    laser_off_s: float = 450e-6  # assumed, see above
    variable_polygon: bool = False

    def __post_init__(self) -> None:
        for name in ("jump_s", "mark_s", "polygon_s", "laser_on_s", "laser_off_s"):
            ticks(f"{name.removesuffix('_s').replace('_', ' ')} delay", getattr(self, name))
        if not isinstance(self.variable_polygon, bool):
            raise ValueError(
                f"variable_polygon must be true or false, got {self.variable_polygon!r}"
            )

    def in_ticks(self) -> dict[str, int]:
        """``{"jump": n, "mark": n, "polygon": n, "laser_on": n, "laser_off": n}`` in ticks."""
        return {
            k: ticks(k, getattr(self, f"{k}_s"))
            for k in ("jump", "mark", "polygon", "laser_on", "laser_off")
        }


@dataclass(frozen=True, kw_only=True)
class SkyWriting:
    """RTC sky-writing (RTC5 ``set_sky_writing_para`` and ``set_sky_writing_mode``).

    Parameters
    ----------
    mode : int
        0 off; 1, 2 or 3 (see the module doc).
    n_prev, n_post : int
        Run-in and run-out, ticks (>= 0; modes 2 and 3 use at least 1 each, as the RTC5).
    limit_angle_deg : float
        Mode 3: corners turning by more than this are sky-written, the others get the
        polygon delay, deg in [0, 180] (assumed default 30°).
    """

    mode: int = 0
    n_prev: int = 0
    n_post: int = 0
    limit_angle_deg: float = 30.0  # assumed

    def __post_init__(self) -> None:
        check_int("sky-writing mode", self.mode, 0)
        if self.mode > 3:
            raise ValueError(f"sky-writing mode must be 0, 1, 2 or 3, got {self.mode}")
        check_int("sky-writing n_prev", self.n_prev, 0, "ticks")
        check_int("sky-writing n_post", self.n_post, 0, "ticks")
        check_in_range("sky-writing limit_angle_deg", self.limit_angle_deg, 0.0, 180.0, "deg")

    @property
    def run_in(self) -> int:
        """Run-in ticks of this mode (RTC5: ``2 n_prev`` in mode 1, ``n_prev >= 1`` in 2, 3)."""
        return 2 * self.n_prev if self.mode == 1 else max(self.n_prev, 1)

    @property
    def run_out(self) -> int:
        """Run-out ticks of this mode (RTC5: ``2 n_post`` in mode 1, ``n_post >= 1`` in 2, 3)."""
        return 2 * self.n_post if self.mode == 1 else max(self.n_post, 1)


@dataclass(frozen=True, kw_only=True)
class RTCSettings:
    """Everything the RTC timing needs besides the vectors.

    Parameters
    ----------
    speeds : ScanSpeeds
        Mark and jump speeds.
    delays : RTCDelays
        Fixed delays.
    sky_writing : SkyWriting
        Sky-writing mode and run-in/out.
    bit_size_m : float
        One bit of the field at the work plane, m (1.5 µm, assumed as the twin's).
    """

    speeds: ScanSpeeds = field(default_factory=ScanSpeeds)
    delays: RTCDelays = field(default_factory=RTCDelays)
    sky_writing: SkyWriting = field(default_factory=SkyWriting)
    bit_size_m: float = 1.5e-6  # assumed, as data/galvo_slm.toml

    def __post_init__(self) -> None:
        parts = (("speeds", ScanSpeeds), ("delays", RTCDelays), ("sky_writing", SkyWriting))
        for name, cls in parts:
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"{name} must be a {cls.__name__}, got {getattr(self, name)!r}")
        check_positive("bit_size_m", self.bit_size_m, "m")

    def bit_per_tick(self, speed_m_s: float) -> float:
        """Distance per tick at ``speed_m_s``, bit."""
        return speed_m_s * TICK_S / self.bit_size_m

    def with_delays(self, **changes: Any) -> RTCSettings:
        """A copy with some `RTCDelays` fields replaced (validated)."""
        return replace(self, delays=replace(self.delays, **changes))


@dataclass(frozen=True, eq=False)
class Timeline:
    """Straight segments and the holds after them: the RTC's output for a `VectorPath`.

    Segment ``j`` moves the set position from ``p0[j]`` to ``p1[j]`` in ``n[j]`` equal steps
    (one per tick; the set position of its ``k``-th tick is ``p0 + (k + 1) / n (p1 - p0)``),
    then holds ``p1[j]`` for ``hold[j]`` ticks. It starts at tick ``start[j]``.

    Attributes
    ----------
    p0, p1 : numpy.ndarray
        Segment ends, bit, shape (m, 2).
    n, hold : numpy.ndarray
        Motion and hold ticks, int, shape (m,).
    kind : numpy.ndarray
        0 mark, 1 jump, 2 sky-writing motion (laser off), int8 (m,).
    hold_kind : numpy.ndarray
        0 none, 1 jump delay, 2 mark delay, 3 polygon delay, int8 (m,).
    vector : numpy.ndarray
        Index of the `VectorPath` vector each segment belongs to, int (m,).
    laser_on_tick, laser_off_tick : numpy.ndarray
        Ticks at which the laser switches on and off, int (k,) each.
    laser_on_target, laser_off_target : numpy.ndarray
        Where the beam should be then: the polyline's first and last point, bit (k, 2).
    laser_on_s, laser_off_s : float
        The laser delays the instants were placed with, s.
    """

    p0: np.ndarray
    p1: np.ndarray
    n: np.ndarray
    hold: np.ndarray
    kind: np.ndarray
    hold_kind: np.ndarray
    vector: np.ndarray
    laser_on_s: float = 0.0
    laser_off_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("p0", "p1"):
            object.__setattr__(self, name, readonly(getattr(self, name)).reshape(-1, 2))
        for name, dt in (
            ("n", np.int64),
            ("hold", np.int64),
            ("kind", np.int8),
            ("hold_kind", np.int8),
            ("vector", np.int64),
        ):
            object.__setattr__(self, name, readonly(getattr(self, name), dtype=dt).reshape(-1))
        m = self.p0.shape[0]
        names = ("p1", "n", "hold", "kind", "hold_kind", "vector")
        if any(getattr(self, k).shape[0] != m for k in names):
            raise ValueError("every segment array needs one entry per segment")
        if np.any(self.n < 0) or np.any(self.hold < 0):
            raise ValueError("motion and hold ticks must be >= 0")

    @property
    def n_segments(self) -> int:
        """Number of segments."""
        return int(self.n.size)

    @property
    def start(self) -> np.ndarray:
        """First tick of each segment, int (m,)."""
        s = np.zeros(self.n_segments, dtype=np.int64)
        np.cumsum((self.n + self.hold)[:-1], out=s[1:])
        return s

    @property
    def total_ticks(self) -> int:
        """All ticks of the program."""
        return int(self.n.sum() + self.hold.sum())

    @property
    def total_s(self) -> float:
        """Scan time, s."""
        return self.total_ticks * TICK_S

    def breakdown_s(self) -> dict[str, float]:
        """Time per category of `CATEGORIES`, s (they add up to `total_s`)."""
        out = dict.fromkeys(CATEGORIES, 0.0)
        for code, name in _MOTION_CATEGORY.items():
            out[name] += float(self.n[self.kind == code].sum()) * TICK_S
        for code, name in _HOLD_CATEGORY.items():
            out[name] += float(self.hold[self.hold_kind == code].sum()) * TICK_S
        return out

    def _laser_runs(self) -> tuple[np.ndarray, np.ndarray]:
        """Segment indices of the first and last mark of each laser-on run."""
        mk = self.kind == MARK
        prev = np.concatenate([[False], mk[:-1]])
        nxt = np.concatenate([mk[1:], [False]])
        return np.flatnonzero(mk & ~prev), np.flatnonzero(mk & ~nxt)

    @property
    def laser_on_tick(self) -> np.ndarray:
        """Tick of each laser switch-on (first step of a polyline + laser on delay)."""
        first, _ = self._laser_runs()
        return self.start[first] + ticks("laser on delay", self.laser_on_s)

    @property
    def laser_off_tick(self) -> np.ndarray:
        """Tick of each laser switch-off (after the last step of a polyline + laser off delay)."""
        _, last = self._laser_runs()
        return self.start[last] + self.n[last] + ticks("laser off delay", self.laser_off_s)

    @property
    def laser_on_target(self) -> np.ndarray:
        """First point of each polyline, bit (k, 2)."""
        return self.p0[self._laser_runs()[0]]

    @property
    def laser_off_target(self) -> np.ndarray:
        """Last point of each polyline, bit (k, 2)."""
        return self.p1[self._laser_runs()[1]]

    def with_holds(self, hold: np.ndarray) -> Timeline:
        """The same segments with other hold ticks (e.g. per-vector jump delays)."""
        return replace(self, hold=np.asarray(hold, dtype=np.int64))

    def command(self) -> np.ndarray:
        """The set positions tick by tick, bit, shape (total_ticks, 2).

        The tick ``k`` of segment ``j`` (``0 <= k < n + hold``) commands
        ``p0 + min((k + 1) / n, 1) (p1 - p0)``.
        """
        per = self.n + self.hold
        seg = np.repeat(np.arange(self.n_segments), per)
        k = np.arange(seg.size) - np.repeat(self.start, per)
        nn = self.n[seg]
        frac = np.minimum((k + 1) / np.maximum(nn, 1), 1.0)
        frac[nn == 0] = 1.0
        return self.p0[seg] + frac[:, None] * (self.p1[seg] - self.p0[seg])

    def summary(self) -> Mapping[str, float]:
        """Total and breakdown, s, and counts."""
        out: dict[str, float] = {"total_s": self.total_s, "n_segments": self.n_segments}
        out.update({f"{k}_s": v for k, v in self.breakdown_s().items()})
        return out


def _motion_ticks(length_bit: np.ndarray, bit_per_tick: float | np.ndarray) -> np.ndarray:
    """``ceil(L / (v T))`` per vector, a whole tick for a vector within rounding of one."""
    return np.ceil(length_bit / bit_per_tick * (1.0 - _ROUND)).astype(np.int64)


def _turn_deg(d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
    """Turning angle between unit directions, deg (0: straight on, 180: back)."""
    c = np.clip(np.einsum("ij,ij->i", d_in, d_out), -1.0, 1.0)
    return np.degrees(np.arccos(c))


def rtc_timeline(path: VectorPath, settings: RTCSettings | None = None) -> Timeline:
    """The RTC's segments, holds and laser instants for a scan program (module doc).

    Parameters
    ----------
    path : VectorPath
        The vectors, m.
    settings : RTCSettings, optional
        Speeds, delays and sky-writing (defaults: `RTCSettings()`).

    Returns
    -------
    Timeline
        In bit of the field; delays as given (see
        `microfab.process.slm.estimate.dynamics_estimate` for delays from the twin).
    """
    s = RTCSettings() if settings is None else settings
    d = s.delays.in_ticks()
    sky = s.sky_writing
    P = path.points / s.bit_size_m
    nv = len(path)
    if nv == 0:
        z = np.zeros(0)
        return Timeline(np.zeros((0, 2)), np.zeros((0, 2)), z, z, z, z, z)
    a, b = P[:-1], P[1:]
    vec = b - a
    L = np.hypot(*vec.T)
    u = np.divide(vec, L[:, None], out=np.zeros_like(vec), where=L[:, None] > 0)
    mark = path.is_mark
    nxt_mark = np.concatenate([mark[1:], [False]])
    prev_mark = np.concatenate([[False], mark[:-1]])
    # turning angle at the junction after each vector (to the next), for mark -> mark
    turn = np.zeros(nv)
    turn[:-1] = _turn_deg(u[:-1], u[1:])
    corner = mark & nxt_mark  # a polyline corner after this vector
    v_mark, v_jump = s.bit_per_tick(s.speeds.mark_m_s), s.bit_per_tick(s.speeds.jump_m_s)
    if sky.mode == 0:
        # one segment per vector
        hold = np.where(mark, np.where(corner, d["polygon"], d["mark"]), d["jump"])
        if s.delays.variable_polygon:
            hold = np.where(corner, np.ceil(d["polygon"] * turn / 180.0 - _ROUND), hold)
        hk = np.where(mark, np.where(corner, POLYGON_DELAY, MARK_DELAY), JUMP_DELAY)
        n = _motion_ticks(L, np.where(mark, v_mark, v_jump))
        return Timeline(
            a,
            b,
            n,
            hold.astype(np.int64),
            np.where(mark, MARK, JUMP),
            hk,
            np.arange(nv),
            s.delays.laser_on_s,
            s.delays.laser_off_s,
        )
    return _sky_timeline(path, s, a, b, u, L, mark, prev_mark, corner, turn, d, v_mark, v_jump)


def _sky_timeline(
    path: VectorPath,
    s: RTCSettings,
    a: np.ndarray,
    b: np.ndarray,
    u: np.ndarray,
    L: np.ndarray,
    mark: np.ndarray,
    prev_mark: np.ndarray,
    corner: np.ndarray,
    turn: np.ndarray,
    d: dict[str, int],
    v_mark: float,
    v_jump: float,
) -> Timeline:
    """`rtc_timeline` with sky-writing: each vector expands into up to 6 slots.

    Slots per vector: forerun (mode 1), run-in, the vector itself, run-out, retrace (mode
    1), and a sky-writing jump to the next mark's run-in (modes 2, 3 at a sky-written
    corner). Each slot's end point and tick count is computed for all vectors at once; a
    slot starts where the previous valid one ended.
    """
    sky = s.sky_writing
    nv = L.size
    mode1 = sky.mode == 1
    half_in = sky.n_prev if mode1 else sky.run_in  # ticks of the run-up along the mark
    half_out = sky.n_post if mode1 else sky.run_out
    # which corners are sky-written (mode 2: all, mode 3: turning more than the limit)
    sky_corner = corner & (True if sky.mode != 3 else turn > sky.limit_angle_deg)
    poly_corner = corner & ~sky_corner  # mode 3 small corners: polygon delay, laser on
    has_in = mark & (mode1 | ~prev_mark | np.concatenate([[False], sky_corner[:-1]]))
    has_out = mark & (mode1 | ~corner | sky_corner)
    d_in = u * (v_mark * half_in)  # run-in length along the mark, bit
    d_out = u * (v_mark * half_out)
    run_in_start = a - d_in
    run_out_end = b + d_out
    # the point each vector's main motion starts from (sky jumps go to the run-in start)
    nxt_has_in = np.concatenate([has_in[1:], [False]])
    nxt_start = np.vstack([run_in_start[1:], [[0.0, 0.0]]])
    main_end = np.where((~mark & nxt_has_in & (not mode1))[:, None], nxt_start, b)
    S = 6  # slots: forerun, run-in, main, run-out, retrace, sky jump
    end = np.zeros((nv, S, 2))
    nt = np.zeros((nv, S), dtype=np.int64)
    valid = np.zeros((nv, S), dtype=bool)
    kind = np.full((nv, S), SKY, dtype=np.int8)
    hold = np.zeros((nv, S), dtype=np.int64)
    hk = np.zeros((nv, S), dtype=np.int8)
    # 0 forerun (mode 1): from the mark start back to the run-in start
    valid[:, 0] = has_in & mode1
    end[:, 0], nt[:, 0] = run_in_start, sky.n_prev
    # 1 run-in: to the mark start (first vector's run-in starts where the scanner is)
    valid[:, 1] = has_in
    end[:, 1], nt[:, 1] = a, half_in
    # 2 the vector
    valid[:, 2] = True
    end[:, 2] = np.where(mark[:, None], b, main_end)
    kind[:, 2] = np.where(mark, MARK, JUMP)
    # 3 run-out past the end, 4 retrace (mode 1)
    valid[:, 3] = has_out
    end[:, 3], nt[:, 3] = run_out_end, half_out
    valid[:, 4] = has_out & mode1
    end[:, 4], nt[:, 4] = b, sky.n_post
    # 5 sky-writing jump from the run-out end to the next run-in start (modes 2, 3)
    valid[:, 5] = sky_corner & ~mode1
    end[:, 5] = nxt_start
    # holds: jump delay after jumps, polygon delay at unsky-written corners
    hold[:, 2] = np.where(mark, np.where(poly_corner, d["polygon"], 0), d["jump"])
    hk[:, 2] = np.where(mark, np.where(poly_corner, POLYGON_DELAY, NO_HOLD), JUMP_DELAY)
    if s.delays.variable_polygon:
        scaled = np.ceil(d["polygon"] * turn / 180.0 - _ROUND)
        hold[:, 2] = np.where(poly_corner, scaled, hold[:, 2])
    flat = valid.ravel()
    p1 = end.reshape(-1, 2)[flat]
    p0 = np.vstack([path.points[:1] / s.bit_size_m, p1[:-1]])
    n = nt.ravel()[flat]
    kd = kind.ravel()[flat]
    moving = (kd != SKY) | (np.repeat(np.arange(S)[None, :], nv, axis=0).ravel()[flat] == 5)
    speed = np.where(kd == MARK, v_mark, v_jump)
    n = np.where(moving, _motion_ticks(np.hypot(*(p1 - p0).T), speed), n)
    vector = np.repeat(np.arange(nv), S)[flat]
    return Timeline(
        p0,
        p1,
        n,
        hold.ravel()[flat],
        kd,
        hk.ravel()[flat],
        vector,
        s.delays.laser_on_s,
        s.delays.laser_off_s,
    )
