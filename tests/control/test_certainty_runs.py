"""Seed 001 eqs. 7-8 and A6 along a run of the nonlinear twin under the RBF controller.

`tests/control/test_rbf.py` checks them on a linear stand-in (eq. 9 alone, no ``d``); here
the plant is the twin of `microfab.plants.nanomanipulator` (the §4.1 terms and the
disturbance ``d(t)`` on), run as `compare.py` runs its RBF loop (its circle 0.25 mm
off-centre, the default RBF rule on one period), one period, noise off. The loop is stepped
in Python over the compiled kernels so that the twin's true ``(x1, x2, y1, y2)``, the
weights ``Ŵ`` and ``h(z)`` are known at every sample (the run is checked to be the one
`simulate` gives).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest

from microfab.control.certainty import (
    a6_bound,
    ce_law,
    eq7_rhs,
    eq8_rhs,
    fit_ideal_weights,
    lyapunov_v,
)
from microfab.control.rbf import RBFAdaptive
from microfab.experiments.seed001_nanomanipulator.compare import ComparisonConfig
from microfab.plants.nanomanipulator import (
    NanomanipulatorPlant,
    drift_and_gain,
    nanomanipulator_twin,
)
from microfab.sim.loop import simulate
from microfab.trajectory.circle_pattern import pattern_reference

# Trapezoid rule over one sample (command and d held): the residual of ṡ is
# dt²/12 · s''' somewhere in the sample. On the linear part of eq. 1 (α = −a0 x1 − a1 x2)
# s''' = −a0(λ − a1) x2 − (a0 + λa1 − a1²) ẍ1 − λ r⃛ − r⁗; we bound it by
# a0(λ + a1)|x2| + (a0 + λa1 + a1²)|ẍ1| at the samples (the reference's r⃛, r⁗ add
# < 1e-3 of that here). The §4.1 cross term a0/(ω_n L) x1 x̄2 adds x1 d²x̄2/dt² ~ (x1/L) of
# the linear part (a third at the circle's 0.33 mm), and the largest value inside a sample
# exceeds the sampled ones: hence a factor 3 (measured: 1.4 in the lead-in, 0.55 on the
# circle).
TRAPEZOID_FACTOR = 3.0


@dataclass(frozen=True, kw_only=True, eq=False)
class TwinRun:
    """One recorded closed-loop run (n samples)."""

    plant: NanomanipulatorPlant
    ctl: RBFAdaptive
    ref: np.ndarray  # (n + 1, 3, 2): position, velocity, acceleration (held after the end)
    states: np.ndarray  # (n + 1, 4): true x1, x2, y1, y2 at the sample instants
    weights: np.ndarray  # (n, 2, l): Ŵ used at each sample
    hidden: np.ndarray  # (n, 2, l): h(z) at each sample
    command: np.ndarray  # (n, 2), V
    disturbance: np.ndarray  # (n, 2): d held over each sample, mm/s²
    segments: dict[str, slice]  # lead-in, circle, tail


@pytest.fixture(scope="module")
def run() -> TwinRun:
    cfg = ComparisonConfig()
    plant = nanomanipulator_twin(seed=cfg.seed)
    dt = plant.dt
    ref = pattern_reference(replace(cfg.pattern, periods=1), dt)
    pos = ref.position + cfg.offset_mm
    s0, n_per = ref.starts[0], ref.period_samples
    one = slice(s0, s0 + n_per)
    ctl = RBFAdaptive.for_reference(pos[one], ref.velocity[one], ref.acceleration[one], dt, cfg.rbf)
    R = np.ascontiguousarray(np.stack([pos, ref.velocity, ref.acceleration], axis=1))
    n, nl = pos.shape[0], ctl.n_nodes
    out_k, upd_k = plant.kernels()
    (step_k,) = ctl.kernels()
    pp, cp = plant.packed_params(), ctl.packed_params()
    px, cx = plant.init(), ctl.init()
    X = np.empty((n + 1, 4))
    C = np.empty((n + 1, cx.size))  # controller state before each sample, and the last
    U = np.empty((n, 2))
    y = np.empty(2)
    for k in range(n):
        X[k], C[k] = px[:4], cx
        out_k(pp, px, y)
        step_k(cp, cx, R, k, y, U[k])
        upd_k(pp, px, U[k])
    X[n], C[n] = px[:4], cx
    ih = 2 * nl + 6  # h_x, h_y follow Ŵ (2l) and the estimators (2 x 3): `RBFAdaptive`
    c = plant.config
    phases = c.disturbance_phases()
    t = np.arange(n) * dt
    d = np.zeros((n, 2))
    for a in range(2):
        for j, (f, w) in enumerate(
            zip(c.disturbance_frequencies_hz, c.disturbance_weights, strict=True)
        ):
            d[:, a] += c.disturbance_mm_s2[a] * w * np.sin(2 * math.pi * f * t + phases[a, j])
    return TwinRun(
        plant=plant,
        ctl=ctl,
        ref=np.concatenate([R, R[-1:]]),
        states=X,
        weights=C[:n, : 2 * nl].reshape(n, 2, nl),
        hidden=C[1:, ih : ih + 2 * nl].reshape(n, 2, nl),  # h of sample k is in the state after it
        command=U,
        disturbance=d,
        segments={
            "lead-in": slice(0, s0),
            "circle": slice(s0, s0 + n_per),
            "tail": slice(s0 + n_per, n),
        },
    )


def true_terms(run: TwinRun, a: int) -> dict[str, np.ndarray]:
    """s, v, α, β, β̇ and u* of axis ``a`` from the true states, at the n + 1 instants."""
    lam, eps = run.ctl.config.lam, run.ctl.config.eps
    x1, x2 = run.states[:, 2 * a], run.states[:, 2 * a + 1]
    s = lam * (x1 - run.ref[:, 0, a]) + x2 - run.ref[:, 1, a]
    v = lam * (x2 - run.ref[:, 1, a]) - run.ref[:, 2, a]
    p = run.plant.params
    ab = np.array([drift_and_gain(p, a, xk) for xk in run.states])
    beta_dot = np.gradient(ab[:, 1], run.plant.dt)  # central differences along the run
    u_star = ce_law(ab[:, 0], ab[:, 1], beta_dot, s, v, eps)
    return {"s": s, "v": v, "alpha": ab[:, 0], "beta": ab[:, 1], "beta_dot": beta_dot,
            "u_star": u_star}  # fmt: skip


@pytest.fixture(scope="module")
def terms(run: TwinRun) -> tuple[dict[str, np.ndarray], ...]:
    """`true_terms` of both axes (computed once)."""
    return true_terms(run, 0), true_terms(run, 1)


def test_the_recorded_run_is_the_simulated_one_and_u_is_eq4(run: TwinRun) -> None:
    R = run.ref[:-1]
    res = simulate(run.plant, run.ctl, R[:, 0], derivatives=(R[:, 1], R[:, 2]))
    np.testing.assert_array_equal(res.command, run.command)
    np.testing.assert_array_equal(res.output, run.states[:-1, [0, 2]])
    # eq. 4: the command is the network's output Ŵᵀh(z)
    net = np.einsum("kal,kal->ka", run.weights, run.hidden)
    np.testing.assert_allclose(net, run.command, rtol=0, atol=1e-14)
    assert np.abs(run.command).max() > 0.05  # V: the network drives the stage (0.095 V)


@pytest.mark.parametrize("a", [0, 1], ids=["x", "y"])
def test_eq7_and_eq8_hold_along_the_twin_run(
    run: TwinRun, terms: tuple[dict[str, np.ndarray], ...], a: int
) -> None:
    dt, eps, lam = run.plant.dt, run.ctl.config.eps, run.ctl.config.lam
    q = terms[a]
    s, b, bd, us = q["s"], q["beta"], q["beta_dot"], q["u_star"]
    u, d = run.command[:, a], run.disturbance[:, a]
    H = run.hidden[:, a]
    w_star = fit_ideal_weights(H, us[:-1])
    ideal = H @ w_star
    net = np.einsum("kl,kl->k", run.weights[:, a], H)
    sdot = np.diff(s) / dt
    # each sample's right sides at its start (k) and end (k + 1), command, h and d held
    ends = (slice(None, -1), slice(1, None))
    rhs8 = [eq8_rhs(b[e], bd[e], u, us[e], s[e], eps, d) for e in ends]
    rhs7 = [
        eq7_rhs(q["alpha"][e], b[e], q["v"][e], net, ideal, us[e] - ideal, us[e], d) for e in ends
    ]
    for r7, r8 in zip(rhs7, rhs8, strict=True):  # eq. 6 substituted into eq. 7 gives eq. 8
        np.testing.assert_allclose(r7, r8, rtol=0, atol=1e-9 * np.abs(r8).max())
    resid = sdot - 0.5 * (rhs8[0] + rhs8[1])
    c = run.plant.config
    a0, a1 = c.stiffness_per_s2[a], c.damping_per_s[a]
    x2 = run.states[:, 2 * a + 1]
    acc = [q["alpha"][e] + b[e] * u + d for e in ends]  # ẍ1 by eq. 1
    g = np.maximum(*(a0 * (lam + a1) * np.abs(x2[e]) + (a0 + lam * a1 + a1 * a1) * np.abs(ac)
                     for e, ac in zip(ends, acc, strict=True)))  # fmt: skip
    for name, seg in run.segments.items():
        tol = TRAPEZOID_FACTOR * dt * dt / 12.0 * g[seg].max()
        worst = np.abs(resid[seg]).max()
        assert worst <= tol, (name, worst, tol)
    # d is resolved: on the circle (tolerance ~0.014 mm/s²) leaving out d (|d| <= d0 = 20 or
    # 40 mm/s²) breaks the identity
    seg = run.segments["circle"]
    tol = TRAPEZOID_FACTOR * dt * dt / 12.0 * g[seg].max()
    assert np.median(np.abs(resid + d)[seg]) > 100 * tol
    assert np.abs(sdot).max() > 1e4  # mm/s²: the lead-in's step of 0.25 mm moves s hard


def a6_terms(
    run: TwinRun, q: dict[str, np.ndarray], a: int
) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """``(|s| true, A6 bound, inputs)`` of axis ``a`` with measured μ0 and the twin's d0."""
    cfg = run.ctl.config
    n = run.command.shape[0]
    H = run.hidden[:, a]
    us = q["u_star"][:-1]
    w_star = fit_ideal_weights(H, us)
    mu = us - H @ w_star  # eq. 7: μ_l = u* − W*ᵀh, along the run
    gamma = cfg.gamma_diagonal()
    beta = q["beta"]
    inputs = {
        "mu0": float(np.abs(mu).max()),
        "d0": float(run.plant.config.disturbance_mm_s2[a]),
        "beta0": float(np.abs(beta).max()),
        "eps": cfg.eps,
        "sigma": cfg.sigma,
        "gamma_bar": float(1.0 / gamma.min()),
        "w_star_norm": float(np.linalg.norm(w_star)),
        "v0": lyapunov_v(q["s"][0], beta[0], run.ctl.networks[a].weights - w_star, gamma),
    }
    bound = a6_bound(np.arange(n) * run.plant.dt, **inputs)
    return np.abs(q["s"][:-1]), bound, inputs


