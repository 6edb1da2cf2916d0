"""The galvo MSL machine of seed 000: its surface (limits, twin, play)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation
from microfab.machines.galvo import machine as galvo
from microfab.trajectory.periodic import square_scan


def test_limits_are_a_copy_of_the_declared_ones():
    lim = galvo.limits()
    assert lim == galvo.GALVO_LIMITS and lim is not galvo.GALVO_LIMITS
    assert lim["x"].position == 10.0 and lim["y"].unit == "V"


def test_play_is_one_run_of_a_fresh_twin():
    axes = galvo.calibrated_axes()
    ref = square_scan(400, (axes["x"].amplitude_v, axes["y"].amplitude_v), axes["x"].fs_hz)
    got = galvo.play(ref, seed=3)
    want = galvo.twin(axes, seed=3).run(ref)
    np.testing.assert_array_equal(got.output, want.output)
    assert got.output.shape == ref.shape
    # a fresh twin each time: the same noise again
    np.testing.assert_array_equal(galvo.play(ref, seed=3).output, got.output)


def test_play_refuses_a_command_beyond_the_limits():
    with pytest.raises(LimitViolation):
        galvo.play(np.full((2500, 2), 11.0))
