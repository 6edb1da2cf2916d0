"""The SLM galvo shaping run's parts: identification, shapers, jumps, settings, summary."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.shaped_command import ShapedCommandError
from microfab.identify.chirp import ChirpDesign
from microfab.machines.slm_galvo import machine as slm_galvo
from microfab.machines.slm_galvo.machine import SEED_MODEL_DEN, SEED_MODEL_NUM
from microfab.machines.slm_galvo.shaping import (
    IdentifySettings,
    ShaperSettings,
    design_shapers,
    identify_twin,
    jump_response,
)

SHORT_CHIRP = ChirpDesign(period_s=0.1, n_periods=3, n_dropped=1)


@pytest.fixture(scope="module")
def twin():
    return slm_galvo.twin()


def test_identification_finds_the_seeds_model(twin):
    ident = identify_twin(twin, IdentifySettings(chirp=SHORT_CHIRP), noise=False)
    m = ident.fit.model
    seed = np.array([SEED_MODEL_NUM[0], *SEED_MODEL_DEN[1:]])  # seed 003 part 2 §1
    np.testing.assert_allclose([m.num[-1], *m.den[1:]], seed, rtol=0.01)
    assert ident.measured.shape == ident.chirp.input.shape


def test_both_discretisations_are_designed():
    shapers = design_shapers((SEED_MODEL_NUM, SEED_MODEL_DEN), ShaperSettings())
    assert set(shapers) == {"zoh", "zpetc"}
    assert shapers["zpetc"].config.discretization == "zpetc"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"discretization": "foh"}, "discretization"), ({"pole_hz": 1e6}, "pole")],
)
def test_shaper_settings_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ShaperSettings(**kwargs)


def test_jump_settles_with_and_without_the_shaper(twin):
    shaper = design_shapers((SEED_MODEL_NUM, SEED_MODEL_DEN), ShaperSettings())["zpetc"]
    for sh in (None, shaper):
        r = jump_response(twin, 1.64e-3, 5.0, sh, noise=False)
        L = r.command[-1]
        assert abs(r.position[-20:].mean() - L) < 0.02 * L
        assert (r.shaped is None) == (sh is None)


def test_shaped_jump_outside_the_field_is_refused(twin):
    shaper = design_shapers((SEED_MODEL_NUM, SEED_MODEL_DEN), ShaperSettings())["zpetc"]
    with pytest.raises(ShapedCommandError):
        jump_response(twin, 40e-3, 1e4, shaper, noise=False)  # a near step overshoots the field
