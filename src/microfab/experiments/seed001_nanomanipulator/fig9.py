"""Seed 001 Fig. 9 on the twin: the RBF controller on one sine per axis, no cross-correlation.

Seed 001 §4.1: "we removed the cross-correlation between X and Y axes by taking sinusoidal
signals of irreducible frequencies as the references for each axis"; Fig. 9 shows curves
only, and the seed uses it to show that the RBF approximates the nonlinearity itself.
The project's target (issue 45, `paper.FIG_TARGETS` ``"fig9_rbf_over_pid_max"`` and
``"fig9_phase_margin_min_deg"``): on these sines, the proposed RBF's error below the
PID's at the same crossover (200 and 400 Hz), both loops with >= 45° phase margin
(`fig9_matched`, on the paper's model: eq. 9, the §4.1 terms and ``d(t)``, noise off;
with the circle's ``noise`` on, the same on the calibrated twin, a prediction).
`fig9_rbf` runs the seed's literal network (`RBFAdaptive.for_reference`) on the sines and
on the circle, as before.

Reference (ours; the seed gives no frequency, amplitude or start):
``r_a(t) = c + A E(t) sin(2π f_a (t − t_run))`` per axis ``a``, where

* ``f = (1, √2) Hz`` (assumed): x at the circle's 1 Hz, y at an irrational multiple of it,
  so the two never repeat together (no common period, no fixed phase between the axes;
  "irreducible" read as a frequency ratio that is no fraction; 1 and 1.3 Hz would repeat
  every 10 s). y then moves √2 and 2 times faster and harder than x.
* ``A`` = the circle's radius (the same stroke per axis as the circle, 0.15 mm peak to
  peak) and ``c`` = `compare.py`'s offset on the diagonal, (0.25, 0.25) mm.
* Start as the circle's: the reference sits at ``c`` from the first sample (the stage
  starts at rest at the origin: the same 0.25 mm step as `compare.py`) for the circle's
  ``move_s + pause_s``, then the envelope ``E`` rises from 0 to 1 over its ``ramp_s`` by
  ``10τ³ − 15τ⁴ + 6τ⁵`` (acceleration continuous), and ``t_run`` is its end.

RBF centres: `RBFAdaptive.for_reference` places its nodes along one period of the
reference, and these sines have none in common. We give it the first ``fit_s`` of the run
(default 1 s, one x period: x's whole cycle and 1.41 of y's), with ``closed=False`` (the
segment does not close on itself). Worst period of 8, nm RMS: 1 s 595 (closed=True 597),
2 s 571, 5 s 556, 10 s 623: the choice moves the result by ±6 %.

Errors are RMS over both axes of ``r − y`` (true output), per period of x (1 s windows),
as in `compare.py`; the circle case is `compare.py`'s RBF run (same twin, seed, RBF rule),
run again here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive
from microfab.control.repetitive import period_samples
from microfab.core.validate import check_positive
from microfab.experiments.seed001_nanomanipulator import paper
from microfab.experiments.seed001_nanomanipulator.compare import ComparisonConfig
from microfab.experiments.seed001_nanomanipulator.fig8 import discrete_phase_margin
from microfab.experiments.seed001_nanomanipulator.proposed import state_controller
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.plants.nanomanipulator import NanomanipulatorPlant
from microfab.report.tables import Table
from microfab.trajectory.circle_pattern import pattern_reference

__all__ = [
    "MATCHED_HZ",
    "Fig9Config",
    "Fig9Matched",
    "Fig9Reference",
    "Fig9Result",
    "fig9_matched",
    "fig9_rbf",
    "fig9_reference",
]

#: Crossovers of the matched comparison, Hz (issue 45: 200 and 400 Hz).
MATCHED_HZ = (200.0, 400.0)


@dataclass(frozen=True, kw_only=True)
class Fig9Config:
    """Two sines of irreducible frequencies, compared with the circle of `compare.py`.

    Parameters
    ----------
    frequencies_hz : tuple of float
        ``(f_x, f_y)``, Hz (assumed (1, √2): see the module docstring). ``1 / f_x`` must be
        a whole number of samples (it sets the RMS windows); the two must differ.
    fit_s : float
        Length of the reference, from the end of the ramp, that the RBF centres come from,
        s (assumed 1 s, one x period).
    circle : ComparisonConfig
        The circle case; its offset, amplitude (radius), lead-in, ramp, period count, RBF
        settings and seed are used here too.
    """

    frequencies_hz: tuple[float, float] = (1.0, math.sqrt(2.0))  # assumed
    fit_s: float = 1.0  # assumed
    circle: ComparisonConfig = field(default_factory=ComparisonConfig)

    def __post_init__(self) -> None:
        f = tuple(self.frequencies_hz)
        if len(f) != 2:
            raise ValueError(f"frequencies_hz needs one frequency per axis (x, y), got {f!r} Hz")
        fx = check_positive("frequencies_hz[x]", f[0], "Hz")
        fy = check_positive("frequencies_hz[y]", f[1], "Hz")
        if fx == fy:
            raise ValueError(
                f"frequencies_hz are equal ({fx:g} Hz): equal sines correlate the axes; "
                "give frequencies whose ratio is no fraction, e.g. (1, 2 ** 0.5)"
            )
        object.__setattr__(self, "frequencies_hz", (fx, fy))
        check_positive("fit_s", self.fit_s, "s")
        if not isinstance(self.circle, ComparisonConfig):
            raise ValueError(f"circle must be a ComparisonConfig, got {type(self.circle).__name__}")

    @property
    def amplitude_mm(self) -> float:
        """Amplitude of each sine, mm: the circle's radius."""
        return self.circle.pattern.diameter_mm / 2.0

    @property
    def periods(self) -> int:
        """Periods of x run (the RMS windows): as many as the circle's."""
        return self.circle.pattern.periods


