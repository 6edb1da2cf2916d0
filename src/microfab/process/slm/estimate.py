"""Scan time of an SLM layer three ways, with breakdowns (seed 003 part 2 §4).

* `naive_estimate`: ``Σ L / v`` over marks and jumps, optionally a jump delay per jump (as
  PySLM's ``getLayerTime``): no ticks, no dynamics.
* `fixed_delay_estimate`: the RTC timing (`microfab.process.slm.timing.rtc_timeline`):
  whole ticks per vector, fixed jump, mark and polygon delays (the seed's jump delays: 750
  µs without its input shaper, 250 µs with it, §4), sky-writing.
* `dynamics_estimate`: the same RTC timing with each jump delay replaced by the shortest
  one after which the twin's calibrated position stays within a tolerance of the jump's
  end (`SettleTolerance`: 2 % of the jump length, assumed), found by exact propagation of
  the axis model over every segment (`microfab.process.slm.propagate`; equal to a
  per-sample simulation to round-off), and the position error at every laser on and off.

The axis model is the twin's (`microfab.plants.galvo_slm.GalvoSLMPlant.axis_model`), or the
model seen through a command filter (`series`, e.g. the seed's input shaper in front of
the twin). Errors are of the *calibrated* position ``y / G(0)``: the seed's model has
``G(0) = 0.9764``, which the scanner's field calibration takes out (assumed), so that a
settled scanner sits on its set position.

`implied_jumps` reads the seed's totals: 4686 s -> 4219 s for a jump delay cut from 750 to
250 µs imply 9.34e5 jumps and a 14.95 % share of jump delay in the unshaped build.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from microfab.control.setpoint import SetPoint
from microfab.core.validate import check_nonnegative, check_positive
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI, block_diag
from microfab.process.slm.program import VectorPath
from microfab.process.slm.propagate import Propagation, propagate
from microfab.process.slm.timing import (
    CATEGORIES,
    JUMP,
    JUMP_DELAY,
    TICK_S,
    RTCSettings,
    ScanSpeeds,
    Timeline,
    rtc_timeline,
    ticks,
)
from microfab.sim.loop import LoopState, simulate
from microfab.sim.result import SimResult

__all__ = [
    "ImpliedJumps",
    "ScanTimeComparison",
    "ScanTimeEstimate",
    "SettleTolerance",
    "axis_model_of",
    "dynamics_estimate",
    "estimate_scan_time",
    "estimate_with_shaper",
    "fixed_delay_estimate",
    "implied_jumps",
    "jump_delay",
    "naive_estimate",
    "series",
    "simulate_timeline",
]

# seed 003 part 2 §4: total scan time of the lattice bunny and the jump delays
SEED_TOTAL_UNSHAPED_S = 4686.0
SEED_TOTAL_SHAPED_S = 4219.0
SEED_JUMP_DELAY_UNSHAPED_S = 750e-6
SEED_JUMP_DELAY_SHAPED_S = 250e-6


@dataclass(frozen=True, kw_only=True)
class SettleTolerance:
    """When a jump has settled: the calibrated error stays within ``max(relative L, absolute)``.

    Parameters
    ----------
    relative : float
        Fraction of the jump length ``L`` (assumed 2 %: the seed gives no criterion).
    absolute_bit : float
        Floor, bit (assumed 1 bit, the set-position resolution), so that a very short jump
        does not wait for sub-bit settling.
    """

    relative: float = 0.02  # assumed, see above
    absolute_bit: float = 1.0  # assumed, see above

    def __post_init__(self) -> None:
        check_nonnegative("settling tolerance relative", self.relative)
        check_nonnegative("settling tolerance absolute_bit", self.absolute_bit, "bit")
        if self.relative == 0 and self.absolute_bit == 0:
            raise ValueError("settling tolerance: give a positive relative or absolute_bit")

    def of(self, length_bit: np.ndarray) -> np.ndarray:
        """Tolerance for jumps of ``length_bit`` (bit), bit."""
        return np.maximum(self.relative * np.asarray(length_bit, float), self.absolute_bit)


@dataclass(frozen=True, eq=False)
class ScanTimeEstimate:
    """One scan-time estimate and its breakdown.

    Attributes
    ----------
    method : str
        ``"naive"``, ``"fixed delays"`` or ``"dynamics-aware"``.
    total_s : float
        Scan time, s.
    breakdown_s : dict of str to float
        Time per category of `microfab.process.slm.timing.CATEGORIES`, s (sums to total).
    n_marks, n_jumps : int
        Vectors of the program.
    timeline : Timeline or None
        The RTC segments (not for the naive estimate).
    jump_delay_s : numpy.ndarray or None
        Delay after each jump vector as run, s (RTC estimates).
    laser_on_error_bit, laser_off_error_bit : numpy.ndarray or None
        Calibrated position minus target at every laser switch-on / off, bit, shape (k, 2)
        (when a model was given).
    """

    method: str
    total_s: float
    breakdown_s: Mapping[str, float]
    n_marks: int
    n_jumps: int
    timeline: Timeline | None = None
    jump_delay_s: np.ndarray | None = None
    laser_on_error_bit: np.ndarray | None = None
    laser_off_error_bit: np.ndarray | None = None

    def share(self, category: str) -> float:
        """Fraction of the total spent in ``category``."""
        if category not in self.breakdown_s:
            raise ValueError(f"unknown category {category!r}; known: {', '.join(CATEGORIES)}")
        return self.breakdown_s[category] / self.total_s if self.total_s > 0 else 0.0

    def rows(self) -> list[tuple[str, float, float]]:
        """``(category, seconds, share)`` per category, then ``("total", total_s, 1)``."""
        out = [(c, float(self.breakdown_s[c]), self.share(c)) for c in CATEGORIES]
        return [*out, ("total", self.total_s, 1.0)]

    def summary(self) -> dict[str, Any]:
        """JSON-ready: method, totals, breakdown and the largest laser on/off errors."""
        out: dict[str, Any] = {
            "method": self.method,
            "total_s": self.total_s,
            "n_marks": self.n_marks,
            "n_jumps": self.n_jumps,
            "breakdown_s": dict(self.breakdown_s),
        }
        if self.jump_delay_s is not None and self.jump_delay_s.size:
            out["mean_jump_delay_s"] = float(self.jump_delay_s.mean())
        for name in ("laser_on_error_bit", "laser_off_error_bit"):
            err = getattr(self, name)
            if err is not None and err.size:
                out[f"max_{name}"] = float(np.hypot(*err.T).max())
        return out


@dataclass(frozen=True, eq=False)
class ScanTimeComparison:
    """The three estimates of one layer (`estimate_scan_time`)."""

    naive: ScanTimeEstimate
    fixed: ScanTimeEstimate
    dynamics: ScanTimeEstimate

    def table(self) -> list[tuple[str, float, float, float]]:
        """``(category, naive s, fixed s, dynamics s)`` per category and the total."""
        rows = [
            (c, self.naive.breakdown_s[c], self.fixed.breakdown_s[c], self.dynamics.breakdown_s[c])
            for c in CATEGORIES
        ]
        return [*rows, ("total", self.naive.total_s, self.fixed.total_s, self.dynamics.total_s)]


@dataclass(frozen=True)
class ImpliedJumps:
    """What two total scan times and two jump delays imply (`implied_jumps`).

    Attributes
    ----------
    n_jumps : float
        ``(T_before - T_after) / (d_before - d_after)``.
    delay_share : float
        Jump-delay share of ``T_before``: ``n_jumps d_before / T_before``.
    """

    n_jumps: float
    delay_share: float


def implied_jumps(
    total_before_s: float = SEED_TOTAL_UNSHAPED_S,
    total_after_s: float = SEED_TOTAL_SHAPED_S,
    delay_before_s: float = SEED_JUMP_DELAY_UNSHAPED_S,
    delay_after_s: float = SEED_JUMP_DELAY_SHAPED_S,
) -> ImpliedJumps:
    """Jumps and jump-delay share implied by a scan time cut by a shorter jump delay.

    If only the jump delay changed (seed 003 part 2 §4: 750 -> 250 µs, 4686 -> 4219 s),
    the build held ``(4686 - 4219) / 500e-6 = 9.34e5`` jumps, and jump delays were
    ``9.34e5 * 750e-6 / 4686 = 14.95 %`` of its time.
    """
    tb = check_positive("total_before_s", total_before_s, "s")
    ta = check_nonnegative("total_after_s", total_after_s, "s")
    db = check_positive("delay_before_s", delay_before_s, "s")
    da = check_nonnegative("delay_after_s", delay_after_s, "s")
    if not db > da:
        raise ValueError(f"delay_before_s ({db} s) must exceed delay_after_s ({da} s)")
    n = (tb - ta) / (db - da)
    return ImpliedJumps(n_jumps=n, delay_share=n * db / tb)


def axis_model_of(model: Any, settings: RTCSettings | None = None) -> DiscreteLTI:
    """A SISO axis model from a `DiscreteLTI`, or a twin's ``axis_model`` (a galvo plant).

    Raises
    ------
    ValueError
        When ``model`` is neither, or the twin's bit differs from ``settings.bit_size_m``
        or its sample time from the 10 µs tick.
    """
    if settings is not None:
        bit = getattr(getattr(model, "config", None), "bit_size_m", settings.bit_size_m)
        if abs(bit - settings.bit_size_m) > 1e-12 * bit:
            raise ValueError(
                f"the twin's bit is {bit} m but the RTC settings' bit_size_m is "
                f"{settings.bit_size_m} m; give the settings the twin's bit"
            )
    if isinstance(model, DiscreteLTI):
        if abs(model.dt - TICK_S) > 1e-12 * TICK_S:
            raise ValueError(
                f"the axis model's sample time is {model.dt} s; the RTC runs on {TICK_S} s ticks"
            )
        return model
    axis = getattr(model, "axis_model", None)
    if isinstance(axis, DiscreteLTI):
        return axis_model_of(axis)
    raise ValueError(
        f"give the axis model as a DiscreteLTI or a twin with an axis_model, got "
        f"{type(model).__name__}"
    )


def series(prefilter: DiscreteLTI, axis: DiscreteLTI) -> DiscreteLTI:
    """``axis ∘ prefilter``: a command filter (e.g. an input shaper) in front of the axis.

    Parameters
    ----------
    prefilter : DiscreteLTI
        SISO command filter (feed-through allowed), same sample time.
    axis : DiscreteLTI
        SISO, strictly proper axis model.

    Returns
    -------
    DiscreteLTI
        States ``[filter, axis]``; strictly proper.
    """
    if abs(prefilter.dt - axis.dt) > 1e-12 * axis.dt:
        raise ValueError(f"sample times differ: filter {prefilter.dt} s, axis {axis.dt} s")
    nf, na = prefilter.n_states, axis.n_states
    A = np.block([[prefilter.A, np.zeros((nf, na))], [axis.B @ prefilter.C, axis.A]])
    B = np.vstack([prefilter.B, axis.B @ prefilter.D])
    C = np.hstack([axis.D @ prefilter.C, axis.C])
    D = axis.D @ prefilter.D
    return DiscreteLTI(A, B, C, D, axis.dt)


def naive_estimate(
    path: VectorPath, speeds: ScanSpeeds | None = None, *, jump_delay_s: float = 0.0
) -> ScanTimeEstimate:
    """``Σ L / v`` of marks and jumps (+ a jump delay per jump), as PySLM's ``getLayerTime``.

    Parameters
    ----------
    path : VectorPath
        The program, m.
    speeds : ScanSpeeds, optional
        Mark and jump speeds (default `ScanSpeeds()`).
    jump_delay_s : float
        Added once per jump, s (default 0).
    """
    sp = ScanSpeeds() if speeds is None else speeds
    jd = check_nonnegative("jump_delay_s", jump_delay_s, "s")
    L = path.lengths
    br = dict.fromkeys(CATEGORIES, 0.0)
    br["mark"] = float(L[path.is_mark].sum()) / sp.mark_m_s
    br["jump"] = float(L[~path.is_mark].sum()) / sp.jump_m_s
    br["jump_delay"] = path.n_jumps * jd
    return ScanTimeEstimate("naive", sum(br.values()), br, path.n_marks, path.n_jumps)


def _laser_errors(prop: Propagation, tl: Timeline) -> tuple[np.ndarray, np.ndarray]:
    on = prop.positions(tl.laser_on_tick) - tl.laser_on_target
    off = prop.positions(tl.laser_off_tick) - tl.laser_off_target
    return on, off


def _extra(tl: Timeline) -> int:
    return max(ticks("laser on", tl.laser_on_s), ticks("laser off", tl.laser_off_s))


def fixed_delay_estimate(
    path: VectorPath, settings: RTCSettings | None = None, model: Any = None
) -> ScanTimeEstimate:
    """The RTC timing with the fixed delays of ``settings`` (module doc).

    Parameters
    ----------
    path : VectorPath
        The program, m.
    settings : RTCSettings, optional
        Speeds, delays, sky-writing (default `RTCSettings()`: jump delay 750 µs).
    model : DiscreteLTI or twin, optional
        When given, the laser on/off position errors on it are reported too.
    """
    s = RTCSettings() if settings is None else settings
    tl = rtc_timeline(path, s)
    on = off = None
    if model is not None and tl.n_segments:
        prop = propagate(
            axis_model_of(model, s), tl.p0, tl.p1, tl.n, tl.hold, extra_ticks=_extra(tl)
        )
        on, off = _laser_errors(prop, tl)
    jd = tl.hold[tl.kind == JUMP] * TICK_S
    return ScanTimeEstimate(
        "fixed delays", tl.total_s, tl.breakdown_s(), path.n_marks, path.n_jumps, tl, jd, on, off
    )


def dynamics_estimate(
    path: VectorPath,
    model: Any,
    settings: RTCSettings | None = None,
    *,
    tolerance: SettleTolerance | None = None,
    delays: Literal["per_vector", "worst_case"] = "per_vector",
) -> ScanTimeEstimate:
    """The RTC timing with jump delays the shortest the twin allows.

    Parameters
    ----------
    path : VectorPath
        The program, m.
    model : DiscreteLTI or twin
        SISO axis model (set position -> position, bit), e.g. the twin's ``axis_model`` or
        `series` of a shaper and it.
    settings : RTCSettings, optional
        Speeds, the other delays, sky-writing (the jump delay given there is replaced).
    tolerance : SettleTolerance, optional
        Settling band (default 2 % of the jump length, at least 1 bit).
    delays : {"per_vector", "worst_case"}
        ``"per_vector"``: each jump waits its own shortest delay. ``"worst_case"``: one
        fixed jump delay for all, the shortest that lets every jump settle when all wait
        it (the largest per-vector delay, raised until no jump needs more).

    Returns
    -------
    ScanTimeEstimate
        With the delay per jump and the laser on/off errors.
    """
    s = RTCSettings() if settings is None else settings
    tol = SettleTolerance() if tolerance is None else tolerance
    if delays not in ("per_vector", "worst_case"):
        raise ValueError(f"delays must be 'per_vector' or 'worst_case', got {delays!r}")
    method = "dynamics-aware" if delays == "per_vector" else "dynamics-aware, worst case"
    tl = rtc_timeline(path, s)
    if tl.n_segments == 0:
        return ScanTimeEstimate(method, 0.0, dict.fromkeys(CATEGORIES, 0.0), 0, 0, tl)
    settle = tl.hold_kind == JUMP_DELAY
    band = tol.of(np.hypot(*(tl.p1 - tl.p0).T))  # per segment, from its own length
    axis = axis_model_of(model, s)
    extra = _extra(tl)
    prop = propagate(axis, tl.p0, tl.p1, tl.n, tl.hold, settle, band, extra_ticks=extra)
    if delays == "worst_case" and np.any(settle):
        d = int(prop.required[settle].max())
        for _ in range(100):  # waiting longer calms the next jumps' starts: a few rounds
            hold = np.where(settle, d, tl.hold)
            prop = propagate(
                axis, tl.p0, tl.p1, tl.n, hold, settle, band, extra_ticks=extra, apply=False
            )
            need = int(prop.required[settle].max())
            if need <= d:
                break
            d = need
        else:
            raise RuntimeError(f"no fixed jump delay found for all jumps (last tried {d} ticks)")
    tl = tl.with_holds(prop.hold)
    on, off = _laser_errors(prop, tl)
    jd = tl.hold[tl.kind == JUMP] * TICK_S
    return ScanTimeEstimate(
        method, tl.total_s, tl.breakdown_s(), path.n_marks, path.n_jumps, tl, jd, on, off
    )


def estimate_scan_time(
    path: VectorPath,
    model: Any,
    settings: RTCSettings | None = None,
    *,
    tolerance: SettleTolerance | None = None,
    naive_jump_delay: bool = False,
) -> ScanTimeComparison:
    """The three estimates of one program (module doc).

    Parameters
    ----------
    path, model, settings, tolerance
        As for `dynamics_estimate`; the fixed estimate uses ``settings`` as given.
    naive_jump_delay : bool
        Add the fixed jump delay to the naive estimate (PySLM's option).
    """
    s = RTCSettings() if settings is None else settings
    jd = s.delays.jump_s if naive_jump_delay else 0.0
    return ScanTimeComparison(
        naive=naive_estimate(path, s.speeds, jump_delay_s=jd),
        fixed=fixed_delay_estimate(path, s, model),
        dynamics=dynamics_estimate(path, model, s, tolerance=tolerance),
    )


def estimate_with_shaper(
    path: VectorPath,
    model: Any,
    settings: RTCSettings | None = None,
    *,
    prefilter: DiscreteLTI | None = None,
    shaped_settings: RTCSettings | None = None,
    tolerance: SettleTolerance | None = None,
    naive_jump_delay: bool = False,
) -> dict[str, ScanTimeComparison]:
    """The three estimates of one program without and with a command filter in front.

    Parameters
    ----------
    path, model, settings, tolerance, naive_jump_delay
        As for `estimate_scan_time` (the unshaped estimates).
    prefilter : DiscreteLTI, optional
        The shaper as a sampled filter at the 10 µs tick; None: no shaped estimates.
    shaped_settings : RTCSettings, optional
        The settings of the shaped estimates (e.g. the shaper's shorter fixed jump delay);
        ``settings`` when omitted.

    Returns
    -------
    dict of str to ScanTimeComparison
        ``"unshaped"``, and ``"shaped"`` (the axis behind ``prefilter``) when one is given.
    """
    opts: dict[str, Any] = {"tolerance": tolerance, "naive_jump_delay": naive_jump_delay}
    runs = {"unshaped": estimate_scan_time(path, model, settings, **opts)}
    if prefilter is not None:
        shaped = series(prefilter, axis_model_of(model))
        again = settings if shaped_settings is None else shaped_settings
        runs["shaped"] = estimate_scan_time(path, shaped, again, **opts)
    return runs


def jump_delay(
    model: Any,
    length_m: float,
    *,
    speed_m_s: float | None = None,
    settings: RTCSettings | None = None,
    tolerance: SettleTolerance | None = None,
) -> float:
    """The shortest jump delay after one jump of ``length_m`` from rest, s.

    Parameters
    ----------
    model : DiscreteLTI or twin
        SISO axis model.
    length_m : float
        Jump length, m (along x).
    speed_m_s : float, optional
        Jump speed (default: that of ``settings``, 5 m/s).
    settings : RTCSettings, optional
        For the speed and the bit size.
    tolerance : SettleTolerance, optional
        Settling band (default 2 % of the length).
    """
    s = RTCSettings() if settings is None else settings
    if speed_m_s is not None:
        speeds = ScanSpeeds(mark_m_s=s.speeds.mark_m_s, jump_m_s=speed_m_s)
        s = replace(s, speeds=speeds)
    L = check_positive("length_m", length_m, "m")
    path = VectorPath(np.array([[0.0, 0.0], [L, 0.0]]), np.array([False]))
    est = dynamics_estimate(path, model, s, tolerance=tolerance)
    assert est.jump_delay_s is not None
    return float(est.jump_delay_s[0])


def simulate_timeline(timeline: Timeline, model: Any) -> SimResult:
    """The per-sample simulation of a timeline's set positions on ``model`` (both axes).

    The compiled loop of `microfab.sim.loop.simulate` runs `microfab.plants.base.LTIPlant`
    of the axis model twice (block-diagonal) under `microfab.control.setpoint.SetPoint`,
    from rest at the first segment's start, without noise: the reference against which
    the closed form of `microfab.process.slm.propagate` is checked. Outputs are raw (not
    divided by ``G(0)``), bit.
    """
    axis = axis_model_of(model)
    plant = LTIPlant(block_diag(axis, axis))
    g = np.linalg.solve(np.eye(axis.n_states) - axis.A, axis.B[:, 0])
    p = timeline.p0[0] if timeline.n_segments else np.zeros(2)
    x = np.concatenate([g * p[0], g * p[1]])
    state = LoopState(
        plant=np.concatenate([x, np.zeros_like(x)]),
        controller=np.zeros(0),
        observer=np.zeros(0),
        command=np.array(p, dtype=float),
    )
    return simulate(plant, SetPoint(2), timeline.command(), state=state, axes=("x", "y"))
