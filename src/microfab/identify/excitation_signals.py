"""Deterministic excitation runs of the seed 002 XY stage: regular shapes, PRBS, chirp.

- `shape_runs` (§III-C 2: "a set of varied regular geometries including circles, polygons,
  and spirals", "each shape was traversed at varied speeds, constant for each trial"),
  with the Archimedean spiral of Fig. 1 among them (`shape_catalogue`), traced by
  :func:`microfab.trajectory.cruise.cruise` within ``a_max``;
- `prbs_runs`, `chirp_runs`: the classic inputs the seed found inadequate (§III-C: "none
  of these proved adequate for the identification of the nonlinear system"). Within the
  limits they stay small: a one-sample position step must satisfy ``2A/dt² ≤ 40 m/s²``
  (A ≤ 0.2 µm), so the PRBS switches by quintic moves, and a chirp's amplitude is set by
  its top frequency (``A (2π f₁)² ≤ a_max``: 3.2 µm at 200 Hz and 5 m/s²);
  `classic_runs` mixes both into one data set (the ``stage-identify`` job's networks
  trained on them, `microfab.machines.xy_stage.ann.classic_records`).

Every run starts at rest at the origin and ends at rest there (`ExcitationRun`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.core.validate import check_in_range, check_int, check_positive
from microfab.geometry.path import Path
from microfab.geometry.shapes import circle, rectangle, regular_polygon, spiral
from microfab.identify.excitation_random import (
    HOME,
    QUINTIC_ACC_PEAK,
    QUINTIC_VEL_PEAK,
    home_move,
    quintic,
)
from microfab.identify.excitation_run import (
    DT,
    LIMITS,
    SEED_A_MAX,
    ExcitationRun,
    check_a_max,
    spawn_seeds,
)
from microfab.trajectory.cruise import cruise

__all__ = [
    "FIG1_SPIRAL_B",
    "chirp_runs",
    "classic_runs",
    "prbs_runs",
    "shape_catalogue",
    "shape_runs",
]

#: Seed 002 Fig. 1: the Archimedean spiral r = b θ, b = 50/(2π) mm/rad, θ ∈ [0, 4π].
FIG1_SPIRAL_B = 50e-3 / (2 * math.pi)


# --- shapes --------------------------------------------------------------------------------


def shape_catalogue(seed: int = 0) -> list[tuple[str, Path]]:
    """The regular shapes (§III-C 2), each starting at the origin; placements seeded.

    Circles of 5, 20, 50 and 90 mm radius; a triangle, a square, a hexagon and an octagon
    (circumradius 60, 80, 30, 45 mm); a rounded rectangle 120 × 60 mm (10 mm corners);
    the Fig. 1 spiral as drawn (``r = b θ``, b = 50/(2π) mm/rad, θ ∈ [0, 4π], from the
    origin, unrotated) and a 3-turn spiral of b = 20/(2π) mm/rad. Sizes assumed: from
    fine features to most of the workspace. Each closed shape is rotated by a seeded
    angle and moved so that its start point is the origin (where a run starts); all fit
    in the ±0.19 m workspace whatever the angle.
    """
    rng = np.random.default_rng(spawn_seeds(seed, 1)[0])
    base: list[tuple[str, Path]] = [
        ("circle_r5mm", circle(5e-3)),
        ("circle_r20mm", circle(20e-3)),
        ("circle_r50mm", circle(50e-3)),
        ("circle_r90mm", circle(90e-3)),
        ("triangle_r60mm", regular_polygon(3, 60e-3)),
        ("square_r80mm", regular_polygon(4, 80e-3)),
        ("hexagon_r30mm", regular_polygon(6, 30e-3)),
        ("octagon_r45mm", regular_polygon(8, 45e-3)),
        ("rounded_rect_120x60mm", rectangle(0.12, 0.06, corner_radius=0.01)),
    ]
    out: list[tuple[str, Path]] = []
    for name, path in base:
        turned = path.rotated(float(rng.uniform(0.0, 2 * math.pi)))
        out.append((name, turned.translated(-turned.start)))
    out.append(("spiral_fig1", spiral(FIG1_SPIRAL_B, 0.0, 4 * math.pi)))  # seed 002 Fig. 1
    small = spiral(20e-3 / (2 * math.pi), 0.0, 6 * math.pi)  # assumed: a tighter spiral
    out.append(("spiral_b20mm", small.rotated(float(rng.uniform(0.0, 2 * math.pi)))))
    return out


def _return_home(pos: np.ndarray, v_cap: float, a_cap: float) -> np.ndarray:
    """Append a quintic move from the last sample back to `HOME` (both axes, one time)."""
    end = pos[-1]
    dur = max(home_move(e - h, v_cap, a_cap) for e, h in zip(end, HOME, strict=True))
    if dur == 0.0:
        return pos
    m = math.ceil(dur / DT)
    u = quintic(np.arange(1, m + 1) * DT / dur)
    back = end[None, :] + (np.asarray(HOME)[None, :] - end[None, :]) * u[:, None]
    return np.vstack([pos, back])


def shape_runs(
    speeds: Sequence[float],
    *,
    seed: int = 0,
    a_max: float = SEED_A_MAX,
    shapes: Sequence[tuple[str, Path]] | None = None,
) -> list[ExcitationRun]:
    """Each shape at each constant speed, from rest at the origin to rest there.

    The path is traced by :func:`~microfab.trajectory.cruise.cruise` at ``speed`` within
    1.5 m/s and ``a_max`` per axis (ramps from and to rest, curvature slow-downs, a stop
    at every corner). Cruise samples a whole number of intervals at a ``dt`` just below
    `DT`; played at `DT` the run is slower by less than one sample in its length, which
    only lowers velocity and acceleration. An open shape (a spiral) is followed by a
    quintic move back to the origin (``params["home_from_s"]``).

    Parameters
    ----------
    speeds : sequence of float
        Path speeds, m/s, each in (0, 1.5].
    seed : int
        Seed of the shapes' rotations (`shape_catalogue`).
    a_max : float
        Per-axis acceleration limit given to cruise, m/s² (default 5, §III-D).
    shapes : sequence of (str, Path), optional
        Shapes starting at the origin (default `shape_catalogue(seed)`).

    Returns
    -------
    list of ExcitationRun
        Named ``shape_<shape>_v<mm/s>``; ``params`` hold the shape, speed, path length and
        the share of time at speed.
    """
    a_max = check_a_max(a_max)
    if len(speeds) == 0:
        raise ValueError("speeds must hold at least one path speed in m/s, got none")
    for v in speeds:
        check_in_range("speed", v, 0.0, LIMITS.velocity[0], "m/s", low_closed=False)
    catalogue = list(shapes) if shapes is not None else shape_catalogue(seed)
    limits = MachineLimits(
        workspace=LIMITS.workspace, velocity=LIMITS.velocity, acceleration=(a_max, a_max)
    )
    runs: list[ExcitationRun] = []
    for shape, path in catalogue:
        if float(np.max(np.abs(path.start - np.asarray(HOME)))) > 1e-12:
            raise ValueError(f"shape {shape!r} must start at the origin {HOME} m, not {path.start}")
        for v in speeds:
            traj = cruise(path, limits, speed=float(v), sample_rate_hz=1.0 / DT)
            pos = np.array(traj.position)
            v_home = min(float(v), LIMITS.velocity[0])
            pos = _return_home(pos, v_home, a_max)
            runs.append(
                ExcitationRun(
                    kind="shape",
                    name=f"shape_{shape}_v{round(1e3 * float(v))}mms",
                    dt=DT,
                    command=pos,
                    seed=seed,
                    params={
                        "shape": shape,
                        "speed_m_s": float(v),
                        "a_max": a_max,
                        "length_m": float(path.length),
                        "share_at_speed": float(traj.meta["share_at_speed"]),
                        "home_from_s": traj.n_samples * DT,
                    },
                )
            )
    return runs


# --- classic inputs ----------------------------------------------------------------------


def prbs_runs(
    duration_s: float = 60.0,
    *,
    amplitudes: Sequence[float] = (1e-4, 1e-3),
    clock_s: float = 0.02,
    a_max: float = SEED_A_MAX,
    nbits: int = 10,
    seed: int = 0,
) -> list[ExcitationRun]:
    """A maximum-length PRBS on both axes' set-points, one run per amplitude (§III-C).

    Each axis switches between ``±amplitude`` about the origin on a clock of
    ``clock_s``, with independent sequences (seeded start states of one ``nbits``
    maximum-length shift register, :func:`scipy.signal.max_len_seq`). A switch is a
    quintic move of the shortest duration within 1.5 m/s and ``a_max``
    (``2A · 10/√3 / T² ≤ a_max``); the clock is stretched to it when shorter. The run
    starts and ends at rest at the origin.

    Parameters
    ----------
    duration_s : float
        Length of each run, s (the sequence repeats).
    amplitudes : sequence of float
        Half the peak-to-peak level, m, each in (0, 0.1].
    clock_s : float
        Shortest time between switches, s.
    a_max : float
        Acceleration limit of a switch, m/s² (default 5).
    nbits : int
        Register length, 4 to 20 (period ``2**nbits - 1`` clocks).
    seed : int
        Seed of the start states.
    """
    from scipy.signal import max_len_seq  # SciPy is heavy to import

    dur = check_positive("duration_s", duration_s, "s")
    clock = check_positive("clock_s", clock_s, "s")
    a_max = check_a_max(a_max)
    check_in_range("nbits", check_int("nbits", nbits, 4), 4, 20)
    if len(amplitudes) == 0:
        raise ValueError("amplitudes must hold at least one level in m, got none")
    runs: list[ExcitationRun] = []
    for i, amp in enumerate(amplitudes):
        amp = check_in_range("amplitude", amp, 0.0, 0.1, "m", low_closed=False)
        t_sw = max(
            math.sqrt(QUINTIC_ACC_PEAK * 2 * amp / a_max),
            QUINTIC_VEL_PEAK * 2 * amp / LIMITS.velocity[0],
        )
        t_sw = math.ceil(t_sw / DT) * DT
        clk = max(clock, t_sw)
        n_clk = max(int(dur / clk), 2)
        rng = np.random.default_rng(spawn_seeds(seed, len(amplitudes))[i])
        cmd_cols = []
        for _axis in range(2):
            state = rng.integers(0, 2, nbits)
            state[rng.integers(0, nbits)] = 1  # not all zero
            bits = max_len_seq(nbits, state=state, length=n_clk)[0]
            levels = np.concatenate([[0.0], amp * (2.0 * bits - 1.0), [0.0]])
            cmd_cols.append(levels)
        n = round((n_clk + 1) * clk / DT) + math.ceil(t_sw / DT) + 1
        t = np.arange(n) * DT
        cmd = np.empty((n, 2))
        k = np.minimum((t / clk).astype(int), n_clk + 1)  # the switch that last started
        u = quintic((t - k * clk) / t_sw)
        for a, levels in enumerate(cmd_cols):
            prev = levels[np.maximum(k - 1, 0)]
            cmd[:, a] = np.where(k == 0, 0.0, prev + (levels[k] - prev) * u)
        runs.append(
            ExcitationRun(
                kind="prbs",
                name=f"prbs_a{amp * 1e6:.0f}um",
                dt=DT,
                command=cmd,
                seed=seed,
                params={
                    "amplitude_m": amp,
                    "clock_s": clk,
                    "switch_s": t_sw,
                    "nbits": nbits,
                    "a_max": a_max,
                },
            )
        )
    return runs


def chirp_runs(
    duration_s: float = 60.0,
    *,
    f0_hz: float = 0.5,
    f1_hz: float = 200.0,
    amplitude: float | None = None,
    a_max: float = SEED_A_MAX,
    method: str = "logarithmic",
    fade_s: float = 1.0,
) -> list[ExcitationRun]:
    """A swept sine on one axis at a time (x, then y), the other held at the origin.

    ``x(t) = A w(t) sin φ(t)`` with φ swept from ``f0_hz`` to ``f1_hz``
    (:func:`scipy.signal.chirp`, phase −90° so it starts at 0) and ``w`` a quintic fade in
    and out over ``fade_s``. ``A`` is the largest amplitude (at most ``amplitude``) whose
    sampled velocity and acceleration stay within 1.5 m/s and ``a_max``: roughly
    ``a_max / (2π f1)²``, 3.2 µm for 200 Hz at 5 m/s² (the seed's point: such inputs
    stay small, §III-C).

    Parameters
    ----------
    duration_s : float
        Sweep length, s (each run also fades in and out within it).
    f0_hz, f1_hz : float
        Start and end frequencies, Hz (``0 < f0 < f1 < 5 kHz``).
    amplitude : float, optional
        Largest amplitude wanted, m (default: as large as the limits allow, at most 0.1 m).
    a_max : float
        Acceleration limit, m/s² (default 5).
    method : str
        ``"logarithmic"`` or ``"linear"`` sweep.
    fade_s : float
        Fade-in and fade-out time, s, at most a quarter of ``duration_s``.
    """
    from scipy.signal import chirp  # SciPy is heavy to import

    dur = check_positive("duration_s", duration_s, "s")
    f0 = check_positive("f0_hz", f0_hz, "Hz")
    f1 = check_in_range("f1_hz", f1_hz, f0, 0.5 / DT, "Hz", low_closed=False, high_closed=False)
    a_max = check_a_max(a_max)
    fade = check_in_range("fade_s", fade_s, 0.0, dur / 4, "s", low_closed=False)
    if method not in ("logarithmic", "linear"):
        raise ValueError(f"method must be 'logarithmic' or 'linear', got {method!r}")
    want = (
        0.1
        if amplitude is None
        else check_in_range("amplitude", amplitude, 0.0, 0.1, "m", low_closed=False)
    )
    n = round(dur / DT) + 1
    t = np.arange(n) * DT
    w = quintic(t / fade) * quintic((dur - t) / fade)
    unit = w * chirp(t, f0=f0, t1=dur, f1=f1, method=method, phi=-90.0)
    pad = np.concatenate([[0.0], unit, [0.0]])
    v_pk = float(np.max(np.abs(np.diff(pad)))) / DT
    a_pk = float(np.max(np.abs(np.diff(pad, 2)))) / DT**2
    amp = min(want, LIMITS.velocity[0] / v_pk, a_max / a_pk) * (1 - 1e-6)  # rounding room
    runs = []
    for a, ax in enumerate(("x", "y")):
        cmd = np.zeros((n, 2))
        cmd[:, a] = amp * unit
        runs.append(
            ExcitationRun(
                kind="chirp",
                name=f"chirp_{ax}",
                dt=DT,
                command=cmd,
                params={
                    "axis": ax,
                    "amplitude_m": amp,
                    "f0_hz": f0,
                    "f1_hz": f1,
                    "method": method,
                    "fade_s": fade,
                    "a_max": a_max,
                },
            )
        )
    return runs


_CLASSIC_F1_HZ = (20.0, 50.0, 100.0, 200.0, 500.0)  # assumed: chirp tops, one per block


def classic_runs(total_s: float, seed: int = 0) -> list[ExcitationRun]:
    """PRBS and chirp runs, ``total_s`` in all (§III-C's classic signals).

    Five blocks, each half PRBS (0.1 and 1 mm levels, its own seed, `prbs_runs`) and
    half chirp (x then y from 0.5 Hz to one of ``_CLASSIC_F1_HZ``, `chirp_runs`), all
    within 5 m/s²; twenty runs, so that an 80/20 split by runs leaves some to validate.
    """
    part = total_s / (4 * len(_CLASSIC_F1_HZ))
    out: list[ExcitationRun] = []
    for k, f1 in enumerate(_CLASSIC_F1_HZ):
        chirps = chirp_runs(part, f1_hz=f1, fade_s=min(1.0, part / 4))
        for r in (*prbs_runs(part, seed=seed + k), *chirps):
            out.append(dataclasses.replace(r, name=f"{r.name}_b{k}"))
    return out