@dataclass(frozen=True, kw_only=True, eq=False)
class Fig9Reference:
    """The Fig. 9 reference.

    Attributes
    ----------
    position, velocity, acceleration : numpy.ndarray
        mm, mm/s, mm/s², shape (n_samples, 2).
    start : int
        First sample at full amplitude (``t_run``).
    period_samples : int
        Samples per x period (the RMS window).
    periods : int
        x periods after ``start``.
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    start: int
    period_samples: int
    periods: int


def fig9_reference(config: Fig9Config, dt: float, periods: float | None = None) -> Fig9Reference:
    """The two sines with their lead-in and ramp (module docstring).

    Parameters
    ----------
    config : Fig9Config
        Frequencies and the circle case they follow.
    dt : float
        Sample time, s.
    periods : float, optional
        x periods after the ramp (default ``config.periods``); the run ends there, moving.

    Raises
    ------
    ValueError
        When ``1 / f_x`` is not a whole number of samples, or a duration is not positive.
    """
    check_positive("dt", dt, "s")
    fx, fy = config.frequencies_hz
    n_per = period_samples(1.0 / fx, dt)
    m = config.periods if periods is None else check_positive("periods", periods, "periods")
    pat = config.circle.pattern
    n_lead = max(round((pat.move_s + pat.pause_s) / dt), 1)
    n_ramp = max(round(pat.ramp_s / dt), 1)
    start = n_lead + n_ramp
    n = start + math.ceil(m * n_per)
    k = np.arange(n)
    tau = np.clip((k - n_lead) / n_ramp, 0.0, 1.0)
    ramping = (k >= n_lead) & (k < start)
    T = n_ramp * dt
    E = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    dE = np.where(ramping, (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / T, 0.0)
    ddE = np.where(ramping, (60 * tau - 180 * tau**2 + 120 * tau**3) / T**2, 0.0)
    t = (k - start) * dt
    A, c = config.amplitude_mm, config.circle.offset_mm
    pos, vel, acc = (np.empty((n, 2)) for _ in range(3))
    for a, f in enumerate((fx, fy)):
        w = 2 * math.pi * f
        sn, cs = np.sin(w * t), np.cos(w * t)
        pos[:, a] = c + A * E * sn
        vel[:, a] = A * (dE * sn + E * w * cs)
        acc[:, a] = A * (ddE * sn + 2 * dE * w * cs - E * w * w * sn)
    return Fig9Reference(
        position=pos,
        velocity=vel,
        acceleration=acc,
        start=start,
        period_samples=n_per,
        periods=math.floor(m),
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class Fig9Result:
    """RBF tracking error per x period on the sines, and on the circle.

    Attributes
    ----------
    config : Fig9Config
        What ran.
    rms_nm : numpy.ndarray
        RMS over both axes of ``r − y`` per x period, nm, shape (periods,).
    rms_axes_nm : numpy.ndarray
        The same per axis, nm, shape (periods, 2).
    circle_rms_nm : numpy.ndarray
        `compare.py`'s RBF on its circle, per period, nm, shape (periods,).
    """

    config: Fig9Config
    rms_nm: np.ndarray
    rms_axes_nm: np.ndarray
    circle_rms_nm: np.ndarray

    def ratio(self) -> float:
        """Worst period on the sines over the circle's last period (the target's ratio)."""
        return float(self.rms_nm.max() / self.circle_rms_nm[-1])

    def table(self) -> str:
        """A plain-text table: sines (both axes, x, y) and circle by period."""
        n = self.rms_nm.size
        rows = [f"{'nm RMS':<8}" + "".join(f"{k + 1:>8d}" for k in range(n))]
        for name, r in (
            ("sines", self.rms_nm),
            ("  x", self.rms_axes_nm[:, 0]),
            ("  y", self.rms_axes_nm[:, 1]),
            ("circle", self.circle_rms_nm),
        ):
            rows.append(f"{name:<8}" + "".join(f"{v:8.0f}" for v in r))
        return "\n".join(rows)


def _rms_per_period(err: np.ndarray, start: int, n: int, periods: int) -> np.ndarray:
    """RMS of ``err`` (mm, (samples, 2)) per window, nm, shape (periods, 2)."""
    e = err[start : start + periods * n].reshape(periods, n, 2)
    return np.sqrt(np.mean(e**2, axis=1)) * 1e6


def _circle_rbf(cfg: ComparisonConfig, plant: NanomanipulatorPlant) -> np.ndarray:
    """`compare.py`'s RBF run on its circle: RMS over both axes per period, nm."""
    dt = plant.dt
    ref = pattern_reference(cfg.pattern, dt)
    pos = ref.position + cfg.offset_mm
    vel, acc = ref.velocity, ref.acceleration
    n, s0 = ref.period_samples, ref.starts[0]
    one = slice(s0, s0 + n)
    rbf = RBFAdaptive.for_reference(pos[one], vel[one], acc[one], dt, cfg.rbf)
    res = nanomanipulator.play(rbf, pos, derivatives=(vel, acc), seed=cfg.seed, noise=cfg.noise)
    per_axis = _rms_per_period(pos - res.output, s0, n, ref.periods)
    return np.sqrt(np.mean(per_axis**2, axis=1))


