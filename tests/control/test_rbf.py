"""RBF adaptive controller and certainty-equivalence oracle (seed 001 eqs. 2-8, A6).

The plant here is a stand-in: seed 001 eq. 9 as an `LTIPlant` with states (x1, x2) per
axis (ZOH at 10 kHz), with a test-local ``drift_and_gain`` for the linear eq. 9.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

import control
from microfab.control.base import LTIController, ReferenceWindow
from microfab.control.certainty import (
    CertaintyEquivalence,
    a6_bound,
    ce_law,
    eq8_rhs,
    fit_ideal_weights,
    lyapunov_v,
)
from microfab.control.rbf import RBFAdaptive, RBFConfig, RBFNetwork
from microfab.control.velocity import VelocityEstimator
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI, block_diag, discretize
from microfab.sim.loop import simulate, simulate_python

DT = 1e-4  # assumed sample rate 10 kHz (shared contract)
# seed 001 eq. 9: K, a1, a0 of K / (s² + a1 s + a0), x then y
EQ9 = np.array([101793.23, 14.88, 548248.13, 99664.23, 18.52, 319852.42])
A = 0.075  # mm: the 0.15 mm circle of seed 001 §4.2
F = 1.0  # Hz (assumed rate of the circle)
N_PER = round(1.0 / (F * DT))


@njit(cache=True)
def linear_drift_and_gain(p: np.ndarray, axis: int, x: np.ndarray) -> tuple[float, float]:
    """Eq. 9 as eq. 1: alpha = −a0 x1 − a1 x2, beta = K (no nonlinear terms)."""
    o = 3 * axis
    return -p[o] * x[2 * axis] - p[o + 1] * x[2 * axis + 1], p[o + 2]


def eq9_axis(a0: float, a1: float, k: float) -> DiscreteLTI:
    ss = control.ss([[0.0, 1.0], [-a0, -a1]], [[0.0], [k]], [[1.0, 0.0]], [[0.0]])
    return discretize(ss, DT)


def stand_in() -> LTIPlant:
    return LTIPlant(block_diag(eq9_axis(*EQ9[:3]), eq9_axis(*EQ9[3:])))


def circle(n_periods: float) -> tuple[np.ndarray, ...]:
    """Circle through the origin (where the stage rests), centre (0, A): p, v, a, (n, 2)."""
    t = np.arange(round(n_periods * N_PER)) * DT
    w = 2 * math.pi * F
    p = np.column_stack([A * np.sin(w * t), A * (1 - np.cos(w * t))])
    v = np.column_stack([A * w * np.cos(w * t), A * w * np.sin(w * t)])
    a = np.column_stack([-A * w * w * np.sin(w * t), A * w * w * np.cos(w * t)])
    return t, p, v, a


def rms_per_period(err: np.ndarray) -> np.ndarray:
    n = err.shape[0] // N_PER
    e = err[: n * N_PER].reshape(n, N_PER, 2)
    return np.sqrt(np.mean(e**2, axis=(1, 2)))


@pytest.fixture(scope="module")
def circle_run():
    """Four periods of the circle under the default RBF controller, noise off."""
    _, p, v, a = circle(4)
    ctl = RBFAdaptive.for_reference(p[:N_PER], v[:N_PER], a[:N_PER], DT)
    res = simulate(stand_in(), ctl, p, derivatives=(v, a))
    return ctl, p, v, a, res


# ---------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"gamma": 0.0}, r"gamma \(Γ\) must be positive.*0.0 V/mm"),
        ({"gamma": -1.0}, "gamma"),
        ({"gamma": (0.1, 0.1)}, "gamma .* must have n_nodes = 25 entries, got 2"),
        ({"n_nodes": 3, "gamma": (0.1, -0.1, 0.1)}, r"gamma\[1\]"),
        ({"sigma": 0.0}, r"sigma \(σ\) must be positive"),
        ({"eps": -1e-3}, r"eps \(ε\) must be positive.*s"),
        ({"lam": 0.0}, r"lam \(λ of s = λe \+ ė\) must be positive.*1/s"),
        ({"lam": float("nan")}, "lam"),
        ({"width_factor": 0.0}, "width_factor"),
        ({"s_spread": -1.0}, "s_spread must be non-negative"),
        ({"n_nodes": 0}, "n_nodes must be an integer >= 1"),
        ({"w0": float("inf")}, "w0"),
        ({"estimator": "fast"}, "estimator must be a VelocityEstimator"),
    ],
)
def test_config_refuses_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RBFConfig(**kwargs)


def good_network(nl: int = 3) -> dict:
    return {
        "offset": np.zeros(6),
        "scale": np.ones(6),
        "centres": np.zeros((nl, 6)),
        "widths": np.ones(nl),
        "weights": np.zeros(nl),
    }


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"centres": np.zeros((3, 4))}, r"centres must be shaped \(n, 6\), got \(3, 4\)"),
        ({"widths": np.array([1.0, 0.0, 1.0])}, r"widths b_j must be positive.*b\[1\] = 0"),
        ({"widths": np.ones(2)}, r"widths \(b_j\) must be shaped \(3,\)"),
        ({"scale": np.array([1, 1, 1, 1, 1, -1.0])}, "scale must be positive"),
        ({"offset": np.array([0, 0, np.nan, 0, 0, 0])}, "offset holds NaN"),
        ({"centres": np.full((3, 6), np.nan)}, "centres holds NaN"),
        ({"weights": np.zeros(4)}, r"weights must be shaped \(3,\)"),
    ],
)
def test_network_refuses_bad_arrays(change, match):
    with pytest.raises(ValueError, match=match):
        RBFNetwork(**{**good_network(), **change})


def test_controller_refuses_mismatch_and_missing_derivatives():
    net = RBFNetwork(**good_network(3))
    with pytest.raises(ValueError, match="has 3 nodes but n_nodes = 25"):
        RBFAdaptive(config=RBFConfig(), networks=(net, net), dt=DT)
    with pytest.raises(ValueError, match="two RBFNetwork"):
        RBFAdaptive(config=RBFConfig(n_nodes=3), networks=(net,), dt=DT)
    with pytest.raises(ValueError, match="Nyquist"):
        RBFAdaptive(
            config=RBFConfig(n_nodes=3, estimator=VelocityEstimator(bandwidth_hz=6000.0)),
            networks=(net, net),
            dt=DT,
        )
    ctl = RBFAdaptive(config=RBFConfig(n_nodes=3), networks=(net, net), dt=DT)
    with pytest.raises(ValueError, match="velocity and acceleration"):
        ctl.step(ctl.init(), ReferenceWindow(position=np.zeros((1, 2))), np.zeros(2))
    with pytest.raises(ValueError, match="velocity and acceleration"):
        simulate(stand_in(), ctl, np.zeros((10, 2)))
    _, p, v, a = circle(0.001)
    with pytest.raises(ValueError, match="fewer than n_nodes = 25"):
        RBFAdaptive.for_reference(p, v, a, DT)


# ---------------------------------------------------------------- estimator and rule


def test_velocity_estimator_tracks_a_ramp_and_starts_at_the_first_measurement():
    est = VelocityEstimator()
    phi = est.discrete(DT)
    x = np.zeros(3)
    for k in range(400):
        v, x = est.step(phi, x, 0.3 + 2.0 * k * DT)  # mm, 2 mm/s ramp from 0.3 mm
        if k == 0:
            assert abs(v) < 1e-9  # no spurious velocity from the initial offset
    assert v == pytest.approx(2.0, rel=1e-6)
    # bandwidth: the Tustin poles map back to |s| = ω, damping ζ
    w = 2 * math.pi * est.bandwidth_hz
    z = np.roots([1.0, -(phi[0] + phi[3]), phi[0] * phi[3] - phi[1] * phi[2]]).astype(complex)
    s_poles = 2 / DT * (z - 1) / (z + 1)
    np.testing.assert_allclose(np.abs(s_poles), w, rtol=1e-9)
    np.testing.assert_allclose(-s_poles.real / w, est.damping, rtol=1e-9)


def test_for_reference_rule():
    _, p, v, a = circle(1)
    cfg = RBFConfig(n_nodes=20)
    ctl = RBFAdaptive.for_reference(p, v, a, DT, cfg)
    net = ctl.networks[0]
    idx = np.arange(20) * N_PER // 20
    unscaled = net.centres * net.scale + net.offset
    np.testing.assert_allclose(unscaled[:, 0], p[idx, 0], atol=1e-12)  # along the reference
    np.testing.assert_allclose(unscaled[:, 2], p[idx, 1], atol=1e-12)
    np.testing.assert_allclose(net.centres[:, 4], np.tile([1.0, -1.0], 10))  # ±s_spread
    assert net.scale[0] == pytest.approx(A)
    assert net.scale[4] == pytest.approx(cfg.lam * A + A * 2 * math.pi * F)
    d = np.linalg.norm(np.diff(np.vstack([net.centres, net.centres[:1]]), axis=0), axis=1)
    np.testing.assert_allclose(net.widths, cfg.width_factor * 0.5 * (d + np.roll(d, 1)))


# ---------------------------------------------------------------- kernel == Python


def test_rbf_kernel_equals_python_loop():
    _, p, v, a = circle(0.25)
    rng = np.random.default_rng(1)
    noise = 2e-5 * rng.standard_normal(p.shape)  # 20 nm RMS
    ctl = RBFAdaptive.for_reference(p, v, a, DT, RBFConfig(n_nodes=9, gamma=(0.05,) * 9))
    fast = simulate(stand_in(), ctl, p, noise, derivatives=(v, a))
    slow = simulate_python(stand_in(), ctl, p, noise, derivatives=(v, a))
    assert np.abs(fast.command).max() > 1e-3  # the network is doing something
    np.testing.assert_allclose(fast.command, slow.command, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        fast.final_state.controller, slow.final_state.controller, rtol=1e-12, atol=1e-12
    )
    log = ctl.replay(p, v, a, fast.measured)
    np.testing.assert_allclose(log.command, fast.command, rtol=0, atol=1e-15)
    # the state's s accessor reads what the kernel logged last
    np.testing.assert_array_equal(ctl.error_function(fast.final_state.controller), log.s[-1])


def test_ce_kernel_equals_python_loop_and_tracks():
    _, p, v, a = circle(0.25)
    ce = CertaintyEquivalence(linear_drift_and_gain, EQ9, RBFConfig(), DT)
    assert isinstance(ce, CertaintyEquivalence)
    fast = simulate(stand_in(), ce, p, derivatives=(v, a))
    slow = simulate_python(stand_in(), ce, p, derivatives=(v, a))
    np.testing.assert_allclose(fast.command, slow.command, rtol=0, atol=1e-12)
    # the oracle tracks from the first period: error after the start-up transient, µm
    err = np.abs(fast.output - p)[N_PER // 10 :].max()
    assert err < 5e-4, err


# ---------------------------------------------------------------- tracking on eq. 9


def test_rbf_learns_the_circle_and_beats_a_proportional_controller(circle_run):
    _, p, _, _, res = circle_run
    rms = rms_per_period(res.output - p)
    assert rms[-1] < 0.5 * rms[0]  # the error falls
    assert rms[-1] < 1.5e-3, rms  # µm level after adaptation (0.81 µm measured)
    k_p = 0.05  # V/mm: a naive P gain, near the largest that leaves the resonance damped
    p_ctl = LTIController(
        DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), k_p * np.eye(2), DT)
    )
    rms_p = rms_per_period(simulate(stand_in(), p_ctl, p).output - p)
    assert rms[-1] < rms_p[-1] / 20, (rms[-1], rms_p[-1])


# ---------------------------------------------------------------- eqs. 7-8 and A6


def true_state_run(ctl, n_periods: float):
    """Closed loop kept by hand so that the plant's true (x1, x2) are known at every sample."""
    _, p, v, a = circle(n_periods)
    plant = stand_in()
    px, cx = plant.init(), ctl.init()
    R = np.stack([p, v, a], axis=1)
    (kernel,) = ctl.kernels()
    n = p.shape[0]
    states = np.empty((n + 1, 4))
    u = np.empty((n, 2))
    for k in range(n):
        states[k] = px[:4]
        kernel(ctl.params, cx, R, k, plant.output(px), u[k])
        px = plant.update(px, u[k])
    states[n] = px[:4]
    return p, v, a, states, u


