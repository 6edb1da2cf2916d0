"""The RBF controller that learns on the twin: eq. 6's linear part from eq. 9, the network the rest.

`study.py` shows why the seed's network, as `RBFAdaptive.for_reference` builds it and as
the whole command (eq. 4), cannot learn over periods: its widths (~3.9 scaled units, the
``±s_spread`` alternation of the centres counted as the gap between neighbours) exceed
the orbit (diameter 2), every ``h_j`` stays within [0.61, 0.97] on the circle, and eq. 5
is one integrator on ``s``. Two changes, each from the seed's own law:

* **The linear part of eq. 6 is known** (§4.1: "``β_l`` is the linear part which can be
  obtained from (9)"): ``−(α_l + v)/β_l`` with ``α_l = −a0 x1 − a1 x2`` is eq. 9's inverse
  on the reference, and the ``s`` feedback is a PD. Here: `PID.tuned` on eq. 9 at
  crossover ``f_c`` with 45° phase margin, the integral removed (``ki = 0``: the
  adaptation of eq. 5 is the integral action), with eq. 9's model-inverse feedforward.
  Without an integrator beside it, the network's output reaches ``e`` and ``s`` in phase
  at the contour's frequencies (eq. 8: ``ṡ`` first order in ``s``, driven by
  ``β(u − u*)``), the condition of the gradient law eq. 5; a PID's integrator turns it
  by ~90° at 1 Hz and the law stalls (measured: PID + network 154 -> 124 nm at 200 Hz).
* **The network is left the unknown remainder** (the §4.1 ``α``, ``β`` terms), a function
  of the state along the contour, so its centres need no spread in ``s``
  (``s_spread = 0``): the width rule then gives ``b_j ≈ 0.5`` (twice the spacing along
  the orbit) and each node holds its own part of the period. ``Ŵ(0) = 0``. Γ keeps the
  default network's adaptation rate ``Γ Σ h_j²`` along the orbit (assumed: the seed gives
  no Γ; the default's 0.05 V/mm × 20.3 / 3.6 = 0.28 V/mm).

`proposed_controller` builds it; `proposed_oracle` replaces its network by the true
nonlinearity (`NonlinearityOracle`).

**The state model** (issue 45, `state_controller`): the network above is a memory of one
repeating path, and on Fig. 9's sines (no repeating path) it lost to the PID (200 Hz:
333-794 nm against 182-192). `state_controller` keeps the same linear part and gives the
network the states as inputs with centres on a grid over the state box the reference
reaches (`microfab.control.rbf_grid.networks_for_box`), so that it is a model of the
§4.1 ``α(x, x̄)``, ``β(x, x̄)`` and holds on any path in the box. Its settings are
`STATE_RBF` (`microfab.control.rbf_grid.STATE_CONFIG`, assumed: the trials that chose
them are listed there).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive, RBFConfig
from microfab.control.rbf_composite import NonlinearityOracle, RBFPlusLinear
from microfab.control.rbf_grid import (
    STATE_CONFIG,
    eq6_linear_part,
    state_network,  # the state-model network, re-exported
)
from microfab.experiments.seed001_nanomanipulator.compare import CircleSetting
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.plants.nanomanipulator import NanomanipulatorPlant, drift_and_gain

__all__ = [
    "STATE_RBF",
    "linear_part",
    "local_network",
    "orbit_z",
    "proposed_controller",
    "proposed_oracle",
    "state_controller",
    "state_network",
]

STATE_RBF = STATE_CONFIG  # the state-model network's settings (`rbf_grid.STATE_CONFIG`)


def orbit_z(st: CircleSetting, axis: int) -> np.ndarray:
    """The reference's own network input ``z`` of ``axis`` over one period, shape (n, 6).

    ``z_r = (r_a, ṙ_a, r_b, ṙ_b, 0, −r̈_a)`` (on the reference ``s = 0``, ``v = −r̈``).
    """
    one = st.one
    b = 1 - axis
    pos, vel, acc = st.position[one], st.velocity[one], st.acceleration[one]
    zeros = np.zeros(pos.shape[0])
    return np.column_stack([pos[:, axis], vel[:, axis], pos[:, b], vel[:, b], zeros, -acc[:, axis]])


def linear_part(plant: NanomanipulatorPlant, bandwidth_hz: float) -> PID:
    """Eq. 6's linear part: a PD at crossover ``bandwidth_hz`` (45°) plus eq. 9's inverse.

    `microfab.control.rbf_grid.eq6_linear_part` on the plant's eq. 9.

    Raises
    ------
    ValueError
        When 45° cannot be reached at that crossover (`PIDGains.design`).
    """
    return eq6_linear_part(plant.continuous_models(), bandwidth_hz, plant.dt)


def _sum_h2(rbf: RBFAdaptive, z: np.ndarray) -> float:
    """Mean over ``z`` (n, 6) of ``Σ_j h_j²`` of the x network."""
    return float(np.mean(np.sum(rbf.networks[0].hidden(z) ** 2, axis=1)))


def local_network(st: CircleSetting, config: RBFConfig, dt: float) -> RBFAdaptive:
    """The network of the proposed controller: ``s_spread = 0``, Γ for the default ``ΓΣh²``."""
    one = st.one
    args = (st.position[one], st.velocity[one], st.acceleration[one], dt)
    z = orbit_z(st, 0)
    default = RBFAdaptive.for_reference(*args, config)
    local_cfg = dataclasses.replace(config, s_spread=0.0)
    local = RBFAdaptive.for_reference(*args, local_cfg)
    gamma = float(np.mean(config.gamma_diagonal())) * _sum_h2(default, z) / _sum_h2(local, z)
    return RBFAdaptive.for_reference(*args, dataclasses.replace(local_cfg, gamma=gamma))


def proposed_controller(
    st: CircleSetting, plant: NanomanipulatorPlant, bandwidth_hz: float, config: RBFConfig
) -> RBFPlusLinear:
    """`linear_part` plus `local_network` (module notes)."""
    return RBFPlusLinear(linear_part(plant, bandwidth_hz), local_network(st, config, plant.dt))


def proposed_oracle(
    plant: NanomanipulatorPlant, bandwidth_hz: float, config: RBFConfig
) -> NonlinearityOracle:
    """`linear_part` with the network replaced by the twin's true nonlinearity."""
    lin = nanomanipulator.twin(seed=plant.config.disturbance_seed, nonlinear=False)
    return NonlinearityOracle(
        linear_part(plant, bandwidth_hz),
        drift_and_gain,
        plant.params,
        lin.params,
        config.estimator,
        plant.dt,
    )


def state_controller(
    plant: NanomanipulatorPlant,
    bandwidth_hz: float,
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    config: RBFConfig = STATE_RBF,
) -> RBFPlusLinear:
    """`linear_part` at ``bandwidth_hz`` plus `state_network` on the given reference."""
    net = state_network(position, velocity, acceleration, plant.dt, config)
    return RBFPlusLinear(linear_part(plant, bandwidth_hz), net)
