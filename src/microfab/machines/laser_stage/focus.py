"""Autofocus on the seed 004 focus twin: the sliding-mode search, its figures, the study.

`play_focus` plays `microfab.control.focus.SlidingModeFocus` on the focus twin
(`microfab.machines.laser_stage.focus`; set-up assumed: the seed's [23] is undescribed)
from its start position (500 µm off focus, assumed). `run_focus` measures on it what seed
004 Fig. 6 shows: the detector output falling to its minimum and the z encoder settling
at the focus. Figures of merit: the time to enter the depth of focus (±DOF/2 about the
focus, DOF from the beam: `LMWFocusParams.depth_of_focus_m`, 55 µm against the seed's
~54 µm) for good, and the steady peak-to-peak of z over the last ``settle_window_s``.

The law runs on the log spot area of the twin's dark-field detector
(`microfab.control.focus.dark_field_area`); its constants follow the design rule of
`SlidingModeFocusConfig.for_dark_field` from the twin's optics, stage lag and start
(`microfab.control.focus.focus_law`): search speed = the stage's speed limit, ``ρ`` = half
the slowest fall of the log spot area over the capture range, ``h = ρ τ``. A tilted part
moving under the beam is a focal plane drifting at ``tilt × part speed`` (1 mrad at 10
mm/s: 10 µm/s).

`focus_study` runs what the ``laser-micromachining`` job and its reproduction report: both
laws on a fixed part, and the continuous law on a tilted one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from microfab.control.focus import SlidingModeFocus, focus_law
from microfab.core.validate import check_int, check_positive
from microfab.machines.laser_stage.machine import focus as focus_twin
from microfab.plants.lmw_focus import LMWFocus
from microfab.sim.loop import simulate

__all__ = [
    "FocusJob",
    "FocusRun",
    "FocusStudy",
    "FocusTrace",
    "focus_study",
    "play_focus",
    "run_focus",
]


@dataclass(frozen=True, kw_only=True, eq=False)
class FocusTrace:
    """A focus search played on the focus twin (all shape (n,)).

    Attributes
    ----------
    plant : LMWFocus
        The focus twin.
    detector : numpy.ndarray
        Measured detector output, V.
    z : numpy.ndarray
        z encoder as measured, m.
    z_output : numpy.ndarray
        z encoder as the twin output it (before the measurement noise), m.
    focus : numpy.ndarray
        Focus position at each sample, m (moves with ``surface_rate_m_s``).
    command : numpy.ndarray
        z velocity command, m/s.
    """

    plant: LMWFocus
    detector: np.ndarray
    z: np.ndarray
    z_output: np.ndarray
    focus: np.ndarray
    command: np.ndarray

    @property
    def time(self) -> np.ndarray:
        """Sample times, s."""
        return np.arange(self.z.size) * self.plant.dt


def play_focus(
    *,
    continuous: bool = True,
    duration_s: float = 2.0,
    speed_m_s: float | None = None,
    surface_rate_m_s: float = 0.0,
    seed: int = 0,
    noise: bool = True,
) -> FocusTrace:
    """Play the sliding-mode focus search on the focus twin from its start position.

    The law is `microfab.control.focus.focus_law` of the twin (seed 004 eqs. 16-17 when
    ``continuous``, else the discontinuous baseline).

    Parameters
    ----------
    continuous : bool
        Continuous sign and relay, or the discontinuous baseline.
    duration_s : float
        Simulated time, s.
    speed_m_s : float or None
        Search speed V, m/s (default: the stage's speed limit).
    surface_rate_m_s : float
        Drift of the focal plane, m/s (a tilted part moving under the beam; 0: fixed).
    seed : int
        Seed of the detector noise.
    noise : bool
        Detector noise on.
    """
    plant = focus_twin(surface_rate_m_s=surface_rate_m_s)
    c = plant.config
    ctrl = SlidingModeFocus(focus_law(plant, continuous=continuous, speed_m_s=speed_m_s))
    n = round(duration_s / plant.dt)
    rng = np.random.default_rng(seed)
    v = np.zeros((n, 2))
    if noise:
        v[:, 0] = rng.standard_normal(n) * plant.noise_level.rms[0]
    res = simulate(plant, ctrl, np.zeros((n, 1)), v)
    t = np.arange(n) * plant.dt
    return FocusTrace(
        plant=plant,
        detector=res.measured[:, 0],
        z=res.measured[:, 1],
        z_output=res.output[:, 1],
        focus=c.focus_position_m + c.surface_rate_m_s * t,
        command=res.command[:, 0],
    )


@dataclass(frozen=True, kw_only=True)
class FocusJob:
    """One autofocus run (all assumed; see the module notes).

    Parameters
    ----------
    continuous : bool
        Continuous sign and relay (seed 004 eqs. 16-17) or the discontinuous baseline.
    duration_s : float
        Simulated time, s.
    settle_window_s : float
        Window at the end over which the steady peak-to-peak of z is taken, s.
    speed_m_s : float or None
        Search speed V, m/s (default: the stage's speed limit).
    surface_rate_m_s : float
        Drift of the focal plane, m/s (a tilted part moving under the beam; 0: fixed).
    seed : int
        Seed of the detector noise.
    noise : bool
        Detector noise on.
    """

    continuous: bool = True
    duration_s: float = 2.0
    settle_window_s: float = 1.0
    speed_m_s: float | None = None
    surface_rate_m_s: float = 0.0
    seed: int = 0
    noise: bool = True

    def __post_init__(self) -> None:
        check_positive("duration_s", self.duration_s, "s")
        check_positive("settle_window_s", self.settle_window_s, "s")
        if self.settle_window_s >= self.duration_s:
            raise ValueError(
                f"settle_window_s ({self.settle_window_s:g} s) must be shorter than "
                f"duration_s ({self.duration_s:g} s)"
            )
        if self.speed_m_s is not None:
            check_positive("speed_m_s", self.speed_m_s, "m/s")
        check_int("seed", self.seed, 0)


@dataclass(frozen=True, kw_only=True, eq=False)
class FocusRun(FocusTrace):
    """A finished autofocus run: its `FocusTrace` and its figures of merit.

    Attributes
    ----------
    job : FocusJob
        What ran.
    depth_of_focus_m : float
        DOF of the beam (±5 % spot growth), m.
    entered_s : float or None
        First time after which ``|z − focus| <= DOF/2`` holds to the end, s.
    steady_ptp_m : float
        Peak-to-peak of ``z − focus`` over the settle window, m.
    """

    job: FocusJob
    depth_of_focus_m: float
    entered_s: float | None
    steady_ptp_m: float


def run_focus(job: FocusJob | None = None) -> FocusRun:
    """Run the sliding-mode focus search on the focus twin and measure it (module notes)."""
    job = job or FocusJob()
    tr = play_focus(
        continuous=job.continuous,
        duration_s=job.duration_s,
        speed_m_s=job.speed_m_s,
        surface_rate_m_s=job.surface_rate_m_s,
        seed=job.seed,
        noise=job.noise,
    )
    plant = tr.plant
    n = tr.z.size
    err = tr.z_output - tr.focus
    dof = plant.depth_of_focus_m()
    outside = np.flatnonzero(np.abs(err) > 0.5 * dof)
    entered = None
    if outside.size == 0:
        entered = 0.0
    elif outside[-1] < n - 1:
        entered = float(tr.time[outside[-1] + 1])
    w = round(job.settle_window_s / plant.dt)
    return FocusRun(
        **{f.name: getattr(tr, f.name) for f in fields(FocusTrace)},
        job=job,
        depth_of_focus_m=dof,
        entered_s=entered,
        steady_ptp_m=float(np.ptp(err[-w:])),
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class FocusStudy:
    """Both laws on a fixed part and the continuous law on a tilted one (`focus_study`).

    Attributes
    ----------
    continuous, discontinuous : FocusRun
        The two laws from the twin's start, fixed focal plane.
    tilted : FocusRun or None
        The continuous law with the focal plane drifting (None: no tilt asked).
    tilt_rad, part_speed_m_s : float
        The tilt and the part's speed under the beam of ``tilted``.
    """

    continuous: FocusRun
    discontinuous: FocusRun
    tilted: FocusRun | None
    tilt_rad: float
    part_speed_m_s: float

    @property
    def ptp_ratio(self) -> float:
        """Discontinuous over continuous steady peak-to-peak of z (inf if the latter is 0)."""
        c = self.continuous.steady_ptp_m
        return float("inf") if c == 0.0 else self.discontinuous.steady_ptp_m / c

    def tilted_max_error_m(self) -> float | None:
        """Largest ``|z − focus|`` of the tilted run over its steady window, m (None: no tilt)."""
        r = self.tilted
        if r is None:
            return None
        w = round(r.job.settle_window_s / r.plant.dt)
        return float(np.max(np.abs(r.z[-w:] - r.focus[-w:])))

    def resolution_against_h(self) -> dict[str, float]:
        """The detector's noise and count against the law's ``h``, on ``ln q`` at focus.

        Why the steady band does not depend on the noise seed: the law reverses when
        ``σ`` reaches ``h`` (`microfab.control.focus`), and at focus one volt of the
        detector is worth ``1 / (r (−ln r) full_scale)`` of ``ln q`` (``r = exp(−2
        (a/w0)²)``, `dark_field_area`). When the noise and the converter count are
        hundreds of times below ``h`` there, they never trigger a reversal: the band is
        the law's own stall-reversal cycle (``V``, ``τ``, ``ρ``, ``h``), the same for
        any seed to the z encoder's count.

        Returns
        -------
        dict
            ``h_lnq`` (the continuous law's ``h``), ``noise_lnq`` and ``count_lnq`` (the
            detector noise rms and one converter count at focus), ``h_over_noise``.
        """
        plant = self.continuous.plant
        c = plant.config
        law = focus_law(plant, continuous=True)
        r = math.exp(-2.0 * c.stop_radius_ratio**2)
        per_volt = 1.0 / (r * -math.log(r) * c.full_scale_v)
        noise = float(plant.noise_level.rms[0]) * per_volt
        return {
            "h_lnq": law.h,
            "noise_lnq": noise,
            "count_lnq": c.adc_count_v * per_volt,
            "h_over_noise": law.h / noise if noise > 0 else float("inf"),
        }

    def summary(self) -> dict[str, float | None]:
        """The figures, JSON-ready (µm, s; ``ln q`` for the resolution against ``h``)."""
        tilt_err = self.tilted_max_error_m()
        return {
            **self.resolution_against_h(),
            "depth_of_focus_um": self.continuous.depth_of_focus_m * 1e6,
            "start_um": self.continuous.plant.config.start_position_m * 1e6,
            "continuous_entered_s": self.continuous.entered_s,
            "discontinuous_entered_s": self.discontinuous.entered_s,
            "continuous_steady_ptp_um": self.continuous.steady_ptp_m * 1e6,
            "discontinuous_steady_ptp_um": self.discontinuous.steady_ptp_m * 1e6,
            "ptp_ratio": self.ptp_ratio,
            "tilt_mrad": self.tilt_rad * 1e3,
            "part_speed_mm_s": self.part_speed_m_s * 1e3,
            "tilted_entered_s": None if self.tilted is None else self.tilted.entered_s,
            "tilted_max_error_um": None if tilt_err is None else tilt_err * 1e6,
        }


def focus_study(
    *,
    duration_s: float = 3.0,
    settle_window_s: float = 1.0,
    tilt_rad: float = 1e-3,
    part_speed_m_s: float = 10e-3,
    seed: int = 0,
    noise: bool = True,
) -> FocusStudy:
    """Run both laws on a fixed part and the continuous one on a tilted part.

    Parameters
    ----------
    duration_s, settle_window_s : float
        Length of each run and the window of the steady peak-to-peak, s.
    tilt_rad : float
        Tilt of the part, rad (0: no tilted run). Issue default 1 mrad.
    part_speed_m_s : float
        Speed of the part under the beam, m/s (issue default 10 mm/s).
    seed : int
        Seed of the detector noise.
    noise : bool
        Detector noise on.
    """
    if not np.isfinite(tilt_rad) or tilt_rad < 0.0:
        raise ValueError(f"tilt must be finite and >= 0, got {tilt_rad!r} rad")
    if tilt_rad > 0.0:
        check_positive("part_speed_m_s (speed of the tilted part)", part_speed_m_s, "m/s")
    base = FocusJob(duration_s=duration_s, settle_window_s=settle_window_s, seed=seed, noise=noise)
    cont = run_focus(base)
    disc = run_focus(replace(base, continuous=False))
    tilted = None
    if tilt_rad > 0.0:
        tilted = run_focus(replace(base, surface_rate_m_s=tilt_rad * part_speed_m_s))
    return FocusStudy(
        continuous=cont,
        discontinuous=disc,
        tilted=tilted,
        tilt_rad=tilt_rad,
        part_speed_m_s=part_speed_m_s,
    )
