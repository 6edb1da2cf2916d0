"""The per-period RBF study (study.py): why the seed's network does not learn over periods."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.seed001_nanomanipulator.study import (
    VARIANTS,
    LearningStudy,
    learning_study,
)


@pytest.fixture(scope="module")
def study() -> LearningStudy:
    return learning_study()


def test_every_variant_has_one_number_per_period(study: LearningStudy) -> None:
    for name in VARIANTS:
        assert study.rms_nm[name].shape == (8,) and np.all(np.isfinite(study.rms_nm[name]))
    assert np.all(np.isnan(study.weight_norm["oracle"]))
    assert all(name in study.table() for name in VARIANTS)
    assert len(study.as_table().rows) == 5


def test_default_regressor_is_one_constant_basis_function(study: LearningStudy) -> None:
    default, local = study.regressor
    assert default.h_min > 0.5  # every node active everywhere on the circle
    assert default.width_mean > 2.0  # wider than the orbit (diameter 2 scaled units)
    assert local.h_min < 1e-2 and local.width_mean < 1.0  # localised without ±s_spread


def test_adaptation_acts_as_feedback_not_as_learning(study: LearningStudy) -> None:
    ad, fr, orc = (study.rms_nm[v] for v in VARIANTS)
    assert np.all(fr > 20 * ad)  # frozen weights: the stage does not follow the circle
    assert abs(ad[-1] - ad[0]) < 0.1 * ad[0]  # no learning from period to period
    w = study.weight_norm["adaptive"]
    assert abs(w[-1] - w[0]) < 0.1 * w[0]
    assert np.all(study.weight_norm["frozen"] == study.weight_norm["frozen"][0])
    assert orc[-1] < ad[-1]  # a perfect network (eq. 6 with the true α, β) would do better