def test_eq8_holds_along_an_rbf_run():
    ctl = RBFAdaptive.for_reference(*circle(1)[1:], DT)
    p, _v, _a, X, u = true_state_run(ctl, 0.5)
    cfg = ctl.config
    n = p.shape[0]
    t = np.arange(n + 1) * DT
    w = 2 * math.pi * F
    # the analytic reference at the n + 1 sample instants
    r = np.column_stack([A * np.sin(w * t), A * (1 - np.cos(w * t))])
    rd = np.column_stack([A * w * np.cos(w * t), A * w * np.sin(w * t)])
    rdd = np.column_stack([-A * w * w * np.sin(w * t), A * w * w * np.cos(w * t)])
    for ax in range(2):
        x1, x2 = X[:, 2 * ax], X[:, 2 * ax + 1]
        s = cfg.lam * (x1 - r[:, ax]) + (x2 - rd[:, ax])
        vv = cfg.lam * (x2 - rd[:, ax]) - rdd[:, ax]
        alpha = np.array([linear_drift_and_gain(EQ9, ax, xk)[0] for xk in X])
        beta = np.full(n + 1, EQ9[3 * ax + 2])
        u_star = ce_law(alpha, beta, 0.0, s, vv, cfg.eps)
        # eq. 8 at both ends of each sample, with the command held over it (ZOH)
        rhs0 = eq8_rhs(beta[:-1], 0.0, u[:, ax], u_star[:-1], s[:-1], cfg.eps)
        rhs1 = eq8_rhs(beta[1:], 0.0, u[:, ax], u_star[1:], s[1:], cfg.eps)
        sdot = np.diff(s) / DT
        resid = sdot - 0.5 * (rhs0 + rhs1)
        scale = np.abs(sdot).max()
        assert scale > 1.0  # mm/s²: s moves
        # trapezoid error ~ (ω_n dt)² / 12 ≈ 8.5e-5 of the scale (ω_n of eq. 9: 319 rad/s)
        assert np.abs(resid).max() < 3e-4 * scale, np.abs(resid).max() / scale
        # and the identity is not empty: a wrong sign in eq. 6 breaks it
        bad = eq8_rhs(beta[:-1], 0.0, u[:, ax], -u_star[:-1], s[:-1], cfg.eps)
        assert np.abs(sdot - bad).max() > 100 * np.abs(resid).max()