@pytest.mark.parametrize("a", [0, 1], ids=["x", "y"])
def test_s_stays_under_the_a6_bound_on_the_twin(
    run: TwinRun, terms: tuple[dict[str, np.ndarray], ...], a: int
) -> None:
    s, bound, inputs = a6_terms(run, terms[a], a)
    c = run.plant.config
    beta = terms[a]["beta"]
    # the proof needs β >= β_min > 0 (certainty.py); the twin keeps it on this run
    assert beta.min() >= c.beta_min_fraction * c.numerator_mm_per_v_s2[a]
    assert 0.01 < inputs["mu0"] < 1.0, inputs  # V: measured (0.11 x, 0.16 y)
    assert s.max() > 50.0  # mm/s: the lead-in's step (101 x, 89 y)
    ratio = float((s / bound).max())
    assert ratio <= 1.0, (ratio, inputs)  # measured 2.6e-4 (x), 2.5e-4 (y)


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="A6 is vacuous here: with α0 = γ̄/σ = 2e4 s and β0 ≈ 5.5e5 (x), 3.2e5 (y) "
    "mm/(s² V) in physical units, its steady part √(α0β0(εμ0²β0 + εd0²/2 + σ‖W*‖²)) is "
    "3.9e5 (x), 3.5e5 (y) mm/s, over 1000x the largest |s| = λ·3 mm + 2·20 mm/s = 340 mm/s "
    "the workspace allows (the μ0 term dominates: μ0 = 0.11, 0.16 V measured)",
)
@pytest.mark.parametrize("a", [0, 1], ids=["x", "y"])
def test_a6_bound_says_something_within_the_workspace(
    run: TwinRun, terms: tuple[dict[str, np.ndarray], ...], a: int
) -> None:
    _, bound, _ = a6_terms(run, terms[a], a)
    c = run.plant.config
    s_max = run.ctl.config.lam * 2 * c.workspace_mm + 2 * c.velocity_limit_mm_s
    assert bound.min() < s_max, (bound.min(), s_max)
