"""Why the RBF of seed 001 does not learn over periods: a per-period study on the twin.

Setting: `compare.py`'s circle (0.15 mm, 0.25 mm off-centre on the diagonal, 1 s period,
8 periods, noise off, ``d(t)`` and the §4.1 ``α``, ``β`` terms on). The stage is brought
along the circle's lead-in under the Fig. 8 PID (move, pause, spin-up), and at the first
sample of the first period the loop is handed over (`microfab.control.
rbf_handover`: bumpless, damping ``ζ_h = 1``) to one of three controllers:

* ``adaptive``: the seed's RBF (eqs. 2, 4, 5; default rule of `RBFAdaptive.for_reference`),
  adapting;
* ``frozen``: the same network with the hand-over weights held (Γ → 0);
* ``oracle``: the network's output replaced by what it is meant to approximate, the
  certainty-equivalence law eq. 6 with the twin's true ``α``, ``β`` (same ``λ``, ``ε``,
  velocity estimator; `microfab.control.certainty`): the best the network could do.

Per period: the RMS tracking error over both axes (``r − y``, nm) and ‖Ŵ‖ (mean over the
period, both axes together, V). Beside them, what the network's regressor looks like on
the circle: the range of every ``h_j`` over the orbit and the mean ``Σ_j h_j²``, for the
default rule and for centres without the ``±s_spread`` alternation (``s_spread = 0``).
`LearningStudy.table` prints it; `microfab.report.nanomanipulator_study` draws it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from microfab.control.certainty import CertaintyEquivalence
from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_handover import feedback_gain, handover
from microfab.experiments.seed001_nanomanipulator.compare import (
    CircleSetting,
    ComparisonConfig,
    circle_setting,
)
from microfab.machines import nanomanipulator
from microfab.plants.nanomanipulator import NanomanipulatorPlant, drift_and_gain
from microfab.report.tables import Table
from microfab.sim.loop import LoopState
from microfab.sim.result import SimResult

__all__ = [
    "VARIANTS",
    "LearningStudy",
    "RegressorStats",
    "handed_over",
    "learning_study",
    "regressor_stats",
]

#: The three variants, in the order of the table.
VARIANTS = ("adaptive", "frozen", "oracle")
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
        Per variant, RMS error per period over both axes, nm, shape (periods,).
    weight_norm : dict of str to numpy.ndarray
        Per variant, mean ‖Ŵ‖ per period (both axes), V, shape (periods,); NaN for the
        oracle (no weights).
    regressor : tuple of RegressorStats
        The default rule and ``s_spread = 0``.
    """

    config: ComparisonConfig
    rms_nm: dict[str, np.ndarray]
    weight_norm: dict[str, np.ndarray]
    regressor: tuple[RegressorStats, ...]

    def table(self) -> str:
        """A plain-text table: variants by period, then the regressor statistics."""
        n = len(self.rms_nm[VARIANTS[0]])
        rows = [f"{'':<18}" + "".join(f"{k + 1:>9d}" for k in range(n))]
        for name in VARIANTS:
            rows.append(
                f"{name + ' RMS [nm]':<18}" + "".join(f"{v:9.0f}" for v in self.rms_nm[name])
            )
        for name in VARIANTS[:2]:
            w = self.weight_norm[name]
            rows.append(f"{name + ' |W| [mV]':<18}" + "".join(f"{v * 1e3:9.3f}" for v in w))
        rows.append("regressor  width   h_min   h_max  mean Σh²  ΓΣh² [V/mm]")
        for r in self.regressor:
            rows.append(
                f"{r.rule:<10} {r.width_mean:5.2f} {r.h_min:7.3f} {r.h_max:7.3f} "
                f"{r.sum_h2:9.2f} {r.gain:12.3f}"
            )
        return "\n".join(rows)

    def as_table(self) -> Table:
        """The per-period numbers and the regressor statistics as a report `Table`."""
        n = len(self.rms_nm[VARIANTS[0]])
        rows = [(f"{v} RMS [nm]", *(f"{x:.0f}" for x in self.rms_nm[v])) for v in VARIANTS]
        rows += [
            (f"{v} ‖Ŵ‖ [mV]", *(f"{x * 1e3:.2f}" for x in self.weight_norm[v]))
            for v in VARIANTS[:2]
        ]
        d, loc = self.regressor
        return Table(
            title="RBF per period after the hand-over (0.15 mm circle 0.25 mm off-centre, "
            "noise off)",
            columns=("variant", *(f"period {k + 1}" for k in range(n))),
            rows=rows,
            note=f"Default centres: every h_j stays in [{d.h_min:.2f}, {d.h_max:.2f}] over "
            f"the circle (widths {d.width_mean:.1f} scaled units against an orbit of "
            f"diameter 2; mean Σh² {d.sum_h2:.1f}): the network is one constant basis "
            f"function and eq. 5 an integrator on s (ΓΣh² = {d.gain:.2f} V/mm), a PI with no "
            "memory of the phase, so the error cannot fall from period to period. Without "
            f"the ±s_spread alternation the widths are {loc.width_mean:.2f} and h_j spans "
            f"[{loc.h_min:.3f}, {loc.h_max:.2f}]. The oracle (eq. 6 with the true α, β) is "
            "bounded by d(t): eq. 6 has no integral action.",
        )


def _orbit_z(st: CircleSetting, axis: int) -> np.ndarray:
    """The reference's own ``z`` for ``axis`` over one period, shape (n, 6)."""
    one = st.one
    b = 1 - axis
    pos, vel, acc = st.position[one], st.velocity[one], st.acceleration[one]
    zeros = np.zeros(pos.shape[0])
    return np.column_stack([pos[:, axis], vel[:, axis], pos[:, b], vel[:, b], zeros, -acc[:, axis]])


def regressor_stats(rbf: RBFAdaptive, st: CircleSetting, rule: str) -> RegressorStats:
    """`RegressorStats` of ``rbf``'s x network along one period of ``st``'s reference."""
    net = rbf.networks[0]
    H = net.hidden(_orbit_z(st, 0))
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
    frozen_cfg = dataclasses.replace(cfg.rbf, gamma=1e-30)  # Γ → 0: weights held
    frozen = RBFAdaptive(config=frozen_cfg, networks=adaptive.networks, dt=dt)
    oracle = CertaintyEquivalence(drift_and_gain, plant.params, cfg.rbf, dt)
    rms: dict[str, np.ndarray] = {}
    wn: dict[str, np.ndarray] = {}
    a, n, periods = st.start, st.period_samples, st.periods
    for name, ctrl in (("adaptive", adaptive), ("frozen", frozen), ("oracle", oracle)):
        res = _after(st, lead, ctrl)
        rms[name] = st.period_rms_nm(res.output, a)
        if isinstance(ctrl, RBFAdaptive):
            log = ctrl.replay(st.position[a:], st.velocity[a:], st.acceleration[a:], res.measured)
            w = np.sqrt(np.sum(log.weight_norm**2, axis=1))[: periods * n]
            wn[name] = w.reshape(periods, n).mean(axis=1)
        else:
            wn[name] = np.full(periods, np.nan)
    local = RBFAdaptive.for_reference(
        st.position[one],
        st.velocity[one],
        st.acceleration[one],
        dt,
        dataclasses.replace(cfg.rbf, s_spread=0.0),
    )
    stats = (regressor_stats(base, st, "default"), regressor_stats(local, st, "s_spread=0"))
    return LearningStudy(config=cfg, rms_nm=rms, weight_norm=wn, regressor=stats)
