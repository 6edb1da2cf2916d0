"""Certainty-equivalence oracle (seed 001 eq. 6) and the checks of eqs. 7-8 and A6.

`CertaintyEquivalence` applies the law the RBF network of `microfab.control.rbf` is meant
to approximate,

``u* = −(1/β)(α + v) − (1/(εβ) + 1/(εβ²) − β̇/(2β²)) s``   (seed 001 eq. 6),

with the plant's true ``α``, ``β`` (an oracle: the twin's ``drift_and_gain``) evaluated at
the controller's estimate of the state (measured positions, velocities from the same
filter as the RBF controller's), ``β̇`` by a backward difference over one sample (0 at the
first sample). In physical units (β in mm/(s²·V), ~5e5 for eq. 9) the two ``s`` gains of
eq. 6 add 1/s to 1/(s·(mm/(s² V))): the seed's law is dimensionally consistent only for a
dimensionless β; we apply it as written, the ``1/(εβ²)`` term then being a ~2e-6 part of
the ``1/(εβ)`` one, and ``ṡ ≈ −s/ε`` under the oracle.

Checks along a run (`ce_law`, `fit_ideal_weights`, `eq7_rhs`, `eq8_rhs`, `a6_bound`):
with ``μ_l = u* − W*ᵀh`` (eq. 7; the seed says "substitute control law (5)", meaning (4)),
eq. 7 reads ``ṡ = α + v + β(Ŵᵀh − W*ᵀh − μ_l) + βu* + d`` and eq. 8
``ṡ = β(W̃ᵀh − μ_l) − (1/ε + 1/(εβ) − β̇/(2β)) s + d``, in which ``W̃ᵀh − μ_l = u − u*``
whatever ``W*``. Seed points on the proof: A1 writes
``W̃ᵀΓ⁻¹W̃ᵀ`` for ``W̃ᵀΓ⁻¹W̃``; in the step A2 -> A3 the ``μ_l s`` term needs ``β²``
(``|μ_l s| ≤ s²/(2εβ²) + (ε/2) μ_l² β²``), not ``β``, and dropping ``s²/(εβ)`` against
``s²/(2εβ²)`` needs ``β ≥ 1``; the proof needs ``β ≥ β_min > 0`` where the seed states
only ``|β| ≤ β0``. `a6_bound` evaluates the right side of A6 as printed.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Self

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.control.rbf import RBFConfig
from microfab.control.replay import replay_steps
from microfab.control.velocity import N_ESTIMATOR_PARAMS, N_ESTIMATOR_STATES, estimator_step
from microfab.core.validate import check_nonnegative, check_positive

__all__ = [
    "CertaintyEquivalence",
    "a6_bound",
    "ce_law",
    "eq7_rhs",
    "eq8_rhs",
    "fit_ideal_weights",
    "lyapunov_v",
]

_HEAD = 4 + N_ESTIMATOR_PARAMS  # dt, λ, ε, n_plant_params; estimator (velocity.py)
_NE = 2 * N_ESTIMATOR_STATES
# state: estimators (6), x = [x1, x2, y1, y2] (4), β_prev (2), started (1), logs:
# s (2), v (2), α (2), β (2), β̇ (2)
_IX = _NE
_IB = _IX + 4
_IST = _IB + 2
_ILOG = _IST + 1
_NSTATE = _ILOG + 10


@njit(cache=True, inline="always")
def _ce_u(alpha: float, beta: float, bdot: float, s: float, v: float, eps: float) -> float:
    """Seed 001 eq. 6 for one axis."""
    return -(alpha + v) / beta - (1.0 / (eps * beta) + 1.0 / (eps * beta * beta)
                                  - bdot / (2.0 * beta * beta)) * s  # fmt: skip


def ce_law(
    alpha: np.ndarray,
    beta: np.ndarray,
    beta_dot: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    eps: float,
) -> np.ndarray:
    """Seed 001 eq. 6, elementwise: ``u*`` in V from α (mm/s²), β (mm/(s² V)), β̇, s, v."""
    a, b, bd, s_, v_ = (np.asarray(x, dtype=float) for x in (alpha, beta, beta_dot, s, v))
    return -(a + v_) / b - (1.0 / (eps * b) + 1.0 / (eps * b * b) - bd / (2.0 * b * b)) * s_


def eq7_rhs(
    alpha: np.ndarray,
    beta: np.ndarray,
    v: np.ndarray,
    network: np.ndarray,
    ideal: np.ndarray,
    mu: np.ndarray,
    u_star: np.ndarray,
    disturbance: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Right side of seed 001 eq. 7, ``α + v + β(Ŵᵀh − W*ᵀh − μ_l) + βu* + d``, mm/s².

    Parameters
    ----------
    alpha, beta : numpy.ndarray
        α (mm/s²) and β (mm/(s² V)) of eq. 1.
    v : numpy.ndarray
        ``v = λė − r̈``, mm/s².
    network, ideal : numpy.ndarray
        ``Ŵᵀh`` (the command of eq. 4) and ``W*ᵀh``, V.
    mu : numpy.ndarray
        ``μ_l = u* − W*ᵀh``, V.
    u_star : numpy.ndarray
        ``u*`` of eq. 6, V.
    disturbance : numpy.ndarray or float
        ``d``, mm/s².

    Returns
    -------
    numpy.ndarray
        ``ṡ`` by eq. 7, mm/s²; arrays broadcast. With ``μ_l`` as defined it equals
        ``α + v + βŴᵀh + d``, eq. 1 written for ``s`` under the law of eq. 4.
    """
    b = np.asarray(beta, dtype=float)
    net, ide, m, us = (np.asarray(x, dtype=float) for x in (network, ideal, mu, u_star))
    return np.asarray(alpha) + np.asarray(v) + b * (net - ide - m) + b * us + disturbance


