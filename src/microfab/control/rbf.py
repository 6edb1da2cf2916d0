"""RBF-network robust adaptive control of a two-axis stage (seed 001 §3.2, eqs. 2-5).

One network per axis, ``u = Ŵᵀ h(z)`` (seed 001 eq. 4), Gaussian nodes
``h_j = exp(−‖z − c_j‖² / (2 b_j²))`` (eq. 2), input ``z = (x1, x2, x̄1, x̄2, s, v)`` with
``e = x1 − r``, ``s = λe + ė``, ``v = λė − r̈`` (§3.2) and the adaptive law (eq. 5)

``dŴ/dt = −Γ (h(z) s + σ Ŵ)``.

Seed points: eq. 3 sums the outputs over ``j = 1..m`` while eq. 2 numbers the nodes
``1..l`` (the same ``l`` here); eq. 5 writes ``dŴᵀ/dt · h(z) = −Γ(h s + σŴ)``, which
leaves a scalar on the left and a vector on the right: read as the vector law above (the
one the Lyapunov function A1 needs); eq. 7 says "substitute control law (5)", meaning
the control law (4); A1 writes ``W̃ᵀ Γ⁻¹ W̃ᵀ`` for ``W̃ᵀ Γ⁻¹ W̃``.

Discretisation (ours: the seed is continuous): at sample k the command is
``u_k = Ŵ_kᵀ h(z_k)``; then ``Ŵ_{k+1} = exp(−Γσ dt) Ŵ_k − Γ dt h(z_k) s_k``: the linear
leakage term exactly, the gradient term by explicit Euler.

Scaling (ours): each component of ``z`` is shifted and divided by a scale,
``z̃_i = (z_i − o_i) / g_i``, so that one width rule fits all six; the centres and widths
live in these scaled units. `RBFAdaptive.for_reference` builds them from the reference.
The settings, the networks and that rule (and the choice of the assumed defaults) are in
`microfab.control.rbf_network`, re-exported here. Only positions are measured: ``x2``,
``x̄2`` come from the filtered differentiator of `microfab.control.velocity`, ``ṙ``,
``r̈`` from the reference window (which must carry velocity and acceleration).

The certainty-equivalence oracle (eq. 6) and the checks of eqs. 7-8 and A6 are in
`microfab.control.certainty`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Self

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.control.rbf_network import (
    N_AXES,
    N_Z,
    RBFConfig,
    RBFNetwork,
    _stack_reference,
    networks_for_reference,
)
from microfab.control.replay import replay_steps
from microfab.control.velocity import (
    N_ESTIMATOR_PARAMS,
    N_ESTIMATOR_STATES,
    estimator_step,
)
from microfab.core.fastexp import exp_fast
from microfab.core.validate import check_positive

__all__ = [
    "N_AXES",
    "N_Z",
    "RBFAdaptive",
    "RBFConfig",
    "RBFLog",
    "RBFNetwork",
    "networks_for_reference",
    "rbf_core",
    "rbf_step",
]

_HEAD = 4 + N_ESTIMATOR_PARAMS  # l, dt, λ, spare; estimator (velocity.py)


def _layout(nl: int) -> tuple[int, int, int, int, int]:
    """State offsets ``(estimators, h, z, s, v)`` for ``nl`` nodes per axis."""
    ie = N_AXES * nl
    ih = ie + N_AXES * N_ESTIMATOR_STATES
    iz = ih + N_AXES * nl
    return ie, ih, iz, iz + N_Z, iz + N_Z + N_AXES


@njit(cache=True)
def rbf_core(p: np.ndarray, x: np.ndarray, r: np.ndarray, ym: np.ndarray, u: np.ndarray) -> None:
    """One sample of both axes' RBF controllers, in place (no allocation).

    ``r`` is the reference at this sample, shape (n_orders >= 3, 2): position (mm),
    velocity (mm/s), acceleration (mm/s²); a composite controller (plug-in RC, seed 001
    Fig. 7) may pass a corrected copy. Layouts: see `RBFAdaptive`.

    The node loops run over slice views (indices from ``range`` need no negative-index
    check) with the centres stored input by input, and ``h`` uses `exp_fast`, so that
    LLVM vectorises them; the result is that of `RBFAdaptive.step` to a few ULP.
    """
    if r.shape[0] < 3:
        raise ValueError("the RBF controller needs a reference with velocity and acceleration")
    nl = int(p[0])
    lam = p[2]
    stride = 2 * N_Z + (N_Z + 3) * nl
    ie = N_AXES * nl
    ih = ie + N_AXES * N_ESTIMATOR_STATES
    iz = ih + N_AXES * nl
    isv = iz + N_Z
    v0 = estimator_step(p, 4, x, ie, ym[0])
    v1 = estimator_step(p, 4, x, ie + N_ESTIMATOR_STATES, ym[1])
    for a in range(N_AXES):
        o = _HEAD + a * stride
        if a == 0:
            xa, va, xb, vb = ym[0], v0, ym[1], v1
        else:
            xa, va, xb, vb = ym[1], v1, ym[0], v0
        ed = va - r[1, a]
        s = lam * (xa - r[0, a]) + ed
        vv = lam * ed - r[2, a]
        x[iz] = (xa - p[o]) * p[o + 6]
        x[iz + 1] = (va - p[o + 1]) * p[o + 7]
        x[iz + 2] = (xb - p[o + 2]) * p[o + 8]
        x[iz + 3] = (vb - p[o + 3]) * p[o + 9]
        x[iz + 4] = (s - p[o + 4]) * p[o + 10]
        x[iz + 5] = (vv - p[o + 5]) * p[o + 11]
        ic = o + 2 * N_Z
        ib = ic + N_Z * nl
        w = x[a * nl : (a + 1) * nl]
        h = x[ih + a * nl : ih + (a + 1) * nl]
        ib2 = p[ib : ib + nl]
        gdt = p[ib + nl : ib + 2 * nl]
        decay = p[ib + 2 * nl : ib + 3 * nl]
        h[:] = 0.0
        for i in range(N_Z):
            zi = x[iz + i]
            c = p[ic + i * nl : ic + (i + 1) * nl]
            for j in range(nl):
                dz = zi - c[j]
                h[j] += dz * dz
        for j in range(nl):
            h[j] = exp_fast(-h[j] * ib2[j])
        acc = 0.0
        for j in range(nl):
            acc += w[j] * h[j]
        u[a] = acc
        for j in range(nl):
            w[j] = decay[j] * w[j] - gdt[j] * h[j] * s
        x[isv + a] = s
        x[isv + N_AXES + a] = vv


@njit(cache=True)
def rbf_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """`CompiledController` kernel: `rbf_core` on ``ref[k]``."""
    rbf_core(p, x, ref[k], ym, u)


@njit(cache=True)
def _rbf_record(p: np.ndarray, x: np.ndarray, row: np.ndarray) -> None:
    """`replay_steps` log of the state ``x``: s, v, ‖Ŵ‖ per axis, then ``h`` if ``row`` has room."""
    nl = int(p[0])
    ih = N_AXES * nl + N_AXES * N_ESTIMATOR_STATES
    isv = ih + N_AXES * nl + N_Z
    for a in range(N_AXES):
        row[a] = x[isv + a]
        row[N_AXES + a] = x[isv + N_AXES + a]
        acc = 0.0
        for j in range(nl):
            acc += x[a * nl + j] * x[a * nl + j]
        row[2 * N_AXES + a] = math.sqrt(acc)
    if row.shape[0] > 3 * N_AXES:
        for a in range(N_AXES):
            for j in range(nl):
                row[3 * N_AXES + a * nl + j] = x[ih + a * nl + j]


@dataclass(frozen=True, kw_only=True, eq=False)
class RBFLog:
    """Per-sample signals of an RBF run, replayed from its measurements (`RBFAdaptive.replay`).

    Attributes
    ----------
    command : numpy.ndarray
        ``u = Ŵᵀh``, V, shape (n, 2).
    s : numpy.ndarray
        Error function ``s = λe + ė`` (estimated ``ė``), mm/s, shape (n, 2).
    v : numpy.ndarray
        ``v = λė − r̈``, mm/s², shape (n, 2).
    weight_norm : numpy.ndarray
        ‖Ŵ‖ used at each sample (before its update), V, shape (n, 2).
    hidden : numpy.ndarray or None
        ``h(z)`` per sample and axis, shape (n, 2, l), when asked for.
    final_state : numpy.ndarray
        Controller state after the last sample.
    """

    command: np.ndarray
    s: np.ndarray
    v: np.ndarray
    weight_norm: np.ndarray
    hidden: np.ndarray | None
    final_state: np.ndarray


class RBFAdaptive(CompiledController):
    """Two-axis RBF adaptive controller, seed 001 eqs. 2, 4, 5 (see the module docstring).

    Measurement: positions (x, y), mm, shape (2,). Command: amplifier inputs, V, shape
    (2,). The reference window must carry velocity (mm/s) and acceleration (mm/s²).

    Parameters
    ----------
    config : RBFConfig
        λ, Γ, σ, estimator (its ``n_nodes`` must match the networks).
    networks : sequence of RBFNetwork
        The x and y networks (scaling, centres, widths, initial weights).
    dt : float
        Sample time, s.

    Notes
    -----
    ``params``: ``[l, dt, λ, 0, estimator(11)]`` then per axis ``[offset(6), 1/scale(6),
    centres(6*l, input by input: c_1 of every node, then c_2, ...), 1/(2 b²)(l), Γ dt(l),
    exp(−Γσ dt)(l)]``. State: ``[Ŵ_x(l), Ŵ_y(l),
    estimator x(3), estimator y(3), h_x(l), h_y(l), z̃(6), s(2), v(2)]`` (h, z̃, s and v
    are the last sample's, kept for logging).
    """

    kernel_step: Any = rbf_step

    def __init__(self, *, config: RBFConfig, networks: Sequence[RBFNetwork], dt: float) -> None:
        if not isinstance(config, RBFConfig):
            raise ValueError(f"config must be an RBFConfig, got {type(config).__name__}")
        nets = tuple(networks)
        if len(nets) != N_AXES or not all(isinstance(n, RBFNetwork) for n in nets):
            raise ValueError("networks must be two RBFNetwork, for the x and y axes")
        for name, net in zip("xy", nets, strict=True):
            if net.n_nodes != config.n_nodes:
                raise ValueError(
                    f"the {name} network has {net.n_nodes} nodes but n_nodes = "
                    f"{config.n_nodes}; make them equal"
                )
        self.dt = check_positive("dt", dt, "s")
        self.config = config
        self.networks = nets
        self.preview = 1
        self.n_inputs = N_AXES
        self.n_outputs = N_AXES
        nl = config.n_nodes
        g = config.gamma_diagonal()
        head = np.zeros(_HEAD)
        head[:3] = (nl, dt, config.lam)
        head[4:] = config.estimator.discrete(dt)
        parts = [head]
        for net in nets:
            parts += [
                net.offset,
                1.0 / net.scale,
                net.centres.T.ravel(),
                1.0 / (2.0 * net.widths**2),
                g * dt,
                np.exp(-g * config.sigma * dt),
            ]
        self.params = np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)
        self.params.setflags(write=False)

    @property
    def n_nodes(self) -> int:
        """Nodes per axis ``l``."""
        return self.config.n_nodes

    def _axis_params(self, a: int) -> tuple[np.ndarray, ...]:
        """``(offset, 1/scale, centres, 1/(2b²), Γdt, decay)`` of axis ``a`` from ``params``."""
        nl = self.n_nodes
        o = _HEAD + a * (2 * N_Z + (N_Z + 3) * nl)
        p = self.params
        c = p[o + 2 * N_Z : o + 2 * N_Z + N_Z * nl].reshape(N_Z, nl).T
        ib = o + 2 * N_Z + N_Z * nl
        return (p[o : o + 6], p[o + 6 : o + 12], c, p[ib : ib + nl],
                p[ib + nl : ib + 2 * nl], p[ib + 2 * nl : ib + 3 * nl])  # fmt: skip

    def init(self) -> np.ndarray:
        """Initial weights, estimators not yet initialised, empty logs; shape (4l + 16,)."""
        nl = self.n_nodes
        x = np.zeros(4 * nl + 2 * N_ESTIMATOR_STATES + N_Z + 2 * N_AXES)
        for a, net in enumerate(self.networks):
            x[a * nl : (a + 1) * nl] = net.weights
        return x

    def weights(self, state: np.ndarray) -> np.ndarray:
        """Ŵ of both axes from a state, shape (2, l) (a copy)."""
        nl = self.n_nodes
        return np.array(state[: N_AXES * nl]).reshape(N_AXES, nl)

    def error_function(self, state: np.ndarray) -> np.ndarray:
        """``s = λe + ė`` of both axes at the last sample, mm/s, shape (2,) (a copy)."""
        isv = _layout(self.n_nodes)[3]
        return np.array(state[isv : isv + N_AXES])

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference for `rbf_step`): ``(command, new state)``."""
        if window.velocity is None or window.acceleration is None:
            raise ValueError(
                "the RBF controller needs a reference with velocity and acceleration "
                "(give the simulator derivatives=(velocity, acceleration))"
            )
        nl = self.n_nodes
        ie, ih, iz, isv, iv = _layout(nl)
        x = np.array(state, dtype=float)
        ym = np.asarray(measurement, dtype=float)
        phi = self.params[4:_HEAD]
        vel = np.empty(N_AXES)
        for a in range(N_AXES):
            i0 = ie + a * N_ESTIMATOR_STATES
            vel[a], x[i0 : i0 + N_ESTIMATOR_STATES] = self.config.estimator.step(
                phi, x[i0 : i0 + N_ESTIMATOR_STATES], float(ym[a])
            )
        u = np.empty(N_AXES)
        for a in range(N_AXES):
            b = 1 - a
            off, inv, c, ib2, gdt, decay = self._axis_params(a)
            ed = vel[a] - window.velocity[0, a]
            s = self.config.lam * (ym[a] - window.position[0, a]) + ed
            v = self.config.lam * ed - window.acceleration[0, a]
            z = np.array([ym[a], vel[a], ym[b], vel[b], s, v])
            zs = (z - off) * inv
            h = np.exp(-((zs - c) ** 2).sum(axis=1) * ib2)
            w = x[a * nl : (a + 1) * nl]
            u[a] = w @ h
            x[a * nl : (a + 1) * nl] = decay * w - gdt * h * s
            x[ih + a * nl : ih + (a + 1) * nl] = h
            x[iz : iz + N_Z] = zs
            x[isv + a], x[iv + a] = s, v
        return u, x

    def replay(
        self,
        reference: np.ndarray,
        velocity: np.ndarray,
        acceleration: np.ndarray,
        measured: np.ndarray,
        state: np.ndarray | None = None,
        *,
        hidden: bool = False,
    ) -> RBFLog:
        """Run the controller over recorded measurements and log its internals.

        The controller is deterministic given its measurements and reference, so this
        reproduces the commands of a closed-loop run (simulated or measured) and adds
        ``s``, ``v``, ‖Ŵ‖ and optionally ``h`` per sample (for the report and the checks
        of eqs. 7-8).

        Parameters
        ----------
        reference, velocity, acceleration : numpy.ndarray
            Reference position (mm), velocity (mm/s), acceleration (mm/s²), shape (n, 2).
        measured : numpy.ndarray
            Measured positions the controller saw, mm, shape (n, 2).
        state : numpy.ndarray, optional
            Starting state (default `init`).
        hidden : bool
            Also keep ``h(z)`` (shape (n, 2, l)).

        Returns
        -------
        RBFLog
        """
        ym = np.ascontiguousarray(np.asarray(measured, dtype=float))
        if ym.ndim != 2 or ym.shape[1] != N_AXES or not np.all(np.isfinite(ym)):
            raise ValueError(f"measured must be finite and shaped (n, 2), got {ym.shape}")
        n = ym.shape[0]
        R = _stack_reference(reference, velocity, acceleration, n)
        x = self.init() if state is None else np.array(state, dtype=float)
        na, nl = N_AXES, self.n_nodes
        width = 3 * na + (na * nl if hidden else 0)
        start = np.empty(width)
        _rbf_record(self.params, x, start)  # ‖Ŵ‖ before the first update
        u, log = replay_steps(rbf_step, self.params, x, R, ym, na, _rbf_record, width)
        # ‖Ŵ‖ used at sample k is the norm after the update of sample k - 1
        wn = np.concatenate([start[None, 2 * na : 3 * na], log[:-1, 2 * na : 3 * na]])[:n]
        return RBFLog(
            command=u,
            s=np.ascontiguousarray(log[:, :na]),
            v=np.ascontiguousarray(log[:, na : 2 * na]),
            weight_norm=wn,
            hidden=log[:, 3 * na :].reshape(n, na, nl) if hidden else None,
            final_state=x,
        )

    @classmethod
    def for_reference(
        cls,
        position: np.ndarray,
        velocity: np.ndarray,
        acceleration: np.ndarray,
        dt: float,
        config: RBFConfig | None = None,
        *,
        closed: bool = True,
    ) -> Self:
        """The controller with centres, widths and scaling from a reference (default rule).

        The centres, widths and scaling follow `networks_for_reference` (the rule is
        stated there; ours, the seed gives none).

        Parameters
        ----------
        position, velocity, acceleration : numpy.ndarray
            Reference, shape (n >= l, 2), mm, mm/s, mm/s².
        dt : float
            Sample time, s.
        config : RBFConfig, optional
            Settings (default `RBFConfig()`).
        closed : bool
            Whether the reference is one period of a closed (repeated) contour.
        """
        cfg = RBFConfig() if config is None else config
        nets = networks_for_reference(position, velocity, acceleration, cfg, closed=closed)
        return cls(config=cfg, networks=nets, dt=dt)
