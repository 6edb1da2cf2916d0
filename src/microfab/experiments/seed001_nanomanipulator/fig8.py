"""Seed 001 Fig. 8 compared fairly: PID against RBF at the same bandwidth, per bandwidth.

Fig. 8 says "the proposed RBF controller significantly outperforms the PID controller in
the presence of an unknown parametric nonlinearity" (curves only; the project's target
is RBF <= PID / 3, `paper.FIG_TARGETS`). `compare.py` sets the seed's network (the whole
command, eq. 4) against a 200 Hz PID; here, per crossover ``f_c``, every controller has
the same crossover, 45° phase margin and eq. 9's model-inverse feedforward:

* ``PID``: `PID.tuned` on eq. 9 at ``f_c``, 45° (the margin of the discrete loop, ZOH
  plant and Tustin PID, both axes, is measured and printed; a crossover the design cannot
  reach at 45° is left out), with eq. 9's inverse feedforward;
* ``PID+RBF``: that PID plus the eq. 2-5 network of `proposed.local_network`
  (`RBFPlusLinear`): the same linear part exactly;
* ``RBF``: `proposed.proposed_controller`: eq. 6's linear part (the same design without
  the integral, eq. 9's inverse) plus the same network (centres along the orbit: a
  memory of the repeating path);
* ``RBF state``: `proposed.state_controller`: the same linear part plus the network as a
  model of the state (centres on a grid over the circle's state box, issue 45), the one
  that holds on Fig. 9's non-repeating sines;
* ``oracle``: ``RBF`` with its network replaced by the true nonlinearity
  (`proposed.proposed_oracle`): the best the network could do.

All on `compare.py`'s circle (0.25 mm off-centre: the §4.1 terms active), noise off,
``d(t)`` on, the RMS of the last of 8 periods; ``ComparisonConfig(noise=True)`` runs the
same on the calibrated twin (its sensor noise, rms and colour, as the data file has them).

**Finer sweep and divergences** (issue 45): `fine_fig8` runs the octaves, then 10 Hz steps
within ±50 Hz of each controller's best, widening while a best sits on the edge of what
ran. A run whose output leaves the finite numbers is a divergence: `Fig8Sweep.divergences`
lists each with its measured cause (`Divergence`): the sample where it left, the speed
the stage reached before it and the §4.1 ``β`` there over eq. 9's ``β_l``, beside the
sampled linear loop's phase margin and its distance to −1 (the linear loop at that
crossover, ZOH eq. 9 and the Tustin PID).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from microfab.control.base import Controller
from microfab.control.pid import PID, pid_frequency_response
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_composite import RBFPlusLinear
from microfab.experiments.seed001_nanomanipulator.compare import (
    CircleSetting,
    ComparisonConfig,
    circle_setting,
)
from microfab.experiments.seed001_nanomanipulator.proposed import (
    local_network,
    proposed_controller,
    proposed_oracle,
    state_controller,
)
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.plants.nanomanipulator import NanomanipulatorPlant, drift_and_gain
from microfab.report.tables import Table

__all__ = [
    "BANDWIDTHS_HZ",
    "CONTROLLERS",
    "Divergence",
    "Fig8Row",
    "Fig8Sweep",
    "discrete_phase_margin",
    "fair_fig8",
    "fine_fig8",
    "nyquist_distance",
]

#: Crossovers swept, Hz (assumed: octaves around the 200 Hz of `compare.py`; at 800 Hz
#: the design reaches 45° on the discrete loop but all three loops diverged on the twin).
BANDWIDTHS_HZ = (100.0, 200.0, 400.0)
CONTROLLERS = ("PID", "PID+RBF", "RBF", "RBF state", "oracle")
FINE_STEP_HZ = 10.0  # issue 45: steps <= 10 Hz ...
FINE_SPAN_HZ = 50.0  # ... within ±50 Hz of each controller's best


def discrete_phase_margin(pid: PID, plant: NanomanipulatorPlant) -> float:
    """Smallest phase margin over both axes of the discrete loop (ZOH eq. 9, Tustin PID), deg.

    Evaluated at the highest gain crossover on a log grid from 1 Hz to 0.999 Nyquist.
    """
    dt = plant.dt
    f = np.geomspace(1.0, 0.999 / (2 * dt), 100_000)
    P = plant.linear_model().frequency_response(f)  # ZOH eq. 9, both axes, (n, 2, 2)
    pms = []
    for a, g in enumerate(pid.gains):
        L = P[:, a, a] * pid_frequency_response(g, f, dt)
        i = np.flatnonzero(np.diff(np.sign(np.abs(L) - 1.0)) != 0)
        if i.size == 0:
            return math.nan
        pms.append(float(np.rad2deg(np.angle(L[i[-1]])) % 360.0 - 180.0))
    return min(pms)


def nyquist_distance(pid: PID, plant: NanomanipulatorPlant) -> float:
    """Smallest ``|1 + L|`` over both axes of the discrete loop (ZOH eq. 9, Tustin PID).

    On the same grid as `discrete_phase_margin`; 0 where the loop is at the edge of
    stability, about 0.7 for a 45° margin loop.
    """
    dt = plant.dt
    f = np.geomspace(1.0, 0.999 / (2 * dt), 100_000)
    P = plant.linear_model().frequency_response(f)
    return min(
        float(np.min(np.abs(1.0 + P[:, a, a] * pid_frequency_response(g, f, dt))))
        for a, g in enumerate(pid.gains)
    )


@dataclass(frozen=True, kw_only=True)
class Divergence:
    """A run that left the finite numbers, and what was measured about it.

    Attributes
    ----------
    bandwidth_hz : float
        Crossover, Hz.
    controller : str
        One of `CONTROLLERS`.
    sample : int
        First sample whose output is not finite.
    speed_mm_s : float
        Largest speed of the finite output before it (finite differences), mm/s.
    beta_ratio : float
        The §4.1 ``β`` at that speed over eq. 9's ``β_l`` (the axis where it is
        largest).
    phase_margin_deg, nyquist_distance : float
        The sampled linear loop's margin and ``min |1 + L|`` at this crossover.
    """

    bandwidth_hz: float
    controller: str
    sample: int
    speed_mm_s: float
    beta_ratio: float
    phase_margin_deg: float
    nyquist_distance: float

    @property
    def beta_term(self) -> bool:
        """Whether the measurements point to the §4.1 β term (linear loop sound, β >= 1.5 β_l)."""
        return self.linear_ok and self.beta_ratio >= 1.5

    @property
    def linear_ok(self) -> bool:
        """Whether the sampled linear loop keeps a margin (PM > 0, min |1 + L| > 0.1)."""
        return self.phase_margin_deg > 0 and self.nyquist_distance > 0.1

    def short(self) -> str:
        """One line: controller, crossover, sample, speed and β there."""
        return (
            f"{self.controller} {self.bandwidth_hz:g} Hz (sample {self.sample}, "
            f"{self.speed_mm_s:.0f} mm/s, β {self.beta_ratio:.1f}x β_l)"
        )

    def cause(self) -> str:
        """The cause the measurements point to, in words."""
        linear_ok = self.linear_ok
        if self.beta_term:
            why = (
                f"the stage reached {self.speed_mm_s:.0f} mm/s, where the §4.1 β (its x2² "
                f"term) is {self.beta_ratio:.1f}x β_l and grows with the square of the speed "
                "(ẍ ∝ x2² u runs away); the sampled linear loop is stable there "
                f"(PM {self.phase_margin_deg:.1f}°, min |1 + L| {self.nyquist_distance:.2f})"
            )
        elif not linear_ok:
            why = (
                f"the sampled linear loop is at or past its limit (PM "
                f"{self.phase_margin_deg:.1f}°, min |1 + L| {self.nyquist_distance:.2f})"
            )
        else:
            why = (
                f"cause not identified (speed {self.speed_mm_s:.0f} mm/s, β {self.beta_ratio:.2f}"
                f"x β_l, PM {self.phase_margin_deg:.1f}°, min |1 + L| "
                f"{self.nyquist_distance:.2f})"
            )
        return (
            f"{self.controller} at {self.bandwidth_hz:g} Hz diverged at sample {self.sample}: {why}"
        )


def _divergence_note(divs: tuple[Divergence, ...]) -> str:
    """The divergences for a table note: one shared cause, or each with its own."""
    if not divs:
        return ""
    if all(d.beta_term for d in divs):
        return (
            " Diverged (the stage thrown by the first samples to a speed where the §4.1 β "
            "term in x2² is several times β_l and grows with the square of the speed; the "
            "sampled linear loop keeps its margin there): "
            + "; ".join(d.short() for d in divs)
            + "."
        )
    return "".join(f" Diverged: {d.cause()}." for d in divs)


def _divergence(
    fc: float, name: str, output: np.ndarray, plant: NanomanipulatorPlant, pm: float, dist: float
) -> Divergence | None:
    """`Divergence` of a run whose ``output`` (mm, (n, 2)) is not finite, else None."""
    bad = ~np.all(np.isfinite(output), axis=1)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    y = output[:k]
    dt = plant.dt
    v = np.diff(y, axis=0) / dt if k >= 2 else np.zeros((1, 2))
    j = int(np.argmax(np.max(np.abs(v), axis=1)))
    x = np.array([y[j + 1, 0], v[j, 0], y[j + 1, 1], v[j, 1]]) if k >= 2 else np.zeros(4)
    lin = nanomanipulator.twin(seed=plant.config.disturbance_seed, nonlinear=False)
    ratio = max(
        drift_and_gain(plant.params, a, x)[1] / drift_and_gain(lin.params, a, x)[1]
        for a in range(2)
    )
    return Divergence(
        bandwidth_hz=fc,
        controller=name,
        sample=k,
        speed_mm_s=float(np.max(np.abs(v[j]))),
        beta_ratio=float(ratio),
        phase_margin_deg=pm,
        nyquist_distance=dist,
    )


@dataclass(frozen=True, kw_only=True)
class Fig8Row:
    """One crossover: margin and per-period RMS of each controller.

    Attributes
    ----------
    bandwidth_hz : float
        Crossover ``f_c``, Hz.
    phase_margin_deg : float
        Measured margin of the discrete PID loop, deg (NaN: not designable).
    rms_nm : dict of str to numpy.ndarray
        `CONTROLLERS`: RMS per period, nm, shape (periods,) (NaN when
        the loop diverged).
    """

    bandwidth_hz: float
    phase_margin_deg: float
    rms_nm: dict[str, np.ndarray]

    def final(self, name: str) -> float:
        """Last period's RMS of ``name``, nm."""
        return float(self.rms_nm[name][-1])


