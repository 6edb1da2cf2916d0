"""Seed 001 Figs. 8 and 10 on the twin: PID, RBF, RBF + RC and PID + RC on one circle.

Figs. 8-10 carry curves, no numbers; the project's targets are
`paper.FIG_TARGETS`. Every controller runs the same reference (one circle of the §4.2
pattern, moved off-centre where the §4.1 terms matter), the same twin, disturbance and
noise seed. The PID is tuned by `microfab.control.pid.PIDGains.design` on eq. (9)
(crossover ``pid_bandwidth_hz``, 45° phase margin); the RBF controller takes the default
centres, widths and scaling of `RBFAdaptive.for_reference` on one period of the circle.
Fig. 8 at equal bandwidth, with an RBF controller that learns, is `fig8.py`; why this
one does not, `study.py`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive, RBFConfig
from microfab.control.repetitive import PluginRC, RCConfig
from microfab.core.validate import check_finite, check_int, check_positive
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.trajectory.circle_pattern import PatternConfig, pattern_reference

__all__ = [
    "CONTROLLERS",
    "CircleSetting",
    "ComparisonConfig",
    "ComparisonResult",
    "circle_setting",
    "compare_controllers",
]

#: The controllers compared, in the order of the report.
CONTROLLERS = ("PID", "RBF", "RBF+RC", "PID+RC")


@dataclass(frozen=True, kw_only=True)
class ComparisonConfig:
    """One circle, four controllers.

    Parameters
    ----------
    offset_mm : float
        Centre of the circle on the diagonal, mm (assumed 0.25 mm: issue 14's "0.15 mm
        circle 0.25 mm off-centre", where the §4.1 stiffness term is 25 % of the linear one).
    pattern : PatternConfig
        The circle (diameter, period, periods); only its first circle is used.
    pid_bandwidth_hz : float
        Crossover of the PID design, Hz (assumed 200 Hz, 45° phase margin).
    rbf : RBFConfig
        RBF settings.
    rc_lead_samples : int
        Phase lead of the RC around the RBF loop, samples (assumed 20: the RBF loop lags
        more than the PID's, which runs with none).
    noise : bool
        Encoder noise on (the twin's ``noise_rms_mm``).
    seed : int
        Seed of the disturbance phases and of the noise.
    """

    offset_mm: float = 0.25
    pattern: PatternConfig = field(
        default_factory=lambda: PatternConfig(n_circles=1, field_mm=0.15, periods=8)
    )
    pid_bandwidth_hz: float = 200.0
    rbf: RBFConfig = field(default_factory=RBFConfig)
    rc_lead_samples: int = 20
    noise: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        check_finite("offset_mm", self.offset_mm, "mm")
        check_positive("pid_bandwidth_hz", self.pid_bandwidth_hz, "Hz")
        check_int("rc_lead_samples", self.rc_lead_samples, 0, "samples")
        check_int("seed", self.seed, 0)


@dataclass(frozen=True, kw_only=True, eq=False)
class ComparisonResult:
    """RMS tracking error per period of each controller.

    Attributes
    ----------
    config : ComparisonConfig
        What ran.
    rms_nm : dict of str to numpy.ndarray
        Per controller, the RMS over both axes of ``r − y`` (true output), nm, shape
        (periods,).
    """

    config: ComparisonConfig
    rms_nm: dict[str, np.ndarray]

    def final(self, name: str) -> float:
        """RMS of the last period of controller ``name``, nm."""
        return float(self.rms_nm[name][-1])

    def table(self) -> str:
        """A plain-text table: controllers by period."""
        n = len(next(iter(self.rms_nm.values())))
        rows = [f"{'nm RMS':<8}" + "".join(f"{k + 1:>8d}" for k in range(n))]
        for name, r in self.rms_nm.items():
            rows.append(f"{name:<8}" + "".join(f"{v:8.0f}" for v in r))
        return "\n".join(rows)


@dataclass(frozen=True, kw_only=True, eq=False)
class CircleSetting:
    """The circle of a `ComparisonConfig` at the twin's rate.

    Attributes
    ----------
    position, velocity, acceleration : numpy.ndarray
        Reference moved to the offset, mm, mm/s, mm/s², shape (n_samples, 2).
    start : int
        First sample of the first period.
    period_samples, periods : int
        Samples per period, periods.
    seed : int
        Twin seed.
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    start: int
    period_samples: int
    periods: int
    seed: int

    @property
    def one(self) -> slice:
        """The first period."""
        return slice(self.start, self.start + self.period_samples)

    def period_rms_nm(self, output: np.ndarray, offset: int = 0) -> np.ndarray:
        """RMS over both axes of ``r − y`` per period, nm, shape (periods,).

        ``output`` (mm, shape (n, 2)) starts at sample ``offset`` of the reference.
        """
        a, n = self.start, self.period_samples
        e = (self.position[offset:] - output)[a - offset : a - offset + self.periods * n]
        e = e.reshape(self.periods, n, 2)
        return np.sqrt(np.mean(e**2, axis=(1, 2))) * 1e6  # mm -> nm


def circle_setting(config: ComparisonConfig, dt: float = 1e-4) -> CircleSetting:
    """The circle of ``config`` at sample time ``dt`` (s; the twin's 10 kHz by default)."""
    ref = pattern_reference(config.pattern, dt)
    return CircleSetting(
        position=ref.position + config.offset_mm,
        velocity=ref.velocity,
        acceleration=ref.acceleration,
        start=int(ref.starts[0]),
        period_samples=int(ref.period_samples),
        periods=int(ref.periods),
        seed=config.seed,
    )


def compare_controllers(config: ComparisonConfig | None = None) -> ComparisonResult:
    """Run the four controllers on the same circle of the twin (seed 001 Figs. 8, 10).

    Parameters
    ----------
    config : ComparisonConfig, optional
        Defaults as documented there.

    Returns
    -------
    ComparisonResult
        Per-period RMS of each controller.
    """
    cfg = config or ComparisonConfig()
    plant = nanomanipulator.twin(seed=cfg.seed)
    dt = plant.dt
    ref = pattern_reference(cfg.pattern, dt)
    pos = ref.position + cfg.offset_mm
    vel, acc = ref.velocity, ref.acceleration
    n, s0, periods = ref.period_samples, ref.starts[0], ref.periods
    one = slice(s0, s0 + n)
    rbf = RBFAdaptive.for_reference(pos[one], vel[one], acc[one], dt, cfg.rbf)
    pid = PID.tuned(plant.continuous_models(), bandwidth_hz=cfg.pid_bandwidth_hz, dt=dt)
    window = ((s0, periods),)
    period_s = n * dt
    controllers = {
        "PID": pid,
        "RBF": rbf,
        "RBF+RC": PluginRC(
            rbf,
            RCConfig(period_s=period_s, dt=dt, windows=window, lead_samples=cfg.rc_lead_samples),
        ),
        "PID+RC": PluginRC(pid, RCConfig(period_s=period_s, dt=dt, windows=window)),
    }
    out: dict[str, np.ndarray] = {}
    for name in CONTROLLERS:  # the plant holds no state: each run starts from plant.init()
        res = nanomanipulator.play(
            controllers[name], pos, derivatives=(vel, acc), seed=cfg.seed, noise=cfg.noise
        )
        e = (pos - res.output)[s0 : s0 + periods * n].reshape(periods, n, 2)
        out[name] = np.sqrt(np.mean(e**2, axis=(1, 2))) * 1e6  # mm -> nm
    return ComparisonResult(config=cfg, rms_nm=out)
