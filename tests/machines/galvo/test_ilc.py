"""The galvo ILC learning run: resume (bit-identical), refusals (seed 000 on the twin)."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.machines.galvo.ilc import run_msl_ilc


# ---------------------------------------------------------------------- resuming
def test_resume_continues_to_more_iterations(tmp_path):
    first = run_msl_ilc(400, 10, state_dir=tmp_path)
    assert first.rms_history.shape == (10, 2)
    second = run_msl_ilc(400, 20, state_dir=tmp_path)
    assert second.rms_history.shape == (20, 2)
    np.testing.assert_array_equal(second.rms_history[:10], first.rms_history)
    np.testing.assert_array_equal(second.fb_output, first.fb_output)
    # learning went on: the continued run's error stays at the learned level
    assert np.all(second.rms_history[10:] < 0.2 * second.rms_history[0])
    # asking for no more than is done returns the stored state without running
    again = run_msl_ilc(400, 20, state_dir=tmp_path)
    np.testing.assert_array_equal(again.rms_history, second.rms_history)
    np.testing.assert_array_equal(again.ilc_output, second.ilc_output)
    np.testing.assert_array_equal(again.ilc_input, second.ilc_input)


def test_resumed_run_is_bit_identical_to_an_uninterrupted_one(tmp_path):
    """The twin's loop state and noise generator are saved with the learner's state."""
    whole = run_msl_ilc(400, 12)
    run_msl_ilc(400, 5, state_dir=tmp_path)  # interrupted after 5 trials...
    resumed = run_msl_ilc(400, 12, state_dir=tmp_path)  # ...and resumed on a new twin
    np.testing.assert_array_equal(resumed.rms_history, whole.rms_history)
    np.testing.assert_array_equal(resumed.ilc_output, whole.ilc_output)
    np.testing.assert_array_equal(resumed.ilc_input, whole.ilc_input)


def test_resume_refuses_other_reference(tmp_path):
    run_msl_ilc(400, 2, state_dir=tmp_path)
    with pytest.raises(ValueError, match="another reference"):
        run_msl_ilc(200, 4, state_dir=tmp_path)


def test_iterations_validation():
    with pytest.raises(ValueError, match="iterations"):
        run_msl_ilc(400, 1)