def test_s_stays_under_the_a6_bound(circle_run):
    ctl, p, v, a, res = circle_run
    log = ctl.replay(p, v, a, res.measured, hidden=True)
    ce = CertaintyEquivalence(linear_drift_and_gain, EQ9, ctl.config, DT)
    oracle = ce.replay(p, v, a, res.measured)
    np.testing.assert_allclose(oracle["s"], log.s, rtol=0, atol=1e-12)  # same s, same filter
    t = np.arange(p.shape[0]) * DT
    cfg = ctl.config
    for ax in range(2):
        H = log.hidden[:, ax]
        w_star = fit_ideal_weights(H, oracle["u_star"][:, ax])
        mu = oracle["u_star"][:, ax] - H @ w_star  # eq. 7: μ_l = u* − W*ᵀh
        beta0 = EQ9[3 * ax + 2]
        gamma = cfg.gamma_diagonal()
        v0 = lyapunov_v(log.s[0, ax], beta0, ctl.networks[ax].weights - w_star, gamma)
        bound = a6_bound(
            t,
            mu0=float(np.abs(mu).max()),
            d0=0.0,
            beta0=beta0,
            eps=cfg.eps,
            sigma=cfg.sigma,
            gamma_bar=float(1.0 / gamma.min()),
            w_star_norm=float(np.linalg.norm(w_star)),
            v0=v0,
        )
        assert np.all(np.abs(log.s[:, ax]) <= bound)


def test_a6_bound_formula_and_refusals():
    b = a6_bound(
        np.array([0.0, 1.0]),
        mu0=0.1, d0=2.0, beta0=3.0, eps=0.5, sigma=0.25, gamma_bar=1.0, w_star_norm=2.0, v0=1.5,
    )  # fmt: skip
    a0 = max(0.5, 1.0 / 0.25)
    steady = math.sqrt(a0 * 3.0 * (0.5 * 0.01 * 3.0 + 0.25 * 4.0 + 0.25 * 4.0))
    assert b[0] == pytest.approx(math.sqrt(2 * 3.0 * 1.5) + steady)
    assert b[1] == pytest.approx(math.exp(-1 / (2 * a0)) * math.sqrt(9.0) + steady)
    with pytest.raises(ValueError, match="sigma must be positive"):
        a6_bound(0.0, mu0=0, d0=0, beta0=1, eps=1, sigma=0, gamma_bar=1, w_star_norm=0, v0=0)
    with pytest.raises(ValueError, match="drift_and_gain must be a numba"):
        CertaintyEquivalence(lambda p, a, x: (0.0, 1.0), EQ9, RBFConfig(), DT)
