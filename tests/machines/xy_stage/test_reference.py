"""The reference job's scoring on the XY stage twin (machines.xy_stage.reference).

`run_point` and `saved_point` run in the stage-reference-opt job's tests
(tests/experiments/seed002_reference/test_job.py, tests/cli/test_run_store.py).
"""

from __future__ import annotations

import pytest

from microfab.geometry.shapes import circle, rectangle
from microfab.machines.xy_stage.machine import TwinSettings
from microfab.machines.xy_stage.reference import HOLD_S, _baseline_norms, baseline_l2


def test_baseline_pools_contours_traced_at_one_speed():
    tw = TwinSettings(noise=False, hold_s=HOLD_S)
    a, b = circle(4e-3), rectangle(6e-3, 4e-3)
    one = _baseline_norms(a, 0.3, tw)
    assert one.n == 120 and 0 < one.l1 <= one.l2 <= one.linf and one.tail_linf is not None
    assert baseline_l2([a], 0.3, tw) == one.l2
    total, length = 0.6, a.length + b.length
    parts = [_baseline_norms(p, total * p.length / length, tw) for p in (a, b)]
    pooled = baseline_l2([a, b], total, tw)
    assert min(p.l2 for p in parts) <= pooled <= max(p.l2 for p in parts)
    assert baseline_l2([a, b], 2 * total, tw) < pooled  # slower: closer to the contour
    with pytest.raises(ValueError, match="duration"):
        baseline_l2([a], 0.0, tw)


def test_a_point_saved_in_an_older_format_is_run_again(tmp_path, monkeypatch):
    """Issue 43: points saved before the stages' measured constraints are not reused."""
    import json

    from microfab.machines.xy_stage import reference as xr
    from microfab.optimize.problem import ContourProblem
    from microfab.optimize.stage1 import Stage1Error

    calls = []

    def fails(*args, **kwargs):
        calls.append(1)
        raise Stage1Error("stage 1 is infeasible: eq. 12h (tolerance) broken", None)

    monkeypatch.setattr(xr, "run_point", fails)
    problem = ContourProblem(circle(2e-3), a_max=1.0, tolerance_m=20e-6)
    old = {"case": "c", "a_max": 1.0, "fingerprint": "f", "stage2": {"converged": True}}
    (tmp_path / "c_a1.json").write_text(json.dumps(old))
    kw = {"twin": TwinSettings(), "stage2_max_iter": 1, "folder": tmp_path, "fingerprint": "f"}
    got = xr.saved_point("c", problem, None, **kw)
    assert calls == [1] and got["format"] == xr.POINT_FORMAT and "12h" in got["error"]
    again = xr.saved_point("c", problem, None, **kw)  # the current format: read back
    assert calls == [1] and again == json.loads((tmp_path / "c_a1.json").read_text())
