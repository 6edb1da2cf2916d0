"""The nanomanipulator machine module: the cached twin and play."""

from __future__ import annotations

import numpy as np

from microfab.control.pid import PID
from microfab.machines.nanomanipulator import machine as nanomanipulator
from microfab.sim.loop import simulate


def test_play_is_the_loop_on_the_cached_twin() -> None:
    plant = nanomanipulator.twin(seed=3)
    assert nanomanipulator.twin(seed=3) is plant
    pid = PID.tuned(plant.continuous_models(), bandwidth_hz=200.0, dt=plant.dt)
    t = np.arange(2000) * plant.dt
    ref = np.column_stack([0.01 * np.sin(2 * np.pi * 5 * t), 0.01 * np.cos(2 * np.pi * 5 * t)])
    for noise in (False, True):
        got = nanomanipulator.play(pid, ref, seed=3, noise=noise)
        v = plant.noise(ref.shape[0], 3) if noise else np.zeros_like(ref)
        want = simulate(plant, pid, ref, v)
        np.testing.assert_array_equal(got.output, want.output)
        np.testing.assert_array_equal(got.measured, want.measured)
    assert not np.array_equal(got.measured, got.output)  # the sensor noise, on