def eq8_rhs(
    beta: np.ndarray,
    beta_dot: np.ndarray,
    command: np.ndarray,
    u_star: np.ndarray,
    s: np.ndarray,
    eps: float,
    disturbance: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Right side of seed 001 eq. 8, ``β(u − u*) − (1/ε + 1/(εβ) − β̇/(2β)) s + d``, mm/s².

    ``u − u* = W̃ᵀh − μ_l`` (eq. 7), so no ``W*`` is needed; arrays broadcast.
    """
    b = np.asarray(beta, dtype=float)
    return (
        b * (np.asarray(command) - np.asarray(u_star))
        - (1.0 / eps + 1.0 / (eps * b) - np.asarray(beta_dot) / (2.0 * b)) * np.asarray(s)
        + disturbance
    )


def fit_ideal_weights(hidden: np.ndarray, u_star: np.ndarray, ridge: float = 1e-9) -> np.ndarray:
    """An estimate of ``W*``: ridge least squares of ``u*`` on ``h`` along a run.

    Parameters
    ----------
    hidden : numpy.ndarray
        ``h(z)`` per sample, shape (n, l).
    u_star : numpy.ndarray
        ``u*`` per sample, V, shape (n,).
    ridge : float
        Tikhonov weight relative to the largest eigenvalue of ``HᵀH`` (>= 0).

    Returns
    -------
    numpy.ndarray
        ``W*``, V, shape (l,); then ``μ_l = u* − hidden @ W*`` (eq. 7).
    """
    check_nonnegative("ridge", ridge, "")
    H = np.asarray(hidden, dtype=float)
    G = H.T @ H
    lam = ridge * max(float(np.linalg.eigvalsh(G)[-1]), 1e-300)
    return np.linalg.solve(G + lam * np.eye(G.shape[0]), H.T @ np.asarray(u_star, dtype=float))


def lyapunov_v(s: float, beta: float, w_tilde: np.ndarray, gamma: np.ndarray) -> float:
    """Seed 001 eq. A1 (read ``W̃ᵀΓ⁻¹W̃``): ``V = (s²/β + W̃ᵀ Γ⁻¹ W̃)/2``, Γ diagonal (l,)."""
    w = np.asarray(w_tilde, dtype=float)
    return 0.5 * (s * s / beta + float(np.sum(w * w / np.asarray(gamma, dtype=float))))


def a6_bound(
    t: np.ndarray,
    *,
    mu0: float,
    d0: float,
    beta0: float,
    eps: float,
    sigma: float,
    gamma_bar: float,
    w_star_norm: float,
    v0: float,
) -> np.ndarray:
    """Right side of seed 001 eq. A6, the bound on ``|s(t)|`` (mm/s), as printed.

    ``exp(−t/(2α0)) √(2β0 V(t0)) + √(α0 β0 (ε μ0² β0 + (ε/2) d0² + σ ‖W*‖²))`` with
    ``α0 = max(ε, γ̄/σ)`` (eq. A4). The seed's derivation needs β² in A2-A3 and
    ``β ≥ β_min > 0`` (module docstring); this is its printed result.

    Parameters
    ----------
    t : numpy.ndarray
        Time since ``t0``, s.
    mu0, d0 : float
        Bounds on ``|μ_l|`` (V) and ``|d|`` (mm/s²), e.g. measured maxima along a run.
    beta0 : float
        Bound on ``|β|``, mm/(s² V).
    eps, sigma : float
        ε (s) and σ of eqs. 5-6.
    gamma_bar : float
        Largest eigenvalue of Γ⁻¹ (mm/V).
    w_star_norm : float
        ‖W*‖, V.
    v0 : float
        ``V(t0)`` of eq. A1.
    """
    for name, val in (("mu0", mu0), ("d0", d0), ("w_star_norm", w_star_norm), ("v0", v0)):
        check_nonnegative(name, val, "")
    for name, val in (("beta0", beta0), ("eps", eps), ("sigma", sigma), ("gamma_bar", gamma_bar)):
        check_positive(name, val, "")
    a0 = max(eps, gamma_bar / sigma)
    tt = np.asarray(t, dtype=float)
    steady = math.sqrt(
        a0 * beta0 * (eps * mu0**2 * beta0 + 0.5 * eps * d0**2 + sigma * w_star_norm**2)
    )
    return np.exp(-tt / (2.0 * a0)) * math.sqrt(2.0 * beta0 * v0) + steady


@functools.cache
def _ce_kernel(drift_and_gain: Any) -> Any:
    """The CE controller kernel bound to one ``drift_and_gain`` (compiled once per function)."""

    @njit
    def kernel_step(
        p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
    ) -> None:
        if ref.shape[1] < 3:
            raise ValueError("the CE law needs a reference with velocity and acceleration")
        dt, lam, eps = p[0], p[1], p[2]
        npp = int(p[3])
        pp = p[_HEAD : _HEAD + npp]
        x[_IX] = ym[0]
        x[_IX + 1] = estimator_step(p, 4, x, 0, ym[0])
        x[_IX + 2] = ym[1]
        x[_IX + 3] = estimator_step(p, 4, x, N_ESTIMATOR_STATES, ym[1])
        st = x[_IX : _IX + 4]
        for a in range(2):
            alpha, beta = drift_and_gain(pp, a, st)
            bdot = (beta - x[_IB + a]) / dt if x[_IST] > 0.0 else 0.0
            x[_IB + a] = beta
            ed = x[_IX + 2 * a + 1] - ref[k, 1, a]
            s = lam * (x[_IX + 2 * a] - ref[k, 0, a]) + ed
            v = lam * ed - ref[k, 2, a]
            u[a] = _ce_u(alpha, beta, bdot, s, v, eps)
            x[_ILOG + a] = s
            x[_ILOG + 2 + a] = v
            x[_ILOG + 4 + a] = alpha
            x[_ILOG + 6 + a] = beta
            x[_ILOG + 8 + a] = bdot
        x[_IST] = 1.0

    return kernel_step


class CertaintyEquivalence(CompiledController):
    """Seed 001 eq. 6 with the plant's true α, β: an oracle baseline (two axes).

    Built with the plant's ``drift_and_gain(p, axis, x) -> (alpha, beta)`` (a numba
    function; ``x = [x1, x2, y1, y2]`` in mm and mm/s, ``d²x/dt² = α + β u + d``) and its
    parameter array; each such function gets its own subclass carrying the compiled
    kernel. λ, ε and the velocity estimator come from an `RBFConfig`, so that this law
    sees the same ``s`` and ``v`` as the RBF controller it is compared with.

    Parameters
    ----------
    drift_and_gain : numba dispatcher
        The plant's α, β.
    plant_params : numpy.ndarray
        Its flat ``float64`` parameters.
    config : RBFConfig
        λ (``lam``), ε (``eps``) and ``estimator``.
    dt : float
        Sample time, s.

    Notes
    -----
    State: ``[estimators(6), x(4), β_prev(2), started, s(2), v(2), α(2), β(2), β̇(2)]``
    (the last five pairs are the last sample's, for logging; `logged`).
    """

    kernel_step: Any = None
    _drift: Any = None

    def __new__(cls, drift_and_gain: Any, *args: Any, **kwargs: Any) -> Self:
        """An instance of the subclass whose kernel calls ``drift_and_gain``."""
        sub = _ce_class(drift_and_gain)
        return CompiledController.__new__(sub)  # type: ignore[return-value]

    def __init__(
        self, drift_and_gain: Any, plant_params: np.ndarray, config: RBFConfig, dt: float
    ) -> None:
        if not isinstance(config, RBFConfig):
            raise ValueError(f"config must be an RBFConfig, got {type(config).__name__}")
        self.dt = check_positive("dt", dt, "s")
        pp = np.ascontiguousarray(np.asarray(plant_params, dtype=np.float64).ravel())
        if not np.all(np.isfinite(pp)):
            raise ValueError("plant_params holds NaN or inf")
        self.config = config
        self.preview = 1
        self.n_inputs = 2
        self.n_outputs = 2
        head = np.zeros(_HEAD)
        head[:4] = (dt, config.lam, config.eps, pp.size)
        head[4:] = config.estimator.discrete(dt)
        self.params = np.concatenate([head, pp])
        self.params.setflags(write=False)
        self.plant_params = pp

    def init(self) -> np.ndarray:
        """Estimators not initialised, no β yet; shape (23,)."""
        return np.zeros(_NSTATE)

    @staticmethod
    def logged(state: np.ndarray) -> dict[str, np.ndarray]:
        """The last sample's ``s``, ``v``, ``alpha``, ``beta``, ``beta_dot`` (each (2,))."""
        names = ("s", "v", "alpha", "beta", "beta_dot")
        return {n: np.array(state[_ILOG + 2 * i : _ILOG + 2 * i + 2]) for i, n in enumerate(names)}

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference for the kernel): ``(u*, new state)``."""
        if window.velocity is None or window.acceleration is None:
            raise ValueError(
                "the certainty-equivalence law needs a reference with velocity and acceleration"
            )
        x = np.array(state, dtype=float)
        ym = np.asarray(measurement, dtype=float)
        phi = self.params[4:_HEAD]
        est = self.config.estimator
        for a in range(2):
            i0 = a * N_ESTIMATOR_STATES
            vel, x[i0 : i0 + N_ESTIMATOR_STATES] = est.step(
                phi, x[i0 : i0 + N_ESTIMATOR_STATES], float(ym[a])
            )
            x[_IX + 2 * a], x[_IX + 2 * a + 1] = ym[a], vel
        st = np.array(x[_IX : _IX + 4])
        u = np.empty(2)
        lam, eps = self.config.lam, self.config.eps
        for a in range(2):
            alpha, beta = type(self)._drift(self.plant_params, a, st)
            bdot = (beta - x[_IB + a]) / self.dt if x[_IST] > 0.0 else 0.0
            x[_IB + a] = beta
            ed = st[2 * a + 1] - window.velocity[0, a]
            s = lam * (st[2 * a] - window.position[0, a]) + ed
            v = lam * ed - window.acceleration[0, a]
            u[a] = float(ce_law(alpha, beta, bdot, s, v, eps))
            x[_ILOG + a : _ILOG + 10 : 2] = (s, v, alpha, beta, bdot)
        x[_IST] = 1.0
        return u, x

    def replay(
        self,
        reference: np.ndarray,
        velocity: np.ndarray,
        acceleration: np.ndarray,
        measured: np.ndarray,
    ) -> dict[str, np.ndarray]:
        """``u*`` and its terms along recorded measurements (e.g. of an RBF run).

        Returns
        -------
        dict of numpy.ndarray
            ``u_star`` (V), ``s``, ``v``, ``alpha``, ``beta``, ``beta_dot``, each (n, 2).
        """
        from microfab.control.rbf import _stack_reference

        ym = np.ascontiguousarray(np.asarray(measured, dtype=float))
        if ym.ndim != 2 or ym.shape[1] != 2 or not np.all(np.isfinite(ym)):
            raise ValueError(f"measured must be finite and shaped (n, 2), got {ym.shape}")
        n = ym.shape[0]
        R = _stack_reference(reference, velocity, acceleration, n)
        u, logs = replay_steps(self.kernels()[0], self.params, self.init(), R, ym, 2, _record, 10)
        out = {"u_star": u}
        for i, name in enumerate(("s", "v", "alpha", "beta", "beta_dot")):
            out[name] = np.ascontiguousarray(logs[:, 2 * i : 2 * i + 2])
        return out


@njit(cache=True)
def _record(p: np.ndarray, x: np.ndarray, row: np.ndarray) -> None:
    """`replay_steps` log: the state's ``(s, v, α, β, β̇)`` per axis, interleaved x, y."""
    for i in range(10):
        row[i] = x[_ILOG + i]


@functools.cache
def _ce_class(drift_and_gain: Any) -> type[CertaintyEquivalence]:
    """The subclass of `CertaintyEquivalence` for one ``drift_and_gain``."""
    from microfab.core.compiled import is_kernel

    if not is_kernel(drift_and_gain):
        raise ValueError(
            "drift_and_gain must be a numba @njit function (p, axis, x) -> (alpha, beta), "
            f"got {type(drift_and_gain).__name__}"
        )
    name = getattr(drift_and_gain, "__name__", "model")
    return type(
        f"CertaintyEquivalence[{name}]",
        (CertaintyEquivalence,),
        {"kernel_step": _ce_kernel(drift_and_gain), "_drift": staticmethod(drift_and_gain)},
    )
