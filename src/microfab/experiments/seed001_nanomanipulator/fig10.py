"""Seed 001 Fig. 10: the plug-in RC added to the RBF controller, against the RBF alone.

Seed 001 §4.1: "to validate the performance of the plug-in RC controller for periodic
tracking, we added the plug-in RC to the RBF-based robust adaptive controller. Figure 10
shows that the RC controller significantly reduces the tracking errors" (curves only; the
project's target `paper.FIG_TARGETS` ``"fig10_rc_gain_min"``: RBF alone over RBF + RC
>= 5 in the last of 8 periods, noise off). On `compare.py`'s circle (0.25 mm off-centre,
8 periods, the same twin seed and ``d(t)``), two RBF controllers, each alone and inside
the plug-in RC of §3.3 (``B = 1``, first-order ``Q``, `compare.ComparisonConfig`'s
``rc_lead_samples``):

* ``RBF``: the seed's network (eq. 4 alone, `RBFAdaptive.for_reference` on one period),
  `compare.compare_controllers`'s ``RBF`` and ``RBF+RC``;
* ``RBF state``: the proposed controller of the job (`proposed.state_controller` at
  ``pid_bandwidth_hz``: eq. 6's linear part from eq. 9 plus the network as a model of the
  state), ``Ŵ(0) = 0``.

``ComparisonConfig(noise=False)`` is the paper's model (eq. 9, the §4.1 terms, ``d(t)``);
``noise=True`` the calibrated twin (its sensor noise, rms and colour, as the data file
has them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from microfab.control.base import Controller
from microfab.control.rbf import RBFAdaptive
from microfab.control.repetitive import PluginRC, RCConfig
from microfab.experiments.seed001_nanomanipulator import paper
from microfab.experiments.seed001_nanomanipulator.compare import ComparisonConfig, circle_setting
from microfab.experiments.seed001_nanomanipulator.proposed import state_controller
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.report.tables import Table

__all__ = ["BASES", "Fig10Result", "fig10_rc"]

#: The RBF controllers that get the plug-in RC, in the order of the table.
BASES = ("RBF", "RBF state")


@dataclass(frozen=True, kw_only=True, eq=False)
class Fig10Result:
    """RMS per period of each RBF controller alone and inside the plug-in RC.

    Attributes
    ----------
    config : ComparisonConfig
        What ran (its ``noise``: paper's model or calibrated twin).
    rms_nm : dict of str to numpy.ndarray
        ``"RBF"``, ``"RBF+RC"``, ``"RBF state"``, ``"RBF state+RC"``: RMS over both axes
        of ``r − y`` (true output) per period, nm, shape (periods,).
    """

    config: ComparisonConfig
    rms_nm: dict[str, np.ndarray]

    def final(self, name: str) -> float:
        """Last period's RMS of ``name``, nm."""
        return float(self.rms_nm[name][-1])

    def gain(self, base: str) -> float:
        """``base`` alone over ``base`` + RC, last period (the target's ratio)."""
        return self.final(base) / self.final(base + "+RC")

    def as_table(self, model: str) -> Table:
        """Per controller: first and last period alone and with RC, and the gain.

        Parameters
        ----------
        model : str
            What ran, for the title (``"paper's model (noise off)"``, ...).
        """
        floor = paper.FIG_TARGETS["fig10_rc_gain_min"]  # project's target, not seed data
        rows = []
        for b in BASES:
            alone, rc = self.rms_nm[b], self.rms_nm[b + "+RC"]
            g = self.gain(b)
            rows.append(
                (
                    b,
                    f"{alone[0]:.0f}",
                    f"{alone[-1]:.0f}",
                    f"{rc[-1]:.0f}",
                    f"{float(np.min(rc)):.0f}",
                    f"{g:.2f}",
                    "yes" if g >= floor else "no",
                )
            )
        return Table(
            title=f"Seed 001 Fig. 10, RBF + plug-in RC against RBF alone, RMS [nm], {model}",
            columns=(
                "RBF",
                "period 1",
                f"alone, period {alone.size}",
                f"+ RC, period {rc.size}",
                "+ RC, best period",
                "gain alone / + RC",
                f"gain >= {floor:g}",
            ),
            rows=rows,
            note="One 0.15 mm circle 0.25 mm off-centre, 8 periods, d(t) and the §4.1 terms "
            "on; RC as in §3.3 (B = 1, Q = 1/(τs + 1)), its memory empty in period 1, lead "
            f"{self.config.rc_lead_samples} samples. RBF = the seed's network (eq. 4 alone); "
            f"RBF state = the proposed controller ({self.config.pid_bandwidth_hz:g} Hz "
            "linear part of eq. 6 plus the state-model network). Seed: 'the RC controller "
            f"significantly reduces the tracking errors' (curves only; the project's target "
            f"gain >= {floor:g}).",
        )


def fig10_rc(config: ComparisonConfig | None = None) -> Fig10Result:
    """Run `BASES`, each alone and inside the plug-in RC (module notes).

    Parameters
    ----------
    config : ComparisonConfig, optional
        Circle, RBF settings, seed, RC lead and noise (default: noise off, the paper's
        model).

    Returns
    -------
    Fig10Result
    """
    cfg = config or ComparisonConfig()
    plant = nanomanipulator.twin(seed=cfg.seed)
    dt = plant.dt
    st = circle_setting(cfg, dt)
    run = slice(st.start, None)
    bases: dict[str, Controller] = {
        "RBF": RBFAdaptive.for_reference(
            st.position[st.one], st.velocity[st.one], st.acceleration[st.one], dt, cfg.rbf
        ),
        "RBF state": state_controller(
            plant, cfg.pid_bandwidth_hz, st.position[run], st.velocity[run], st.acceleration[run]
        ),
    }
    rc = RCConfig(
        period_s=st.period_samples * dt,
        dt=dt,
        windows=((st.start, st.periods),),
        lead_samples=cfg.rc_lead_samples,
    )
    out: dict[str, np.ndarray] = {}
    for name, ctrl in bases.items():
        for key, c in ((name, ctrl), (name + "+RC", PluginRC(ctrl, rc))):
            res = nanomanipulator.play(
                c,
                st.position,
                derivatives=(st.velocity, st.acceleration),
                seed=cfg.seed,
                noise=cfg.noise,
            )
            out[key] = st.period_rms_nm(res.output)
    return Fig10Result(config=cfg, rms_nm=out)