def fig9_rbf(config: Fig9Config | None = None) -> Fig9Result:
    """Run the RBF controller on the Fig. 9 sines and on the circle, on the same twin.

    Parameters
    ----------
    config : Fig9Config, optional
        Defaults as documented there (noise as the circle case's, off by default).

    Returns
    -------
    Fig9Result
        Per-period RMS on the sines (both axes and per axis) and on the circle.
    """
    cfg = config or Fig9Config()
    circle = cfg.circle
    plant = nanomanipulator.twin(seed=circle.seed)
    dt = plant.dt
    ref = fig9_reference(cfg, dt)
    n_fit = max(round(cfg.fit_s / dt), circle.rbf.n_nodes)
    fit = ref
    if n_fit > ref.period_samples * ref.periods:  # longer than the run: the sines, extended
        fit = fig9_reference(cfg, dt, periods=n_fit / ref.period_samples)
    one = slice(fit.start, fit.start + n_fit)
    rbf = RBFAdaptive.for_reference(
        fit.position[one], fit.velocity[one], fit.acceleration[one], dt, circle.rbf, closed=False
    )
    res = nanomanipulator.play(
        rbf,
        ref.position,
        derivatives=(ref.velocity, ref.acceleration),
        seed=circle.seed,
        noise=circle.noise,
    )
    per_axis = _rms_per_period(
        ref.position - res.output, ref.start, ref.period_samples, ref.periods
    )
    return Fig9Result(
        config=cfg,
        rms_nm=np.sqrt(np.mean(per_axis**2, axis=1)),
        rms_axes_nm=per_axis,
        circle_rms_nm=_circle_rbf(circle, plant),
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class Fig9Matched:
    """PID against the proposed RBF on the sines, per crossover (`fig9_matched`).

    Attributes
    ----------
    bandwidths_hz : tuple of float
        Crossovers, Hz.
    rms_nm : dict of str to numpy.ndarray
        ``"PID"`` and ``"RBF"``: RMS over both axes per x period, nm, shape
        (n_bandwidths, periods); NaN where the loop diverged.
    phase_margin_deg : dict of str to numpy.ndarray
        Phase margin of the discrete loop (ZOH eq. 9 with the controller's linear
        part, both axes, the smaller), deg, shape (n_bandwidths,).
    """

    bandwidths_hz: tuple[float, ...]
    rms_nm: dict[str, np.ndarray]
    phase_margin_deg: dict[str, np.ndarray]

    def final(self, name: str) -> np.ndarray:
        """Last period's RMS of ``name`` per crossover, nm."""
        return self.rms_nm[name][:, -1]

    def ratio(self) -> np.ndarray:
        """RBF over PID, last period, per crossover."""
        return self.final("RBF") / self.final("PID")

    def as_table(self, model: str) -> Table:
        """Per crossover: margins, last-period RMS of both, RBF / PID and the target.

        Parameters
        ----------
        model : str
            What ran, for the title (``"paper's model (noise off)"``, ...).
        """
        top = paper.FIG_TARGETS["fig9_rbf_over_pid_max"]  # the project's, not seed data
        pm_min = paper.FIG_TARGETS["fig9_phase_margin_min_deg"]

        def cell(v: float, fmt: str = "{:.0f}") -> str:
            return fmt.format(v) if np.isfinite(v) else "diverged"

        rows = []
        n = self.rms_nm["PID"].shape[1]
        for i, f in enumerate(self.bandwidths_hz):
            pid, rbf = self.final("PID")[i], self.final("RBF")[i]
            pm = (self.phase_margin_deg["PID"][i], self.phase_margin_deg["RBF"][i])
            met = rbf / pid <= top and min(pm) >= pm_min - 0.5  # the design's 45° to its grid
            rows.append(
                (
                    f"{f:g}",
                    f"{pm[0]:.1f}",
                    f"{pm[1]:.1f}",
                    cell(pid),
                    cell(rbf),
                    cell(rbf / pid, "{:.2f}"),
                    "yes" if met else "no",
                )
            )
        return Table(
            title=f"Seed 001 Fig. 9, PID against RBF on two uncorrelated sines, last of {n} "
            f"periods, RMS [nm], {model}",
            columns=(
                "f_c [Hz]",
                "PID PM [deg]",
                "RBF PM [deg]",
                "PID",
                "RBF",
                "RBF / PID",
                f"RBF / PID <= {top:g}, PM >= {pm_min:g}°",
            ),
            rows=rows,
            note="x 1 Hz, y √2 Hz (no common period), the circle's stroke and offset, d(t) "
            "and the §4.1 terms on; PID = PID.tuned on eq. 9 at f_c, 45°, eq. 9's inverse "
            "feedforward; RBF = the same design without its integral plus the state-model "
            "network (a grid over the sines' state box, Ŵ(0) = 0). Seed: 'the RBF-based "
            "control remains a good tracking performance' (curves only); the project's "
            f"target (issue 45): RBF below the PID at each f_c with >= {pm_min:g}° margin.",
        )

    def table(self) -> str:
        """A plain-text table: per crossover and controller, PM and RMS by period."""
        n = self.rms_nm["PID"].shape[1]
        rows = [f"{'f_c':>5} {'':<4} {'PM':>5}" + "".join(f"{k + 1:>7d}" for k in range(n))]
        for i, f in enumerate(self.bandwidths_hz):
            for c in ("PID", "RBF"):
                rows.append(
                    f"{f:5.0f} {c:<4} {self.phase_margin_deg[c][i]:5.1f}"
                    + "".join(f"{v:7.0f}" for v in self.rms_nm[c][i])
                )
        return "\n".join(rows)


def fig9_matched(
    config: Fig9Config | None = None, bandwidths_hz: tuple[float, ...] = MATCHED_HZ
) -> Fig9Matched:
    """PID and the proposed RBF at the same crossover on the Fig. 9 sines (module notes).

    ``PID``: `PID.tuned` on eq. 9 at ``f_c``, 45°, with eq. 9's inverse feedforward (as
    `fig8.fair_fig8`). ``RBF``: `proposed.state_controller`, the same design without its
    integral plus the state-model network on the sines' state box, ``Ŵ(0) = 0``. Both on
    the paper's model (eq. 9, the §4.1 terms, ``d(t)``, sensor noise off) from rest, or,
    with ``config.circle.noise``, on the calibrated twin (its sensor noise on).

    Parameters
    ----------
    config : Fig9Config, optional
        The sines (default `Fig9Config()`; its circle's seed and noise setting).
    bandwidths_hz : tuple of float
        Crossovers, Hz.

    Returns
    -------
    Fig9Matched
    """
    cfg = config or Fig9Config()
    seed = cfg.circle.seed
    plant = nanomanipulator.twin(seed=seed)
    dt = plant.dt
    ref = fig9_reference(cfg, dt)
    run = slice(ref.start, None)
    rms = {c: np.full((len(bandwidths_hz), ref.periods), np.nan) for c in ("PID", "RBF")}
    pm = {c: np.full(len(bandwidths_hz), np.nan) for c in ("PID", "RBF")}
    for i, fc in enumerate(bandwidths_hz):
        pid = PID.tuned(plant.continuous_models(), bandwidth_hz=fc, dt=dt, feedforward=True)
        rbf = state_controller(
            plant, fc, ref.position[run], ref.velocity[run], ref.acceleration[run]
        )
        for name, ctrl, lin in (("PID", pid, pid), ("RBF", rbf, rbf.linear)):
            pm[name][i] = discrete_phase_margin(lin, plant)  # type: ignore[arg-type]
            res = nanomanipulator.play(
                ctrl,
                ref.position,
                derivatives=(ref.velocity, ref.acceleration),
                seed=seed,
                noise=cfg.circle.noise,
            )
            per_axis = _rms_per_period(
                ref.position - res.output, ref.start, ref.period_samples, ref.periods
            )
            r = np.sqrt(np.mean(per_axis**2, axis=1))
            rms[name][i] = np.where(np.isfinite(r), r, np.nan)
    return Fig9Matched(bandwidths_hz=tuple(bandwidths_hz), rms_nm=rms, phase_margin_deg=pm)
