"""Stage 2's QP (issue 34): PIQP gives IPOPT's step, the projection HiGHS's input."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("casadi")
pytest.importorskip("torch")

from microfab.optimize.ann_torch import NetworkMap
from microfab.optimize.stage2 import (
    _UM,
    Stage2Settings,
    _diff_ops,
    _linearize,
    _Problem,
    _rest_terms,
    jacobian_band,
    solve_stage2,
)
from microfab.optimize.stage2_qp import Subproblem


def _subproblem(case, qp: str, norm: str = "euclidean") -> tuple[Subproblem, _Problem]:
    _, problem, target, _ = case
    st = Stage2Settings(qp=qp, norm=norm)
    pb = _Problem(target, np.asarray(problem.path.start), problem.tolerance_m, problem.v_max,
                  problem.a_max, problem.limits, st)  # fmt: skip
    return Subproblem(pb, st, _diff_ops(pb.m), [_rest_terms(pb.m, float(x)) for x in pb.rest]), pb


@pytest.mark.parametrize("norm", ["euclidean", "axis"])
@pytest.mark.parametrize("trust", [50.0, 0.5])
def test_piqp_step_equals_ipopt_step(case, norm, trust):
    models, _, _, r_init = case
    qps = {name: _subproblem(case, name, norm) for name in ("piqp", "ipopt")}
    qp, pb = qps["ipopt"]
    r = qp.project(r_init.T.ravel() * _UM)
    nm = NetworkMap(models.networks)
    _, jac = _linearize(nm, r, pb)
    phi, jac = _linearize(nm, r, pb, jacobian_band(jac, pb.m, 0.99))
    steps, merits = {}, {}
    for name, (sub, _) in qps.items():
        # twice: the second solve reuses the solver built for the pattern
        for _ in range(2):
            steps[name] = sub.solve(r, phi, jac, trust)
            merits[name] = sub.model_merit
    assert steps["piqp"] is not None and steps["ipopt"] is not None
    assert np.max(np.abs(steps["piqp"])) <= trust * (1 + 1e-9)
    # both interior-point solutions of the same QP; the steps are in µm
    assert np.allclose(steps["piqp"], steps["ipopt"], rtol=0, atol=2e-3)
    assert merits["piqp"] == pytest.approx(merits["ipopt"], rel=1e-6)


def test_piqp_projection_equals_highs(case):
    _, _, _, r_init = case
    r0 = r_init.T.ravel() * _UM
    r0 = r0 + np.where(np.arange(r0.size) % 7 == 3, 40.0, 0.0)  # kinks beyond the bounds
    out = {}
    for name in ("piqp", "ipopt"):  # "ipopt": the projection on HiGHS, as before
        sub, _ = _subproblem(case, name)
        lo1, hi1, lo2, hi2 = sub._cmd_bounds(r0)
        assert np.any(lo1 > 0) or np.any(hi1 < 0) or np.any(lo2 > 0) or np.any(hi2 < 0)
        out[name] = sub.project(r0)
        lo1, hi1, lo2, hi2 = sub._cmd_bounds(out[name])
        assert np.all(lo1 <= 1e-6) and np.all(hi1 >= -1e-6)
        assert np.all(lo2 <= 1e-6) and np.all(hi2 >= -1e-6)
    # moved by up to 190 µm; the same input to 1e-3 µm, the same distance to 1e-9
    assert np.allclose(out["piqp"], out["ipopt"], rtol=0, atol=1e-3)
    dist = {k: float(np.sum((v - r0) ** 2)) for k, v in out.items()}
    assert dist["piqp"] == pytest.approx(dist["ipopt"], rel=1e-9)


def test_piqp_and_ipopt_reach_the_same_merit(case):
    models, problem, target, r_init = case
    res = {}
    for name, th in (("piqp", 1), ("ipopt", None)):  # today's setting and the one before
        st = Stage2Settings(max_iter=4, qp=name, threads=th)
        res[name] = solve_stage2(
            target, r_init, models.networks, rest=problem.path.start,
            tolerance_m=problem.tolerance_m, v_max=problem.v_max, a_max=problem.a_max,
            limits=problem.limits, settings=st,
        )  # fmt: skip
    assert res["piqp"].cost_history[-1] == pytest.approx(res["ipopt"].cost_history[-1], rel=1e-2)
    assert res["piqp"].info["qp"] == "piqp"
    assert set(res["piqp"].phase_s) == {"project_s", "networks_s", "qp_s"}
    assert "qp_s" not in res["piqp"].summary()  # bookkeeping, not a result


@pytest.mark.parametrize(
    ("kw", "match"), [({"qp": "osqp"}, "qp must be"), ({"threads": 0}, "threads must be")]
)
def test_solver_settings_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        Stage2Settings(**kw)
