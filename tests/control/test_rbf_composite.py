"""RBFPlusLinear: a linear controller plus the seed 001 network."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from microfab.control.base import ReferenceWindow
from microfab.control.pid import PID
from microfab.control.rbf import RBFAdaptive, RBFConfig
from microfab.control.rbf_composite import NonlinearityOracle, RBFPlusLinear
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.plants.nanomanipulator import drift_and_gain


def _setup() -> tuple[PID, RBFAdaptive, np.ndarray, np.ndarray, np.ndarray]:
    plant = nanomanipulator.twin()
    dt = plant.dt
    t = np.arange(4000) * dt
    w = 2 * np.pi * 5.0
    pos = 0.01 * np.column_stack([np.sin(w * t), np.cos(w * t)])
    vel = 0.01 * w * np.column_stack([np.cos(w * t), -np.sin(w * t)])
    acc = -(w**2) * pos
    pid = PID.tuned(plant.continuous_models(), bandwidth_hz=200.0, dt=dt)
    cfg = RBFConfig(n_nodes=9, s_spread=0.0, gamma=0.3)
    rbf = RBFAdaptive.for_reference(pos[:2000], vel[:2000], acc[:2000], dt, cfg)
    return pid, rbf, pos, vel, acc


def test_with_frozen_zero_weights_it_is_the_linear_controller() -> None:
    pid, rbf, pos, vel, acc = _setup()
    frozen = RBFAdaptive(
        config=dataclasses.replace(rbf.config, gamma=1e-30), networks=rbf.networks, dt=rbf.dt
    )
    a = nanomanipulator.play(pid, pos, derivatives=(vel, acc))
    b = nanomanipulator.play(RBFPlusLinear(pid, frozen), pos, derivatives=(vel, acc))
    np.testing.assert_allclose(b.command, a.command, rtol=0, atol=1e-12)


def test_kernel_matches_the_python_step_and_adds_both_parts() -> None:
    pid, rbf, pos, vel, acc = _setup()
    c = RBFPlusLinear(pid, rbf)
    res = nanomanipulator.play(c, pos, derivatives=(vel, acc))
    x = c.init()
    xp, xr = pid.init(), rbf.init()
    for k in range(300):
        win = ReferenceWindow(position=pos[k : k + 1], velocity=vel[k : k + 1],
                              acceleration=acc[k : k + 1])  # fmt: skip
        u, x = c.step(x, win, res.measured[k])
        up, xp = pid.step(xp, win, res.measured[k])
        ur, xr = rbf.step(xr, win, res.measured[k])
        np.testing.assert_allclose(u, res.command[k], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(u, up + ur, rtol=1e-12, atol=1e-15)
    assert np.any(np.abs(rbf.weights(c.rbf_state(x))) > 0)  # the network adapted


def test_refuses_what_it_cannot_combine() -> None:
    pid, rbf, *_ = _setup()
    with pytest.raises(TypeError, match="RBFAdaptive"):
        RBFPlusLinear(pid, pid)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="CompiledController"):
        RBFPlusLinear(object(), rbf)  # type: ignore[arg-type]


def _oracle(pid: PID, nonlinear: bool) -> NonlinearityOracle:
    true = nanomanipulator.twin(nonlinear=nonlinear)
    lin = nanomanipulator.twin(nonlinear=False)
    return NonlinearityOracle(
        pid, drift_and_gain, true.params, lin.params, RBFConfig().estimator, true.dt
    )


def test_oracle_on_the_linear_model_is_the_linear_controller() -> None:
    pid, _, pos, vel, acc = _setup()
    a = nanomanipulator.play(pid, pos, derivatives=(vel, acc), nonlinear=False)
    b = nanomanipulator.play(_oracle(pid, False), pos, derivatives=(vel, acc), nonlinear=False)
    np.testing.assert_allclose(b.command, a.command, rtol=1e-12, atol=1e-15)


def test_oracle_kernel_matches_its_python_step_and_cancels_the_nonlinearity() -> None:
    pid, _, pos, vel, acc = _setup()
    pos = pos + 0.25  # off-centre, where the §4.1 terms act
    orc = _oracle(pid, True)
    res = nanomanipulator.play(orc, pos, derivatives=(vel, acc))
    x = orc.init()
    for k in range(200):
        win = ReferenceWindow(position=pos[k : k + 1], velocity=vel[k : k + 1],
                              acceleration=acc[k : k + 1])  # fmt: skip
        u, x = orc.step(x, win, res.measured[k])
        np.testing.assert_allclose(u, res.command[k], rtol=1e-9, atol=1e-12)
    lin = nanomanipulator.play(pid, pos, derivatives=(vel, acc), nonlinear=False)
    plain = nanomanipulator.play(pid, pos, derivatives=(vel, acc))
    err = {
        name: float(np.sqrt(np.mean((pos - r.output)[2000:] ** 2)))
        for name, r in (("oracle", res), ("linear twin", lin), ("plain", plain))
    }
    assert abs(err["oracle"] - err["linear twin"]) < 0.1 * err["linear twin"], err
    assert abs(err["plain"] - err["oracle"]) > 0.3 * err["oracle"], err  # the terms matter here
