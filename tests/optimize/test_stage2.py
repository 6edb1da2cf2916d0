"""Stage 2 (seed 002 eqs. 13-14): Gauss-Newton on the networks, monotone, resumable."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("casadi")
pytest.importorskip("torch")

from microfab.core.limits import MachineLimits
from microfab.optimize.pipeline import optimize_reference
from microfab.optimize.stage1 import Stage1Settings
from microfab.optimize.stage2 import Stage2Settings, solve_stage2


def run(case, **kw):
    models, problem, target, r_init = case
    settings = kw.pop("settings", Stage2Settings(max_iter=4))
    return solve_stage2(target, r_init, models.networks, rest=problem.path.start,
                        tolerance_m=problem.tolerance_m, v_max=problem.v_max,
                        a_max=problem.a_max, limits=problem.limits, settings=settings,
                        **kw)  # fmt: skip


def test_stage2_never_raises_the_merit_and_lowers_the_cost(case):
    res = run(case)
    hist = np.array(res.cost_history)
    assert np.all(np.diff(hist) <= 0)
    assert hist[-1] < hist[0]
    assert res.cost_end < res.cost_start
    assert res.r.shape == case[2].shape and res.phi.shape == case[2].shape
    assert res.phi_tail.shape == (200, 2)


def test_stage2_input_is_a_valid_command(case):
    from microfab.optimize.command import checked_command

    res = run(case)
    traj = checked_command(res.r, rest=case[1].path.start, limits=MachineLimits.seed002_stage())
    assert traj.position.shape[1] == 2


def test_checkpoint_resumes_to_the_same_result(case, tmp_path):
    ck = str(tmp_path / "s2.npz")
    full = run(case, settings=Stage2Settings(max_iter=4))
    first = run(case, settings=Stage2Settings(max_iter=2), checkpoint=ck)
    assert first.iterations == 2
    second = run(case, settings=Stage2Settings(max_iter=4), checkpoint=ck)
    assert second.resumed_from == 2
    assert np.allclose(second.r, full.r, atol=1e-12)
    assert second.cost_history == pytest.approx(full.cost_history)
    del first


def test_checkpoint_of_other_inputs_refused(case, tmp_path):
    ck = str(tmp_path / "s2.npz")
    run(case, settings=Stage2Settings(max_iter=1), checkpoint=ck)
    with pytest.raises(ValueError, match=r"stage-2 iterate of other settings: penalty \S+ -> 500"):
        run(case, settings=Stage2Settings(max_iter=1, penalty=500.0), checkpoint=ck)
    data = (tmp_path / "s2.npz").read_bytes()
    (tmp_path / "s2.npz").write_bytes(data[: len(data) // 2])  # cut short by a full disk
    with pytest.raises(ValueError, match="not a readable stage-2 iterate file"):
        run(case, settings=Stage2Settings(max_iter=1), checkpoint=ck)


def test_axis_norm_runs(case):
    res = run(case, settings=Stage2Settings(max_iter=2, norm="axis"))
    assert res.cost_history[-1] <= res.cost_history[0]


def test_pipeline_stage_one_only_needs_no_networks(case):
    models, problem, _, _ = case
    res = optimize_reference(problem, models.linear, None, stage="1",
                             stage1=Stage1Settings(n=80))  # fmt: skip
    assert res.stage2 is None and res.predicted is None
    assert res.command.position.shape[0] == 25 * (res.m + 3) + 1
    with pytest.raises(ValueError, match="needs the networks"):
        optimize_reference(problem, models.linear, None)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"norm": "l2"}, "norm must be"),
        ({"penalty": 0.0}, "penalty"),
        ({"max_iter": 0}, "max_iter"),
        ({"trust_um": -1.0}, "trust_um"),
        ({"tol": -1.0}, "tol"),
    ],
)
def test_settings_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        Stage2Settings(**kw)


def test_a_max_beyond_the_training_data_is_a_warning(tiny_models):
    from microfab.optimize.pipeline import training_warning

    _, model = tiny_models
    seen = max(model.info["command_accel_max_m_s2"].values())
    assert training_warning(model, 0.5 * seen) is None
    assert "beyond the networks' training data" in training_warning(model, 2 * seen)
