"""The models of a stage-identify output, as the optimisation reads them."""

from __future__ import annotations

import pytest

from microfab.optimize.models import load_models


def test_a_folder_without_a_linear_model_is_refused(tmp_path):
    with pytest.raises(ValueError, match=r"linear_model\.json: no linear model"):
        load_models(tmp_path)


def test_the_linear_model_alone_for_stage_1(tiny_models):
    m = load_models(tiny_models[0], networks=False)
    assert m.networks is None and m.linear is not None
    assert m.source == str(tiny_models[0])
