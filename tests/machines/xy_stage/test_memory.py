"""The XY stage twin forgets within seed 002's 500 ms window (issue 34, item 0)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.identify.excitation import random_runs
from microfab.identify.excitation_random import RandomDesign
from microfab.machines.xy_stage.machine import Command
from microfab.machines.xy_stage.memory import history_spread


@pytest.fixture(scope="module")
def runs():
    return random_runs(24.0, seed=7, design=RandomDesign(run_s=(4.0, 4.0)))


def test_the_500_ms_window_holds_all_the_twins_memory(runs) -> None:
    spread = history_spread(runs[0], runs[1:])
    assert spread.at(0.0).max() > 1e-6  # the histories do differ where the segment starts
    assert spread.after(0.5).max() < 1e-8  # 10 nm: nothing of them is left after 500 ms
    assert spread.time_s.shape[0] == runs[0].command.shape[0]


def test_joins_that_jump_and_too_few_histories_are_refused(runs) -> None:
    moved = Command(name="moved", dt=runs[1].dt, command=runs[1].command + 1e-3)
    with pytest.raises(ValueError, match="would jump"):
        history_spread(runs[0], [runs[1], moved])
    with pytest.raises(ValueError, match="at least two"):
        history_spread(runs[0], [runs[1]])
    other = Command(name="other", dt=2e-4, command=np.zeros((10, 2)))
    with pytest.raises(ValueError, match="dt"):
        history_spread(runs[0], [runs[1], other])
    with pytest.raises(ValueError, match="outside"):
        history_spread(runs[0], runs[1:3]).at(99.0)
