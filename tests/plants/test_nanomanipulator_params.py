"""Tests of the nanomanipulator twin's parameter module and its re-export (seed 001 §4.1)."""

from __future__ import annotations

import pytest

from microfab.plants import nanomanipulator, nanomanipulator_params
from microfab.plants.nanomanipulator_params import beta_minimum, check_beta, load_params


def test_names_stay_importable_from_the_plant_module():
    for name in nanomanipulator_params.__all__:
        assert getattr(nanomanipulator, name) is getattr(nanomanipulator_params, name)
        assert name in nanomanipulator.__all__


def test_params_alone_load_and_check_beta():
    params = load_params()
    check_beta(params)  # the shipped twin passes its own check
    for axis in (0, 1):
        beta, *_ = beta_minimum(params, axis)
        assert beta >= params.beta_min_fraction * params.numerator_mm_per_v_s2[axis]


def test_beta_check_refuses_a_twin_whose_beta_falls_below_beta_min():
    with pytest.raises(ValueError, match="beta of axis x falls to"):
        load_params().with_(beta_cross_gain=1e4)
