"""RBF networks whose centres cover the state box a reference reaches (seed 001 §3.2, §4.1).

Seed 001 uses the RBF network "to approximate nonlinear functions" (§1, §3.2) of the
state: the input of eq. 4 is ``z = (x, x̄, s, v)`` and the §4.1 terms ``α(x, x̄)``,
``β(x, x̄)`` are functions of the states of both axes. A network whose centres lie along
one period of a reference (`microfab.control.rbf_network.networks_for_reference`) is a
memory of that path; `networks_for_box` places the centres on a grid over the box of
states the reference reaches instead, so that the network is a model of a function of
the state and holds on any path inside the box (seed 001 Fig. 9: sines of irreducible
frequencies, no repeating path).

Rule (ours; the seed gives no centres, widths or scaling), for axis ``a`` (other axis
``b``) and the states ``(x1, x2, x̄1, x̄2) = (r_a, ṙ_a, r_b, ṙ_b)`` of the reference:

* Box: per state, the mid-range ``m`` and a half-range ``H``: positions their own
  half-range ``A``; velocities ``λA + V`` (``V`` their own half-range), the deviation
  that moves ``s = λe + ė`` as much as a position error ``A`` does (the scaling of
  `networks_for_reference`: a velocity grid as fine as the positions' would make the
  network a steep function of the estimated velocity, a derivative gain that set the
  loop oscillating on eq. 9 in our trials); both widened by ``margin``.
* Grid: ``counts[i]`` points equally spaced over ``[m − H, m + H]`` per state; the scale
  of state ``i`` is the grid spacing, so that the grid is the integer lattice in scaled
  units and one width fits every direction: ``b_j = width_factor`` (the widths follow
  the spacing). A state whose count is 1, or which does not move, gets one layer at its
  mid-range and a scale of `WIDE`.
* ``s`` and ``v`` (the last two inputs of eq. 4) are carried with one layer at 0 and
  the scale `WIDE`: the remainder the network models beside a linear part known from
  eq. 9 (`microfab.control.rbf_composite`) is a function of ``x``, ``x̄`` alone (the
  terms of eq. 6 in ``s`` and ``v`` are the linear part's).
* Weights: ``Ŵ(0) = w0``.

`state_network` builds the controller's network with the settings `STATE_CONFIG`;
`eq6_linear_part` the linear part beside it (`microfab.control.rbf_composite.RBFPlusLinear`):
a PD at the given crossover (45°) on eq. 9 with eq. 9's inverse feedforward.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive
from microfab.control.rbf_network import N_AXES, N_Z, RBFConfig, RBFNetwork, _stack_reference
from microfab.core.validate import check_int, check_nonnegative, check_positive

__all__ = [
    "DEFAULT_COUNTS",
    "STATE_CONFIG",
    "WIDE",
    "eq6_linear_part",
    "networks_for_box",
    "state_network",
]

#: Grid points per state ``(x1, x2, x̄1, x̄2)`` (assumed: 7 along the own position, on
#: which the §4.1 ``α`` depends most; 3 on the others). Measured on Fig. 9's sines at
#: 200 Hz with `STATE_CONFIG`'s λ and Γ, last of 8 periods, nm: (5,3,3,3) 161, (7,3,3,3)
#: 137, (11,3,3,3) 133, (7,5,3,3) 127, (7,1,3,1) 171, (7,1,1,1) 139. With λ = 1000 the
#: velocity half-range ``λA + V`` is ~150 times the velocities' own, so the network is
#: nearly flat in them (they are inputs, as eq. 4 has them, but weigh little); a velocity
#: grid on their own range (2x or 5x ``V``) gave 80 nm at 400 Hz, no better, and one run
#: at 200 Hz rose to 3.8 µm by period 8.
DEFAULT_COUNTS = (7, 3, 3, 3)
#: Scale of an input the network is flat in (units of ``z``): ``h`` does not see it.
WIDE = 1e12
#: Settings of the state-model network (assumed; chosen on seed 001 Fig. 9's sines at 200
#: and 400 Hz, 8 periods, last period nm, 200 / 400 Hz: λ = 100, Γ = 0.2 282 / 121;
#: λ = 300, Γ = 0.15 172 / 83; λ = 1000, Γ = 0.05 137 / 73; λ = 1000, Γ = 0.2 498 / 78;
#: Γ = 0.4 diverged at 200 Hz: eq. 5 adds ``ΓΣh²`` (Σh² ≈ 7 on the grid) to the loop's
#: proportional gain, so Γ keeps it below the PD's). Widths one grid spacing; σ as
#: `RBFConfig`.
STATE_CONFIG = RBFConfig(
    n_nodes=int(np.prod(DEFAULT_COUNTS)), lam=1000.0, gamma=0.05, width_factor=1.0, s_spread=0.0
)
_NO_INTEGRAL = 1e9  # integral_ratio of the design: the integral zero far below 1 Hz, then ki = 0


def networks_for_box(
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    config: RBFConfig,
    *,
    counts: Sequence[int] = DEFAULT_COUNTS,
    margin: float = 0.1,
) -> tuple[RBFNetwork, RBFNetwork]:
    """The x and y networks on a grid over the reference's state box (module notes).

    Parameters
    ----------
    position, velocity, acceleration : numpy.ndarray
        The reference (or the part whose states the network must cover), mm, mm/s,
        mm/s², shape (n, 2).
    config : RBFConfig
        Settings: ``lam`` (the velocity half-range), ``width_factor`` (``b_j`` in grid
        spacings), ``w0``; its ``n_nodes`` must equal the grid's ``prod(counts)``.
    counts : sequence of int
        Grid points per state ``(x1, x2, x̄1, x̄2)``, each >= 1.
    margin : float
        Relative widening of the box, >= 0 (assumed 0.1: the states leave the
        reference by the tracking error).

    Returns
    -------
    tuple of RBFNetwork

    Raises
    ------
    ValueError
        For a bad count or margin, or ``config.n_nodes != prod(counts)``.
    """
    cts = tuple(counts)
    if len(cts) != 4:
        raise ValueError(f"counts needs one grid size per state (x1, x2, x̄1, x̄2), got {cts!r}")
    for i, c in enumerate(cts):
        check_int(f"counts[{i}]", c, 1, "points")
    check_nonnegative("margin", margin, "")
    check_positive("width_factor", config.width_factor, "")
    nl = int(np.prod(cts))
    if config.n_nodes != nl:
        raise ValueError(
            f"n_nodes = {config.n_nodes} but the grid {cts} has {nl} nodes; set n_nodes = {nl}"
        )
    P = np.asarray(position, dtype=float)
    R = _stack_reference(P, velocity, acceleration, P.shape[0] if P.ndim == 2 else 0)
    nets = []
    for a in range(N_AXES):
        b = 1 - a
        z = np.column_stack([R[:, 0, a], R[:, 1, a], R[:, 0, b], R[:, 1, b]])
        lo, hi = z.min(axis=0), z.max(axis=0)
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        half[1] += config.lam * half[0]
        half[3] += config.lam * half[2]
        half *= 1.0 + margin
        offset, scale = np.zeros(N_Z), np.full(N_Z, WIDE)
        layers = []
        for i, c in enumerate(cts):
            if c == 1 or half[i] <= 1e-12 * max(1.0, abs(mid[i])):
                offset[i] = mid[i]
                layers.append(np.zeros(1))
            else:
                offset[i] = mid[i] - half[i]
                scale[i] = 2.0 * half[i] / (c - 1)
                layers.append(np.arange(c, dtype=float))
        grid = np.array(list(itertools.product(*layers)))
        centres = np.zeros((grid.shape[0], N_Z))
        centres[:, :4] = grid
        nets.append(
            RBFNetwork(
                offset=offset,
                scale=scale,
                centres=centres,
                widths=np.full(grid.shape[0], float(config.width_factor)),
                weights=np.full(grid.shape[0], float(config.w0)),
            )
        )
    return nets[0], nets[1]


def state_network(
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    dt: float,
    config: RBFConfig = STATE_CONFIG,
    *,
    counts: Sequence[int] = DEFAULT_COUNTS,
) -> RBFAdaptive:
    """The state-model controller network on the reference's state box (module notes).

    Parameters
    ----------
    position, velocity, acceleration : numpy.ndarray
        The reference the states follow, mm, mm/s, mm/s², shape (n, 2).
    dt : float
        Sample time, s.
    config : RBFConfig
        Settings (default `STATE_CONFIG`); ``n_nodes`` must be ``prod(counts)``.
    counts : sequence of int
        Grid points per state (`networks_for_box`).
    """
    nets = networks_for_box(position, velocity, acceleration, config, counts=counts)
    return RBFAdaptive(config=config, networks=nets, dt=dt)


def eq6_linear_part(models: Sequence[Any], bandwidth_hz: float, dt: float) -> PID:
    """Eq. 6's linear part: a PD at crossover ``bandwidth_hz`` (45°) plus eq. 9's inverse.

    Seed 001 §4.1: "``β_l`` is the linear part which can be obtained from (9)": eq. 6's
    ``−(α_l + v)/β_l`` is eq. 9's inverse on the reference and its ``s`` feedback a PD.
    `PID.tuned` on ``models`` (eq. 9 per axis, mm/V) with the integral removed (the
    adaptation of eq. 5 is the integral action).

    Raises
    ------
    ValueError
        When 45° cannot be reached at that crossover (`PIDGains.design`).
    """
    pid = PID.tuned(
        models, bandwidth_hz=bandwidth_hz, dt=dt, feedforward=True, integral_ratio=_NO_INTEGRAL
    )
    gains = [dataclasses.replace(g, ki=0.0) for g in pid.gains]
    return PID(gains=gains, dt=dt, feedforward=True)