@dataclass(frozen=True, kw_only=True, eq=False)
class Fig8Sweep:
    """The sweep and the best of each controller.

    Attributes
    ----------
    rows : tuple of Fig8Row
        Per designable crossover, by crossover.
    skipped : tuple of str
        Crossovers left out and why.
    gamma : float
        Γ of the orbit network, V/mm.
    divergences : tuple of Divergence
        Every run that diverged, with its measured cause.
    """

    rows: tuple[Fig8Row, ...]
    skipped: tuple[str, ...]
    gamma: float
    divergences: tuple[Divergence, ...] = field(default=())

    def best(self, name: str) -> tuple[float, float]:
        """``(RMS nm, f_c Hz)`` of the best finite last-period RMS of ``name``."""
        vals = [
            (r.final(name), r.bandwidth_hz)
            for r in self.rows
            if name in r.rms_nm and np.isfinite(r.final(name))
        ]
        return min(vals) if vals else (math.nan, math.nan)

    def table(self) -> str:
        """A plain-text table: last-period RMS per crossover, then the best of each."""
        rows = [f"{'f_c [Hz]':>9} {'PM [deg]':>9}" + "".join(f"{c:>10}" for c in CONTROLLERS)]
        # (NaN: diverged, listed below)
        for r in self.rows:
            rows.append(
                f"{r.bandwidth_hz:9.0f} {r.phase_margin_deg:9.1f}"
                + "".join(f"{r.final(c):10.0f}" for c in CONTROLLERS if c in r.rms_nm)
            )
        rows.append(
            "best: "
            + ", ".join(
                f"{c} {v:.0f} nm at {f:.0f} Hz" for c in CONTROLLERS for v, f in [self.best(c)]
            )
        )
        rows += [f"skipped: {s}" for s in self.skipped]
        rows += [f"diverged: {d.cause()}" for d in self.divergences]
        return "\n".join(rows)

    def as_table(self, model: str = "") -> Table:
        """Last-period RMS per crossover as a report `Table` (NaN: diverged).

        Parameters
        ----------
        model : str
            What ran, appended to the title (``"calibrated twin (noise on)"``, ...).
        """

        def cell(v: float) -> str:
            return f"{v:.0f}" if np.isfinite(v) else "diverged"

        ran = tuple(c for c in CONTROLLERS if any(c in r.rms_nm for r in self.rows))
        rows = [
            (f"{r.bandwidth_hz:g}", f"{r.phase_margin_deg:.1f}",
             *(cell(r.final(c)) if c in r.rms_nm else "" for c in ran))
            for r in self.rows
        ]  # fmt: skip
        best = "; ".join(f"{c} {v:.0f} nm at {f:g} Hz" for c in ran for v, f in [self.best(c)])
        return Table(
            title="Seed 001 Fig. 8, fair: last of 8 periods, RMS [nm], same crossover and margin"
            + (f", {model}" if model else ""),
            columns=("f_c [Hz]", "PM [deg]", *ran),  # the controllers that ran
            rows=rows,
            note=f"Best: {best}. All with 45° at f_c and eq. 9's inverse feedforward. "
            "PID+RBF = the same PID plus the eq. 2-5 network (centres along the orbit, "
            f"s_spread = 0, Γ = {self.gamma:.3f} V/mm); RBF = the PID's design without its "
            "integral (eq. 6's linear part) plus the same network; RBF state = that linear "
            "part plus the network as a model of the state (a grid over the circle's state "
            "box); oracle = RBF with the network replaced by the true §4.1 terms. Seed: "
            "'the proposed RBF controller significantly outperforms the PID' (curves only; "
            "the project's target RBF <= PID/3)."
            + "".join(f" Skipped {s}." for s in self.skipped)
            + _divergence_note(self.divergences),
        )


