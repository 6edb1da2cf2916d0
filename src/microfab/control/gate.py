"""The laser gate of seed 001 §4.2: expose a closed contour once the tracking has converged.

Seed 001 (abstract, §4.2): "the fabrication of a closed pattern will not begin by turning
on the laser source until the tracking error reaches submicrons", which happened "in 3-4
periods". We read "submicrons" as a threshold on the RMS over one full period (loop) of
the contour of the tracking error's Euclidean norm, default 1 µm = 1e-3 mm. The error is
whatever vector the caller hands over: the 2-D tracking error ``r - y`` (x, y) of the
experiments, which bounds the contour error from above (so the criterion is
conservative), or a contour error as a 1-vector.

`LaserGate` is a state machine ``off -> settling -> exposing -> done``:

* ``off`` until the first contour start ``s_0``;
* ``settling``: at each decision instant ``d_j = s_j - lead_on`` (``s_j`` the contour
  starts: ``0, N, 2N, ...`` by default, or given sample indices spaced by at least ``N``)
  the gate opens when the ``N`` samples just before ``d_j`` all lie on the contour (inside
  loops ``[s_i, s_i + N)``) and their RMS error norm is below the threshold; otherwise it
  waits for the next start (a NaN error fails its period);
* ``exposing``: the laser is on over ``[d_j, s_j + N - lead_off)``: exactly one loop when
  the leads are 0 (the default);
* ``done``: off for good (one gate exposes one loop).

``lead_on`` advances the switch-on (and with it the decision) so that a laser that warms
up after switch-on has its power at the contour start (seed 001 §4.2 leaves this
"compensated by software in the future"); ``lead_off`` ends the exposure early for a
laser that keeps shining after switch-off. The decision at ``d_j`` looks at the last full
period before it, which with ``lead_on > 0`` is a shifted loop of the same converged
contour.

`run_gate` runs the same kernel over a whole error trace (numba).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from microfab.control.repetitive import period_samples
from microfab.core.validate import check_int, check_positive

__all__ = [
    "DONE",
    "EXPOSING",
    "MODE_NAMES",
    "OFF",
    "SETTLING",
    "GateConfig",
    "GateRun",
    "LaserGate",
    "gate_step",
    "run_gate",
]

OFF, SETTLING, EXPOSING, DONE = 0, 1, 2, 3
MODE_NAMES = ("off", "settling", "exposing", "done")

# params: [N, threshold, lead_on, lead_off, n_starts, starts...]
# state:  [mode, k, j, i_cur, run, open_at, close_at, last_rms, ring buffer (N)]
_PH = 5
_SH = 8


@dataclass(frozen=True, kw_only=True)
class GateConfig:
    """Settings of the laser gate.

    Parameters
    ----------
    period_samples : int
        Samples in one loop of the contour, ``N`` (>= 2).
    threshold_mm : float
        Gate threshold on the RMS error norm over a period, mm (> 0; default 1e-3 mm =
        1 µm, our reading of seed 001's "reaches submicrons").
    starts : tuple of int, optional
        Sample indices at which a loop of the contour starts, increasing and spaced by at
        least ``N``; ``None`` (default): ``0, N, 2N, ...`` (loops back to back).
    lead_on_samples : int
        Switch the laser on this many samples before the contour start, ``0 <= . < N``
        (warm-up compensation; default 0).
    lead_off_samples : int
        Switch it off this many samples before the loop ends, ``0 <= . < N`` (default 0).
    """

    period_samples: int
    threshold_mm: float = 1e-3  # our reading of seed 001 §4.2 "reaches submicrons"
    starts: tuple[int, ...] | None = None
    lead_on_samples: int = 0
    lead_off_samples: int = 0

    def __post_init__(self) -> None:
        n = check_int("period_samples", self.period_samples, 2, "samples")
        check_positive("threshold_mm (gate threshold)", self.threshold_mm, "mm")
        for name in ("lead_on_samples", "lead_off_samples"):
            v = check_int(name, getattr(self, name), 0, "samples")
            if v >= n:
                raise ValueError(f"{name} must be below the period ({n} samples), got {v}")
        if self.starts is not None:
            starts = tuple(self.starts)
            if not starts:
                raise ValueError("starts must hold at least one contour start sample")
            prev = None
            for i, s in enumerate(starts):
                check_int(f"contour start {i}", s, 0, "samples")
                if prev is not None and s - prev < n:
                    raise ValueError(
                        f"contour start {i} ({s}) follows start {i - 1} ({prev}) by fewer than "
                        f"one period ({n} samples): starts must increase by at least a period"
                    )
                prev = s
            object.__setattr__(self, "starts", tuple(int(s) for s in starts))

    @classmethod
    def from_period(cls, *, period_s: float, dt: float, **kwargs: object) -> GateConfig:
        """Config for a period in s (refused unless a whole number of samples)."""
        return cls(period_samples=period_samples(period_s, dt), **kwargs)  # type: ignore[arg-type]

    def params(self) -> np.ndarray:
        """The kernel's flat parameters ``[N, threshold, lead_on, lead_off, n_starts, ...]``."""
        starts = () if self.starts is None else self.starts
        head = [
            self.period_samples,
            self.threshold_mm,
            self.lead_on_samples,
            self.lead_off_samples,
            len(starts),
        ]
        return np.array([*head, *starts], dtype=np.float64)


@njit(cache=True, inline="always")
def _start(p: np.ndarray, i: int) -> int:
    """Start of loop ``i`` (``i * N`` without given starts; -1 past the last given one)."""
    ns = int(p[4])
    if ns == 0:
        return i * int(p[0])
    if i < ns:
        return int(p[_PH + i])
    return -1


@njit(cache=True)
def gate_step(p: np.ndarray, x: np.ndarray, err: np.ndarray) -> bool:
    """One sample of the gate (state ``x`` advanced in place); returns whether the laser is on.

    ``p`` from `GateConfig.params`; ``x`` from `LaserGate.init`; ``err`` the error vector
    of this sample, mm.
    """
    n = int(p[0])
    lead_on = int(p[2])
    lead_off = int(p[3])
    k = int(x[1])
    # loop that contains (or last started before) sample k
    i_cur = int(x[3])
    while True:
        s_next = _start(p, i_cur + 1)
        if s_next < 0 or s_next > k:
            break
        i_cur += 1
    x[3] = i_cur
    s_cur = _start(p, i_cur)
    on_contour = i_cur >= 0 and s_cur >= 0 and s_cur <= k < s_cur + n
    mode = int(x[0])
    if mode == OFF and on_contour:
        mode = SETTLING
    if mode == SETTLING:
        j = int(x[2])
        while True:
            sj = _start(p, j)
            if sj < 0 or sj - lead_on >= k:
                break
            j += 1
        if sj >= 0 and sj - lead_on == k:
            if x[4] >= n:
                acc = 0.0
                for i in range(n):
                    acc += x[_SH + i]
                rms = np.sqrt(acc / n)
                x[7] = rms
                if rms < p[1]:
                    mode = EXPOSING
                    x[5] = k
                    x[6] = sj + n - lead_off
            j += 1
        x[2] = j
    laser = False
    if mode == EXPOSING:
        if k < x[6]:
            laser = True
        else:
            mode = DONE
    e2 = 0.0
    for i in range(err.shape[0]):
        e2 += err[i] * err[i]
    x[_SH + k % n] = e2
    x[4] = x[4] + 1.0 if on_contour else 0.0
    x[0] = mode
    x[1] = k + 1
    return laser


@njit(cache=True)
def _run(
    p: np.ndarray, x: np.ndarray, errors: np.ndarray, laser: np.ndarray, mode: np.ndarray
) -> None:
    for k in range(errors.shape[0]):
        laser[k] = gate_step(p, x, errors[k])
        mode[k] = int(x[0])


@dataclass(frozen=True, kw_only=True, eq=False)
class GateRun:
    """The gate over a whole trace.

    Attributes
    ----------
    laser : numpy.ndarray
        Laser command per sample, bool, shape (n,).
    mode : numpy.ndarray
        Gate mode after each sample (`OFF`, `SETTLING`, `EXPOSING`, `DONE`), int8, (n,).
    opened_at, closed_at : int or None
        First sample with the laser on and first sample after the exposure, counted
        from the gate's start (`LaserGate.init`); None when the gate has not opened
        (not closed) by the end of the trace.
    last_rms_mm : float
        RMS error norm of the last period evaluated, mm (NaN if none was).
    state : numpy.ndarray
        Final gate state (to continue with `LaserGate.step` or another run).
    """

    laser: np.ndarray
    mode: np.ndarray
    opened_at: int | None
    closed_at: int | None
    last_rms_mm: float
    state: np.ndarray


class LaserGate:
    """The gate as a state machine (module docstring); ``step`` and `run_gate` agree.

    Parameters
    ----------
    config : GateConfig
        Period, threshold, contour starts and leads.
    """

    def __init__(self, config: GateConfig) -> None:
        if not isinstance(config, GateConfig):
            raise TypeError(f"config must be a GateConfig, got {type(config).__name__}")
        self.config = config
        self.params = config.params()

    def init(self) -> np.ndarray:
        """State before the first sample (mode ``off``), shape (8 + N,)."""
        x = np.zeros(_SH + self.config.period_samples)
        x[5] = x[6] = -1.0
        x[7] = np.nan
        return x

    @staticmethod
    def mode_of(state: np.ndarray) -> str:
        """Name of the mode a state is in."""
        return MODE_NAMES[int(state[0])]

    def step(self, state: np.ndarray, error: np.ndarray) -> tuple[bool, np.ndarray]:
        """One sample: ``(laser_on, next_state)``; ``state`` is not modified.

        Parameters
        ----------
        state : numpy.ndarray
            Gate state.
        error : numpy.ndarray
            Tracking error of this sample, mm, shape (n_axes,).
        """
        x = np.array(state, dtype=np.float64, copy=True)
        e = np.atleast_1d(np.asarray(error, dtype=np.float64))
        on = gate_step(self.params, x, e)
        return bool(on), x

    def run(self, errors: np.ndarray, state: np.ndarray | None = None) -> GateRun:
        """The gate over a trace (`run_gate` with this gate's config)."""
        return run_gate(errors, self.config, state)


def run_gate(errors: np.ndarray, config: GateConfig, state: np.ndarray | None = None) -> GateRun:
    """Run the gate over a whole error trace (compiled).

    Parameters
    ----------
    errors : numpy.ndarray
        Tracking error per sample, mm, shape (n,) or (n, n_axes); finite.
    config : GateConfig
        The gate.
    state : numpy.ndarray, optional
        Where to continue from (`GateRun.state`); at ``off`` if omitted.

    Returns
    -------
    GateRun

    Raises
    ------
    ValueError
        On an empty trace, a NaN or inf error (naming the sample), or a state of the
        wrong size.
    """
    e = np.asarray(errors, dtype=np.float64)
    if e.ndim == 1:
        e = e[:, None]
    if e.ndim != 2 or e.shape[0] == 0 or e.shape[1] == 0:
        raise ValueError(f"errors must be shaped (n_samples >= 1, n_axes), got {e.shape}")
    bad = ~np.isfinite(e)
    if bad.any():
        k, a = np.argwhere(bad)[0]
        raise ValueError(
            f"errors hold {e[k, a]} at sample {k}, axis {a}: the gate needs finite errors"
        )
    gate = LaserGate(config)
    x = gate.init() if state is None else np.array(state, dtype=np.float64, copy=True)
    if x.shape != gate.init().shape:
        raise ValueError(
            f"state must have {gate.init().size} values for period {config.period_samples}, "
            f"got shape {x.shape}"
        )
    n = e.shape[0]
    laser = np.zeros(n, dtype=np.bool_)
    mode = np.zeros(n, dtype=np.int8)
    _run(gate.params, x, np.ascontiguousarray(e), laser, mode)
    opened = int(x[5]) if x[5] >= 0 else None
    closed = int(x[6]) if x[0] == DONE else None
    return GateRun(
        laser=laser,
        mode=mode,
        opened_at=opened,
        closed_at=closed,
        last_rms_mm=float(x[7]),
        state=x,
    )
