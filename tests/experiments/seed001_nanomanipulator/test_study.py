"""The per-period RBF study (study.py): why the seed's network does not learn, and one that does."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.experiments.seed001_nanomanipulator.study import (
    ROWS,
    LearningStudy,
    learning_study,
)


@pytest.fixture(scope="module")
def study() -> LearningStudy:
    return learning_study()


def test_every_row_has_one_number_per_period(study: LearningStudy) -> None:
    assert tuple(study.rms_nm) == ROWS
    for name in ROWS:
        assert study.rms_nm[name].shape == (8,) and np.all(np.isfinite(study.rms_nm[name]))
    assert np.all(np.isnan(study.weight_norm["seed oracle"]))
    assert all(name in study.table() for name in ROWS)
    assert len(study.as_table().rows) == 10  # six RMS rows, four ‖Ŵ‖ rows


def test_default_regressor_is_one_constant_basis_function(study: LearningStudy) -> None:
    default, local = study.regressor
    assert default.h_min > 0.5  # every node active everywhere on the circle
    assert default.width_mean > 2.0  # wider than the orbit (diameter 2 scaled units)
    assert local.h_min < 1e-2 and local.width_mean < 1.0  # localised without ±s_spread
    assert local.gain == pytest.approx(default.gain, rel=1e-9)  # Γ keeps ΓΣh²


def test_seed_network_acts_as_feedback_not_as_learning(study: LearningStudy) -> None:
    ad, fr, orc = (study.rms_nm[f"seed {v}"] for v in ("adaptive", "frozen", "oracle"))
    assert np.all(fr > 20 * ad)  # frozen weights: the stage does not follow the circle
    assert abs(ad[-1] - ad[0]) < 0.1 * ad[0]  # no learning from period to period
    w = study.weight_norm["seed adaptive"]
    assert abs(w[-1] - w[0]) < 0.1 * w[0]
    assert orc[-1] < ad[-1]  # its ideal (eq. 6, true α, β) would do better


def test_proposed_network_learns_period_by_period(study: LearningStudy) -> None:
    ad, fr, orc = (study.rms_nm[f"proposed {v}"] for v in ("adaptive", "frozen", "oracle"))
    assert ad[-1] < ad[0] / 10  # learns: 585 -> 29 nm measured
    assert np.all(np.diff(ad) < 0)  # every period better than the last
    assert ad[-1] < fr[-1] / 100  # the network does the work (linear part alone: 7.7 µm)
    assert orc[-1] < ad[-1] < 154.0 / 3  # above its ideal, a third of the 200 Hz PID (154 nm)
    assert np.all(study.weight_norm["proposed frozen"] < 1e-12)  # Ŵ(0) = 0 held
