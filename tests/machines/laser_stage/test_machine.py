"""The laser stage's machine surface: twins built once, plays that the runs and studies share."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import LimitViolation
from microfab.machines.laser_stage import machine as laser_stage
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings, TwinSettings
from microfab.trajectory.contour_laps import ContourMotion, contour_path, contour_reference

_JOB = ContourJob(motion=ContourMotion(laps=1), twin=TwinSettings(nonlinear=False))


def test_twin_and_limits():
    assert laser_stage.twin(TwinSettings()) is laser_stage.twin(TwinSettings(seed=3))
    assert laser_stage.twin(TwinSettings(nonlinear=False)) is not laser_stage.twin()
    assert laser_stage.limits().velocity == (0.1, 0.1)  # seed 004 Table I


def test_play_contour_is_play_of_the_jobs_reference():
    p = laser_stage.play_contour(_JOB)
    ref = contour_reference(contour_path(_JOB.drawing), _JOB.motion)
    tr = laser_stage.play(ref.trajectory, _JOB.control, _JOB.twin)
    np.testing.assert_array_equal(tr.command, p.trace.command)
    np.testing.assert_array_equal(tr.output, p.trace.output)
    n = ref.trajectory.position.shape[0]
    assert p.trace.measured.shape == (n, 2) and p.trace.dt == pytest.approx(1e-4)
    full = p.full_laps
    assert full.stop - full.start == ref.lap_samples
    # the true position follows the reference to well under a micrometre
    assert np.max(np.abs(p.trace.output[full] - ref.trajectory.position[full])) < 1e-6


def test_play_contour_refuses_a_reference_beyond_the_stage():
    fast = _JOB.with_(drawing="circle:radius=5e-3", motion=ContourMotion(speed_m_s=0.2, laps=1))
    with pytest.raises(LimitViolation, match="velocity"):
        laser_stage.play_contour(fast)
    with pytest.raises(ValueError, match="sample rate"):
        laser_stage.play_contour(_JOB.with_(motion=ContourMotion(laps=1, sample_rate_hz=5e3)))


def test_controller_laws():
    stage = laser_stage.twin()
    names = {law: type(laser_stage.controller(ControlSettings(law=law), stage)).__name__
             for law in laser_stage.LAWS}  # fmt: skip
    assert names["contour"] == "ContourCompensator" and names["cross-coupled"] == "CrossCoupled"
    assert names["pd"] == names["preview"] == "PreviewDOB"


def test_the_paper_model_is_eq_2_with_the_table_one_mass_and_no_disturbance():
    """`TwinSettings.paper_model`: M = M_n = 0.6 kg on both axes (seed 004 Table I), K_f =
    K_fn, no friction, cogging, cable or saturation; the 10 nm encoder only when
    ``nonlinear`` is on."""
    p = laser_stage.twin(TwinSettings(paper_model=True))
    c = p.config
    assert c.mass_kg == c.nominal_mass_kg == (laser_stage.PAPER_MASS_KG,) * 2
    assert c.force_constant_n_per_a == c.nominal_force_constant_n_per_a
    assert c.quantisation and not (c.friction or c.cogging or c.cable or c.saturation)
    assert not laser_stage.twin(TwinSettings(paper_model=True, nonlinear=False)).config.quantisation
