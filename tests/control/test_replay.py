"""The one replay loop (`replay_steps`) against the per-controller loops it replaced.

Each reference below is the loop a controller's ``replay`` ran before: its step kernel
called sample by sample, the same state read out after each step. The replays must equal
them bit for bit on a recorded closed-loop run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

import control
from microfab.control import certainty as ce_mod
from microfab.control.certainty import CertaintyEquivalence
from microfab.control.preview_dob import PreviewDOB, PreviewDOBConfig, preview_dob_step
from microfab.control.preview_dob_model import _HEAD, _NB, _NS, _S_DHAT, _S_V
from microfab.control.rbf import RBFAdaptive, RBFConfig, rbf_step
from microfab.control.rbf_network import N_AXES, N_Z, _stack_reference
from microfab.control.replay import no_record, replay_steps
from microfab.control.velocity import N_ESTIMATOR_STATES
from microfab.plants.base import LTIPlant
from microfab.plants.lti import block_diag, discretize
from microfab.sim.loop import reference_array, simulate

DT = 1e-4  # s, 10 kHz
EQ9 = np.array([101793.23, 14.88, 548248.13, 99664.23, 18.52, 319852.42])  # seed 001 eq. (9)


@njit(cache=True)
def _count_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """A test kernel: ``u = p0 ym + ref[k]``, the state counts the samples."""
    u[0] = p[0] * ym[0] + ref[k, 0]
    x[0] += 1.0


@njit(cache=True)
def _count_record(p: np.ndarray, x: np.ndarray, row: np.ndarray) -> None:
    """A test record: the count and twice it."""
    row[0] = x[0]
    row[1] = 2.0 * x[0]


@njit(cache=True)
def _linear_drift(p: np.ndarray, axis: int, x: np.ndarray) -> tuple[float, float]:
    """Eq. 9 as eq. 1: alpha = -a0 x1 - a1 x2, beta = K."""
    o = 3 * axis
    return -p[o] * x[2 * axis] - p[o + 1] * x[2 * axis + 1], p[o + 2]


def test_record_sees_the_state_after_each_step():
    ym = np.arange(5.0)[:, None]
    ref = np.full((5, 1), 0.5)
    x = np.array([10.0])
    u, log = replay_steps(_count_step, np.array([2.0]), x, ref, ym, 1, _count_record, 2)
    np.testing.assert_array_equal(u[:, 0], 2.0 * np.arange(5.0) + 0.5)
    np.testing.assert_array_equal(
        log, np.column_stack([11.0 + np.arange(5), 22.0 + 2 * np.arange(5)])
    )
    assert x[0] == 15.0  # the state is advanced in place
    u0, log0 = replay_steps(_count_step, np.array([2.0]), np.zeros(1), ref, ym, 1)
    assert log0.shape == (5, 0)
    np.testing.assert_array_equal(u0, u)
    assert no_record.__name__ == "no_record"


def _circle(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed 001 §4.2's 0.15 mm circle at 1 Hz through the origin: p, v, a (mm), (n, 2)."""
    t = np.arange(n) * DT
    w, A = 2 * math.pi, 0.075
    p = np.column_stack([A * np.sin(w * t), A * (1 - np.cos(w * t))])
    v = np.column_stack([A * w * np.cos(w * t), A * w * np.sin(w * t)])
    a = np.column_stack([-A * w * w * np.sin(w * t), A * w * w * np.cos(w * t)])
    return p, v, a


def _eq9_plant() -> LTIPlant:
    axes = [
        discretize(control.ss([[0.0, 1.0], [-a0, -a1]], [[0.0], [k]], [[1.0, 0.0]], [[0.0]]), DT)
        for a0, a1, k in (EQ9[:3], EQ9[3:])
    ]
    return LTIPlant(block_diag(*axes))


@pytest.fixture(scope="module")
def rbf_run():
    p, v, a = _circle(2500)
    ctl = RBFAdaptive.for_reference(p, v, a, DT, RBFConfig(n_nodes=9, gamma=(0.05,) * 9))
    noise = 2e-5 * np.random.default_rng(1).standard_normal(p.shape)
    res = simulate(_eq9_plant(), ctl, p, noise, derivatives=(v, a))
    return ctl, p, v, a, res


