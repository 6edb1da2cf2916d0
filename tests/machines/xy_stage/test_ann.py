"""The seed 002 networks on the XY stage twin (machines.xy_stage.ann)."""

from __future__ import annotations

import numpy as np


def test_ann_study_splits_by_whole_runs_and_reports_validation_errors():
    from microfab.machines.xy_stage.ann import AnnSettings, ann_study

    st = ann_study(AnnSettings(total_s=12.0, max_epochs=1))
    assert st.train_names and st.validation_names
    assert not set(st.train_names) & set(st.validation_names)
    for axis in ("x", "y"):
        e = st.validation[axis]
        assert e.n > 0 and np.isfinite(e.sigma) and e.sigma < 1e-3  # one epoch: rough
