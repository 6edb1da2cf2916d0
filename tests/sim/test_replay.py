"""Open-loop replays of compiled components: plants over commands, controllers over measurements."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.base import LTIController
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI
from microfab.sim.loop import simulate
from microfab.sim.replay import replay_controller, replay_plant

DT = 1e-3


def _plant() -> LTIPlant:
    return LTIPlant(DiscreteLTI([[0.9, 0.05], [-0.2, 0.8]], [[0.0], [0.1]], [[1.0, 0.0]],
                                [[0.0]], DT))  # fmt: skip


def test_replay_plant_gives_the_state_after_each_command():
    plant = _plant()
    u = np.random.default_rng(0).standard_normal((50, 1))
    states = replay_plant(plant, u)
    x = np.zeros(2)
    A, B = plant.sys.A, plant.sys.B
    for k in range(50):
        x = A @ x + B @ u[k]
        np.testing.assert_allclose(states[k, :2], x, rtol=1e-14, atol=1e-15)
    with pytest.raises(ValueError, match=r"shaped \(n, 1\)"):
        replay_plant(plant, np.zeros((5, 2)))
    with pytest.raises(TypeError, match="compiled plant"):
        replay_plant(object(), u)  # type: ignore[arg-type]


def test_replays_reproduce_a_closed_loop_run():
    plant = _plant()
    ctrl = LTIController(  # integral action on the error: x+ = x + e, u = 0.05 x + 0.5 e
        DiscreteLTI([[1.0]], [[1.0]], [[0.05]], [[0.5]], DT)
    )
    ref = np.sin(np.arange(300) * 0.05)[:, None]
    run = simulate(plant, ctrl, ref)
    u, _ = replay_controller(ctrl, ref, run.measured)
    np.testing.assert_array_equal(u, run.command)
    states = replay_plant(plant, run.command)
    np.testing.assert_array_equal(states[-1], run.final_state.plant)