def fair_fig8(
    config: ComparisonConfig | None = None,
    bandwidths_hz: tuple[float, ...] = BANDWIDTHS_HZ,
    controllers: tuple[str, ...] = CONTROLLERS,
) -> Fig8Sweep:
    """Run `CONTROLLERS` per crossover (module notes).

    Parameters
    ----------
    config : ComparisonConfig, optional
        Circle, RBF settings, seed and sensor noise (default `ComparisonConfig()`: noise
        off, the paper's model; ``noise=True``: the calibrated twin's sensor noise).
    bandwidths_hz : tuple of float
        Crossovers, Hz.
    controllers : tuple of str
        Which of `CONTROLLERS` to run (default all).

    Returns
    -------
    Fig8Sweep
    """
    cfg = config or ComparisonConfig()
    plant = nanomanipulator.twin(seed=cfg.seed)
    dt = plant.dt
    st = circle_setting(cfg, dt)
    net = local_network(st, cfg.rbf, dt)
    unknown = set(controllers) - set(CONTROLLERS)
    if unknown:
        raise ValueError(f"unknown controllers {sorted(unknown)}; choose from {CONTROLLERS}")
    rows, skipped, diverged = [], [], []
    for fc in bandwidths_hz:
        try:
            pid = PID.tuned(plant.continuous_models(), bandwidth_hz=fc, dt=dt, feedforward=True)
        except ValueError as exc:
            skipped.append(f"{fc:g} Hz: {exc}")
            continue
        pm = discrete_phase_margin(pid, plant)
        if not pm >= 45.0 - 0.5:  # the design's 45° to its grid
            skipped.append(f"{fc:g} Hz: measured phase margin {pm:.1f} deg < 45 deg")
            continue
        dist = nyquist_distance(pid, plant)
        rms = {}
        for name in (c for c in CONTROLLERS if c in controllers):
            res = nanomanipulator.play(
                _controller(name, pid, net, st, plant, fc, cfg),
                st.position,
                derivatives=(st.velocity, st.acceleration),
                seed=cfg.seed,
                noise=cfg.noise,
            )
            r = st.period_rms_nm(res.output)
            rms[name] = np.where(np.isfinite(r), r, np.nan)
            d = _divergence(fc, name, res.output, plant, pm, dist)
            if d is not None:
                diverged.append(d)
        rows.append(Fig8Row(bandwidth_hz=fc, phase_margin_deg=pm, rms_nm=rms))
    gamma = float(np.mean(net.config.gamma_diagonal()))
    return Fig8Sweep(
        rows=tuple(rows), skipped=tuple(skipped), gamma=gamma, divergences=tuple(diverged)
    )