def test_rbf_replay_equals_its_former_loop(rbf_run):
    ctl, p, v, a, res = rbf_run
    log = ctl.replay(p, v, a, res.measured, hidden=True)
    # the former loop: ‖Ŵ‖ before each step, then the step, then s, v and h from the state
    n, nl = p.shape[0], ctl.n_nodes
    R = _stack_reference(p, v, a, n)
    x = ctl.init()
    u, s, vv, wn = (np.empty((n, N_AXES)) for _ in range(4))
    H = np.empty((n, N_AXES, nl))
    ih = N_AXES * nl + N_AXES * N_ESTIMATOR_STATES
    isv = ih + N_AXES * nl + N_Z
    for k in range(n):
        for ax in range(N_AXES):
            acc = 0.0
            for j in range(nl):
                acc += x[ax * nl + j] * x[ax * nl + j]
            wn[k, ax] = math.sqrt(acc)
        rbf_step(ctl.params, x, R, k, res.measured[k], u[k])
        s[k], vv[k] = x[isv : isv + N_AXES], x[isv + N_AXES : isv + 2 * N_AXES]
        H[k] = x[ih : ih + N_AXES * nl].reshape(N_AXES, nl)
    np.testing.assert_array_equal(u, res.command)  # and both reproduce the run
    for got, want in ((log.command, u), (log.s, s), (log.v, vv), (log.weight_norm, wn),
                      (log.hidden, H), (log.final_state, x)):  # fmt: skip
        np.testing.assert_array_equal(got, want)
    assert np.abs(wn[-1]).min() > 0  # the weights moved: the norms are not all zeros
    np.testing.assert_array_equal(ctl.replay(p, v, a, res.measured).command, u)


def test_certainty_replay_equals_its_former_loop(rbf_run):
    _ctl, p, v, a, res = rbf_run
    ce = CertaintyEquivalence(_linear_drift, EQ9, RBFConfig(), DT)
    out = ce.replay(p, v, a, res.measured)
    n = p.shape[0]
    R = _stack_reference(p, v, a, n)
    x = ce.init()
    (kernel,) = ce.kernels()
    u = np.empty((n, 2))
    logs = np.empty((n, 10))
    for k in range(n):
        kernel(ce.params, x, R, k, res.measured[k], u[k])
        logs[k] = x[ce_mod._ILOG : ce_mod._ILOG + 10]
    np.testing.assert_array_equal(out["u_star"], u)
    for i, name in enumerate(("s", "v", "alpha", "beta", "beta_dot")):
        np.testing.assert_array_equal(out[name], logs[:, 2 * i : 2 * i + 2])
    assert np.abs(out["alpha"]).max() > 0


def test_preview_dob_replay_equals_its_former_loop():
    cfg = PreviewDOBConfig(mass_kg=(1.2, 0.6), force_constant_n_per_a=(10.0, 8.0))
    ctrl = PreviewDOB(cfg)
    axes = []
    for m, kf in ((1.2, 10.0), (0.6, 8.0)):
        A = [[0, 1, 0, 0], [0, 0, kf / m, -1 / m], [0, 0, -1 / 20e-6, 0], [0, 0, 0, 0]]
        B = [[0], [0], [1 / 20e-6], [0]]
        axes.append(discretize(control.ss(A, B, [[1, 0, 0, 0]], [[0]]), DT, "zoh"))
    n = 2000
    t = np.arange(n) * DT
    w, r = 100.0, 100e-6  # 100 µm circle at 10 mm/s
    pos = r * np.column_stack([np.cos(w * t) - 1.0, np.sin(w * t)])
    vel = r * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    acc = -(w**2) * r * np.column_stack([np.cos(w * t), np.sin(w * t)])
    res = simulate(LTIPlant(block_diag(*axes)), ctrl, pos, derivatives=(vel, acc))
    R = reference_array(pos, (vel, acc))
    log = ctrl.replay(R, res.measured)
    x = ctrl.init()
    u, d, vv = (np.empty((n, 2)) for _ in range(3))
    for k in range(n):
        preview_dob_step(ctrl.params, x, R, k, res.measured[k], u[k])
        for ax in range(2):
            d[k, ax] = ctrl.params[_HEAD + ax * _NB + 1] * x[ax * _NS + _S_DHAT]
            vv[k, ax] = x[ax * _NS + _S_V]
    np.testing.assert_array_equal(u, res.command)
    for got, want in ((log.command, u), (log.disturbance, d), (log.velocity, vv),
                      (log.final_state, x)):  # fmt: skip
        np.testing.assert_array_equal(got, want)
    assert np.abs(vv).max() > 1e-3  # m/s: the estimate follows the circle
