"""Stage 1 alone through `optimize_reference`: the check against the stretched command.

Eq. (12) leaves the end of stage 1 free: on a closed contour its input ends moving, and
the command must come to rest into the held end, which moves the output's end. The
pipeline runs both that command and the time-optimal command stretched to the same T on
the linear model and falls back to the stretched one when stage 1's is predicted worse
(issue 34 item 6). Models, per axis ``(d s² + wz s + wn²) / (s² + 2ζ wn s + wn²)``:

* ``SLOW``: x 70 rad/s ζ 0.5 wz 40, y 60 rad/s ζ 0.6 wz 30, d = 0.9 (as
  tests/optimize/test_stage1.py): a lagging stage, on which the stretched command is far
  worse (stage 1's compensation pays) and nothing falls back;
* ``TIGHT``: x 300 rad/s, y 270 rad/s, ζ 0.7, wz = 0.9 · 2ζ wn, d = 0.9: a stage that
  follows its set-point closely, like the twin (its fitted D ≈ 0.96), on which the end
  stage 1 leaves moving is the largest error and the stretched command is returned.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

pytest.importorskip("casadi")

from microfab.geometry.shapes import circle
from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.pipeline import linear_output, optimize_reference
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Settings


def _axis(wn: float, zeta: float, wz: float, d: float) -> tuple[np.ndarray, ...]:
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    c = np.array([[wn**2 - d * wn**2, wz - d * 2 * zeta * wn]])
    return a, np.array([[0.0], [1.0]]), c


def _model(x: tuple[float, ...], y: tuple[float, ...]) -> ContinuousModel:
    (ax, bx, cx), (ay, by, cy) = _axis(*x), _axis(*y)
    z2, z1 = np.zeros((2, 2)), np.zeros((2, 1))
    return ContinuousModel(
        a=np.block([[ax, z2], [z2, ay]]),
        b=np.block([[bx, z1], [z1, by]]),
        c=np.block([[cx, np.zeros((1, 2))], [np.zeros((1, 2)), cy]]),
        d=np.diag([x[3], y[3]]),
    )


SLOW = _model((70.0, 0.5, 40.0, 0.9), (60.0, 0.6, 30.0, 0.9))
TIGHT = _model((300.0, 0.7, 0.9 * 420.0, 0.9), (270.0, 0.7, 0.9 * 378.0, 0.9))


def test_linear_output_is_the_zoh_sampled_model_from_rest():
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.standard_normal((3000, 2)), axis=0) * 1e-5 + [0.01, -0.02]
    y = linear_output(SLOW, u)
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete((SLOW.a, SLOW.b, SLOW.c, SLOW.d), 1e-4)
    x = -np.linalg.solve(SLOW.a, SLOW.b @ u[0])
    ref = np.empty_like(u)
    for k in range(u.shape[0]):
        ref[k] = cd @ x + dd @ u[k]
        x = ad @ x + bd @ u[k]
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(y[0], u[0], atol=1e-12)  # unit static gain: at rest on u0


@pytest.fixture(scope="module")
def runs():
    problem = ContourProblem(circle(0.01), a_max=1.0, tolerance_m=20e-6)
    settings = Stage1Settings(n=80)
    kept = optimize_reference(problem, TIGHT, stage="1", stage1=settings, fallback=False)
    fell = optimize_reference(problem, TIGHT, stage="1", stage1=kept.stage1)
    return problem, kept, fell


def _predicted(problem, res, model) -> DeviationNorms:
    from microfab.optimize.command import LEAD

    q = 25  # 10 kHz / 400 Hz
    pos = np.asarray(res.command.position)
    pos = np.vstack([pos, np.repeat(pos[-1:], (res.m + LEAD + 1) * q, axis=0)])
    y = linear_output(model, pos)[(np.arange(1, res.m + 1) + LEAD) * q]
    return DeviationNorms.of(problem.path, y)


def test_stage1_alone_falls_back_when_predicted_worse(runs):
    problem, kept, fell = runs
    check = kept.stage1_check
    assert check is not None and not check.fell_back
    # stage 1's input ends moving; bringing it to rest moves the end of the output
    assert np.abs(np.diff(kept.r_init[-3:], axis=0)).max() * 400 > 0.01  # m/s
    assert check.worse and check.worst_at_s > 0.9 * check.duration_s
    assert check.stage1.linf > 3 * check.stretched.linf
    assert "leaves the end free" in kept.warning and "run stage 2" in kept.warning
    assert fell.stage1_check.fell_back and "stretched to T is used instead" in fell.warning
    assert not np.array_equal(fell.command.position, kept.command.position)
    assert fell.r.shape == kept.r.shape and fell.duration == kept.duration
    # what was compared is what is returned
    assert _predicted(problem, kept, TIGHT).linf == pytest.approx(check.stage1.linf)
    assert _predicted(problem, fell, TIGHT).linf == pytest.approx(check.stretched.linf)


def test_stage1_alone_is_kept_when_predicted_better():
    problem = ContourProblem(circle(0.01), a_max=1.0, tolerance_m=20e-6)
    res = optimize_reference(problem, SLOW, stage="1", stage1=Stage1Settings(n=60))
    check = res.stage1_check
    assert check is not None and not check.worse and not check.fell_back
    assert res.warning is None
    assert check.stretched.linf > 3 * check.stage1.linf  # the lagging stage: stage 1 pays
    assert _predicted(problem, res, SLOW).linf == pytest.approx(check.stage1.linf)
    assert res.wall_s["check"] < 10.0


def test_the_prediction_warning_fires_when_sigma_or_rms_exceeds_mu():
    """Issue 43: a network's validation σ above μ = 20 µm is warned of, per axis."""
    import json

    from microfab.optimize.models import builtin_models_dir, recorded_validation_sigma
    from microfab.optimize.pipeline import PredictionCheck

    small = {"x": 5e-6, "y": 6e-6}
    assert PredictionCheck(20e-6, small, small).warning is None
    assert PredictionCheck(20e-6, small, None).warning is None
    sigma = {"x": 19.7e-6, "y": 38.2e-6}  # the shipped networks of issue 43
    over = PredictionCheck(20e-6, small, sigma)
    assert "recorded validation σ y 38.2 µm exceeds μ = 20 µm" in over.warning
    assert "x 19.7" not in over.warning  # x (19.7 µm) is within μ
    assert "good to about 38 µm" in over.warning
    assert over.sigma_warning is not None and not over.rms_over_tolerance
    # the shipped models' σ is read from their record
    record = json.loads((builtin_models_dir() / "trained.json").read_text(encoding="utf-8"))
    shipped = recorded_validation_sigma("builtin")
    for ax in ("x", "y"):
        assert shipped[ax] == pytest.approx(record["validation"][ax]["sigma_um"] * 1e-6)
    apart = PredictionCheck(20e-6, {"x": 5e-6, "y": 45e-6}, None)
    assert "differ by RMS y 45.0 µm (> μ = 20 µm)" in apart.warning
    assert apart.rms_over_tolerance and apart.sigma_warning is None
    assert apart.as_dict()["warning"] == apart.warning
