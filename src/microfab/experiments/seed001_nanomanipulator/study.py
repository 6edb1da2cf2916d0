"""Why the RBF of seed 001 does not learn over periods, and the one that does: a per-period study.

Setting: `compare.py`'s circle (0.15 mm, 0.25 mm off-centre on the diagonal, 1 s period,
8 periods, noise off, ``d(t)`` and the §4.1 ``α``, ``β`` terms on). Two controllers, each
in three variants:

* ``seed``: the seed's network as the whole command (eqs. 2, 4, 5; default rule of
  `RBFAdaptive.for_reference`). The stage is brought along the circle's lead-in under the
  Fig. 8 PID (move, pause, spin-up) and at the first sample of the first period the loop
  is handed over (`microfab.control.rbf_handover`: bumpless, ``ζ_h = 1``) to the network
  ``adaptive``; to the same network with the hand-over weights held (``frozen``, Γ → 0);
  or to its ideal, eq. 6 with the twin's true ``α``, ``β`` (``oracle``,
  `microfab.control.certainty`, same ``λ``, ``ε``, velocity filter).
* ``proposed`` (`proposed.py`): eq. 6's linear part from eq. 9 (PD at 200 Hz, 45°, plus
  eq. 9's inverse) plus the network with centres along the orbit (``s_spread = 0``),
  from rest with ``Ŵ(0) = 0``: ``adaptive``; ``frozen`` (``Ŵ = 0`` held: the linear part
  alone); ``oracle`` (the network replaced by the true nonlinearity,
  `NonlinearityOracle`).

Per period: the RMS tracking error over both axes (``r − y``, nm) and ‖Ŵ‖ (mean over the
period, both axes together, V; replayed from the measurements, the network's update
depends on nothing else). Beside them, what the regressor looks like on the circle: the
range of every ``h_j`` over the orbit and the mean ``Σ_j h_j²``, for the default rule and
for ``s_spread = 0``. `LearningStudy.table` prints it; `microfab.report.
nanomanipulator_study` draws it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from microfab.control.certainty import CertaintyEquivalence
from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_composite import RBFPlusLinear
from microfab.control.rbf_handover import feedback_gain, handover
from microfab.experiments.seed001_nanomanipulator.compare import (
    CircleSetting,
    ComparisonConfig,
    circle_setting,
)
from microfab.experiments.seed001_nanomanipulator.proposed import (
    orbit_z,
    proposed_controller,
    proposed_oracle,
)
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.plants.nanomanipulator import NanomanipulatorPlant, drift_and_gain
from microfab.report.tables import Table
from microfab.sim.loop import LoopState
from microfab.sim.result import SimResult

__all__ = [
    "BLOCKS",
    "ROWS",
    "VARIANTS",
    "LearningStudy",
    "RegressorStats",
    "handed_over",
    "learning_study",
    "regressor_stats",
]

#: The three variants, in the order of the table.
VARIANTS = ("adaptive", "frozen", "oracle")
#: The two controllers studied.
BLOCKS = ("seed", "proposed")
#: Row names: ``"<block> <variant>"``.
ROWS = tuple(f"{b} {v}" for b in BLOCKS for v in VARIANTS)
_HANDOVER_MEAN_S = 0.01  # assumed: mean of the last 10 ms of the PID's signals (as the job)


@dataclass(frozen=True, kw_only=True)
class RegressorStats:
    """What ``h(z)`` of the x network looks like along one period of the reference.

    Attributes
    ----------
    rule : str
        Which centres: ``"default"`` or ``"s_spread = 0"``.
    width_mean : float
        Mean width ``b_j``, scaled units (the orbit's position span is 2).
    h_min, h_max : float
        Smallest and largest ``h_j`` over all nodes and samples.
    sum_h2 : float
        Mean over the period of ``Σ_j h_j²`` (dimensionless).
    gain : float
        ``Γ Σ h_j²``: the rate at which the adaptive law (eq. 5) changes the network's
        output per unit ``s`` when every node sees the same ``s``, V/mm.
    """

    rule: str
    width_mean: float
    h_min: float
    h_max: float
    sum_h2: float
    gain: float


@dataclass(frozen=True, kw_only=True, eq=False)
class LearningStudy:
    """Per-period error and ‖Ŵ‖ of the three variants, and the regressor statistics.

    Attributes
    ----------
    config : ComparisonConfig
        The circle and the RBF settings.
    rms_nm : dict of str to numpy.ndarray
        Per row of `ROWS` (``"seed adaptive"``, ...), RMS error per period over both
        axes, nm, shape (periods,).
    weight_norm : dict of str to numpy.ndarray
        Per row, mean ‖Ŵ‖ per period (both axes), V, shape (periods,); NaN for the
        oracles (no weights).
    regressor : tuple of RegressorStats
        The default rule and ``s_spread = 0``.
    """

    config: ComparisonConfig
    rms_nm: dict[str, np.ndarray]
    weight_norm: dict[str, np.ndarray]
    regressor: tuple[RegressorStats, ...]

    def table(self) -> str:
        """A plain-text table: rows by period, then the regressor statistics."""
        n = len(self.rms_nm[ROWS[0]])
        rows = [f"{'':<26}" + "".join(f"{k + 1:>8d}" for k in range(n))]
        for name in ROWS:
            rows.append(f"{name + ' [nm]':<26}" + "".join(f"{v:8.0f}" for v in self.rms_nm[name]))
        for name in ROWS:
            w = self.weight_norm[name]
            if np.any(np.isfinite(w)):
                rows.append(f"{name + ' |W| [mV]':<26}" + "".join(f"{v * 1e3:8.2f}" for v in w))
        rows.append("regressor   width   h_min   h_max  mean Σh²  ΓΣh² [V/mm]")
        for r in self.regressor:
            rows.append(
                f"{r.rule:<10} {r.width_mean:6.2f} {r.h_min:7.3f} {r.h_max:7.3f} "
                f"{r.sum_h2:9.2f} {r.gain:12.3f}"
            )
        return "\n".join(rows)

    def as_table(self) -> Table:
        """The per-period numbers as a report `Table`, the regressor in its note."""
        n = len(self.rms_nm[ROWS[0]])
        rows = [(f"{v} RMS [nm]", *(f"{x:.0f}" for x in self.rms_nm[v])) for v in ROWS]
        rows += [
            (f"{v} ‖Ŵ‖ [mV]", *(f"{x * 1e3:.2f}" for x in self.weight_norm[v]))
            for v in ROWS
            if np.any(np.isfinite(self.weight_norm[v]))
        ]
        d, loc = self.regressor
        return Table(
            title="RBF per period (0.15 mm circle 0.25 mm off-centre, noise off, d(t) on)",
            columns=("controller / variant", *(f"period {k + 1}" for k in range(n))),
            rows=rows,
            note="seed = the seed's network as the whole command, handed over from the "
            "PID; proposed = eq. 6's linear part from eq. 9 (PD 200 Hz + eq. 9 inverse) "
            "plus the network, centres along the orbit. frozen = weights held; oracle = "
            "the network replaced by its ideal (seed: eq. 6 with the true α, β; proposed: "
            f"the true §4.1 terms cancelled). Default centres: every h_j stays in "
            f"[{d.h_min:.2f}, {d.h_max:.2f}] on the circle (widths {d.width_mean:.1f} "
            f"scaled units against an orbit of diameter 2; mean Σh² {d.sum_h2:.1f}): one "
            f"constant basis function, eq. 5 an integrator on s (ΓΣh² = {d.gain:.2f} "
            "V/mm) with no memory of the phase. With s_spread = 0 the widths are "
            f"{loc.width_mean:.2f}, h_j spans [{loc.h_min:.3f}, {loc.h_max:.2f}] and Γ = "
            f"{loc.gain / loc.sum_h2:.2f} V/mm keeps ΓΣh².",
        )


def regressor_stats(rbf: RBFAdaptive, st: CircleSetting, rule: str) -> RegressorStats:
    """`RegressorStats` of ``rbf``'s x network along one period of ``st``'s reference."""
    net = rbf.networks[0]
    H = net.hidden(orbit_z(st, 0))
    s2 = float(np.mean(np.sum(H**2, axis=1)))
    return RegressorStats(
        rule=rule,
        width_mean=float(np.mean(net.widths)),
        h_min=float(H.min()),
        h_max=float(H.max()),
        sum_h2=s2,
        gain=float(np.mean(rbf.config.gamma_diagonal())) * s2,
    )


def _lead_in(st: CircleSetting, plant: NanomanipulatorPlant, pid: PID) -> SimResult:
    """The PID bringing the stage to the circle's start (move and pause), noise off."""
    a = st.start
    return nanomanipulator.play(
        pid, st.position[:a], derivatives=(st.velocity[:a], st.acceleration[:a]), seed=st.seed
    )


def handed_over(
    rbf: RBFAdaptive, st: CircleSetting, plant: NanomanipulatorPlant, lead: SimResult
) -> RBFAdaptive:
    """``rbf`` with the hand-over weights at the circle's start after ``lead``."""
    a = st.start
    lo = max(a - max(round(_HANDOVER_MEAN_S / plant.dt), 1), 0)
    p = plant.config
    ks = [feedback_gain(p.numerator_mm_per_v_s2[i], p.stiffness_per_s2[i]) for i in range(2)]
    return handover(
        rbf,
        measured=lead.measured[lo:a].mean(axis=0),
        reference=np.stack([st.position[a], st.velocity[a], st.acceleration[a]]),
        command=lead.command[lo:a].mean(axis=0),
        gains=ks,
    )


def _after(st: CircleSetting, lead: SimResult, controller: object) -> SimResult:
    """Play ``controller`` from the circle's start, continuing ``lead``'s plant."""
    a = st.start
    fs = lead.final_state
    state = LoopState(
        plant=np.array(fs.plant),
        controller=controller.init(),  # type: ignore[attr-defined]
        observer=np.zeros(0),
        command=np.array(fs.command),
    )
    return nanomanipulator.play(
        controller,  # type: ignore[arg-type]
        st.position[a:],
        derivatives=(st.velocity[a:], st.acceleration[a:]),
        seed=st.seed,
        state=state,
    )


def learning_study(config: ComparisonConfig | None = None) -> LearningStudy:
    """Run the three variants on the circle (module notes).

    Parameters
    ----------
    config : ComparisonConfig, optional
        The circle, RBF settings and seed (default `ComparisonConfig()`; its noise is
        not used: the study runs noise off).

    Returns
    -------
    LearningStudy
    """
    cfg = config or ComparisonConfig()
    plant = nanomanipulator.twin(seed=cfg.seed)
    dt = plant.dt
    st = circle_setting(cfg, dt)
    pid = PID.tuned(plant.continuous_models(), bandwidth_hz=cfg.pid_bandwidth_hz, dt=dt)
    lead = _lead_in(st, plant, pid)
    one = st.one
    base = RBFAdaptive.for_reference(
        st.position[one], st.velocity[one], st.acceleration[one], dt, cfg.rbf
    )
    adaptive = handed_over(base, st, plant, lead)
    fc = cfg.pid_bandwidth_hz
    proposed = proposed_controller(st, plant, fc, cfg.rbf)
    runs = {
        "seed adaptive": adaptive,
        "seed frozen": _frozen(adaptive),
        "seed oracle": CertaintyEquivalence(drift_and_gain, plant.params, cfg.rbf, dt),
        "proposed adaptive": proposed,
        "proposed frozen": RBFPlusLinear(proposed.linear, _frozen(proposed.rbf)),
        "proposed oracle": proposed_oracle(plant, fc, cfg.rbf),
    }
    rms: dict[str, np.ndarray] = {}
    wn: dict[str, np.ndarray] = {}
    n, periods = st.period_samples, st.periods
    for name, ctrl in runs.items():
        a = st.start if name.startswith("seed") else 0
        if a:
            res = _after(st, lead, ctrl)
        else:
            res = nanomanipulator.play(
                ctrl,  # type: ignore[arg-type]
                st.position,
                derivatives=(st.velocity, st.acceleration),
                seed=st.seed,
            )
        rms[name] = st.period_rms_nm(res.output, a)
        net = ctrl.rbf if isinstance(ctrl, RBFPlusLinear) else ctrl
        if isinstance(net, RBFAdaptive):
            log = net.replay(st.position[a:], st.velocity[a:], st.acceleration[a:], res.measured)
            w = np.sqrt(np.sum(log.weight_norm**2, axis=1))[st.start - a :]
            wn[name] = w[: periods * n].reshape(periods, n).mean(axis=1)
        else:
            wn[name] = np.full(periods, np.nan)
    stats = (
        regressor_stats(base, st, "default"),
        regressor_stats(proposed.rbf, st, "s_spread=0"),
    )
    return LearningStudy(config=cfg, rms_nm=rms, weight_norm=wn, regressor=stats)


def _frozen(rbf: RBFAdaptive) -> RBFAdaptive:
    """``rbf`` with its initial weights held (Γ → 0)."""
    cfg = dataclasses.replace(rbf.config, gamma=1e-30)
    return RBFAdaptive(config=cfg, networks=rbf.networks, dt=rbf.dt)