def _controller(
    name: str,
    pid: PID,
    net: RBFAdaptive,
    st: CircleSetting,
    plant: NanomanipulatorPlant,
    fc: float,
    cfg: ComparisonConfig,
) -> Controller:
    """Controller ``name`` of `CONTROLLERS` at crossover ``fc`` (module notes)."""
    run = slice(st.start, None)
    if name == "PID":
        return pid
    if name == "PID+RBF":
        return RBFPlusLinear(pid, net)
    if name == "RBF":
        return proposed_controller(st, plant, fc, cfg.rbf)
    if name == "RBF state":
        return state_controller(plant, fc, st.position[run], st.velocity[run], st.acceleration[run])
    return proposed_oracle(plant, fc, cfg.rbf)


def fine_fig8(
    config: ComparisonConfig | None = None,
    bandwidths_hz: tuple[float, ...] = BANDWIDTHS_HZ,
    *,
    step_hz: float = FINE_STEP_HZ,
    span_hz: float = FINE_SPAN_HZ,
    max_rounds: int = 4,
) -> Fig8Sweep:
    """`fair_fig8` on ``bandwidths_hz``, then ``step_hz`` steps within ``±span_hz`` of each best.

    After each round, every controller's best crossover (finite last period) gets the
    grid ``best ± span_hz`` in ``step_hz`` steps; the crossovers not yet run are run. It
    stops when a round adds none, or after ``max_rounds`` (the CLI's full sweep: about
    15 crossovers, ~1 min).

    Returns
    -------
    Fig8Sweep
        All rows by crossover, their divergences and skips.
    """
    cfg = config or ComparisonConfig()
    sweep = fair_fig8(cfg, bandwidths_hz)
    for _ in range(max_rounds):
        done = {r.bandwidth_hz for r in sweep.rows} | set(bandwidths_hz)
        want: set[float] = set()
        for c in CONTROLLERS:
            best = sweep.best(c)[1]
            if math.isfinite(best):
                k = round(span_hz / step_hz)
                want |= {best + i * step_hz for i in range(-k, k + 1) if best + i * step_hz > 0}
        new = tuple(sorted(want - done - {float(s.split(" Hz")[0]) for s in sweep.skipped}))
        if not new:
            break
        more = fair_fig8(cfg, new)
        rows = sorted(sweep.rows + more.rows, key=lambda r: r.bandwidth_hz)
        sweep = Fig8Sweep(
            rows=tuple(rows),
            skipped=sweep.skipped + more.skipped,
            gamma=sweep.gamma,
            divergences=tuple(
                sorted(sweep.divergences + more.divergences, key=lambda d: d.bandwidth_hz)
            ),
        )
    return sweep
