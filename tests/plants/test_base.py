"""Plant protocol, the Compiled base for plants, LTIPlant."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.compiled import Compiled
from microfab.plants.base import (
    CompiledPlant,
    LTIPlant,
    NoiseLevel,
    NoisyOutputs,
    Plant,
    lti_output,
    lti_update,
    white_noise,
)
from microfab.plants.lti import DiscreteLTI


@pytest.fixture
def sys2() -> DiscreteLTI:
    rng = np.random.default_rng(11)
    A = np.diag([0.9, 0.5, -0.3]) + 0.05 * rng.standard_normal((3, 3))
    return DiscreteLTI(
        A, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)), np.zeros((2, 2)), 1e-4
    )


def test_lti_plant_is_a_compiled_plant(sys2):
    p = LTIPlant(sys2)
    assert isinstance(p, Plant)
    assert isinstance(p, CompiledPlant)
    assert isinstance(p, Compiled)
    assert (p.n_inputs, p.n_outputs, p.dt) == (2, 2, 1e-4)
    assert p.kernels() == (lti_output, lti_update)


def test_lti_plant_python_and_kernels_agree_with_recursion(sys2):
    p = LTIPlant(sys2)
    rng = np.random.default_rng(3)
    s = p.init()
    xk = s.copy()  # kernel state, advanced in place
    x = np.zeros(3)
    yk = np.empty(2)
    for _ in range(20):
        u = rng.standard_normal(2)
        y = p.output(s)
        lti_output(p.params, xk, yk)
        np.testing.assert_allclose(y, sys2.C @ x, rtol=1e-14, atol=1e-14)
        np.testing.assert_allclose(yk, y, rtol=1e-14, atol=1e-14)
        s_old, s_copy = s, s.copy()
        s = p.update(s_old, u)
        np.testing.assert_array_equal(s_old, s_copy)  # update returns a new array
        lti_update(p.params, xk, u)
        x = sys2.A @ x + sys2.B @ u
    np.testing.assert_allclose(s[:3], x, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(xk[:3], x, rtol=1e-12, atol=1e-14)


def test_lti_plant_update_leaves_the_given_state(sys2):
    p = LTIPlant(sys2)
    s0 = p.init()
    s1 = p.update(s0, np.ones(2))
    np.testing.assert_array_equal(s0, 0.0)
    assert np.any(s1 != 0.0)


def test_lti_plant_refuses_feedthrough():
    with pytest.raises(ValueError, match="strictly proper"):
        LTIPlant(DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[1.0]], 1e-3))


def test_compiled_plant_missing_a_kernel_is_refused():
    class HalfCompiled(CompiledPlant):
        n_inputs = n_outputs = 1
        dt = 1e-3
        kernel_output = lti_output  # no kernel_update

        def init(self) -> np.ndarray:
            return np.zeros(2)

    with pytest.raises(TypeError, match=r"HalfCompiled .*'kernel_update'"):
        HalfCompiled()

    class NothingCompiled(CompiledPlant):
        def init(self) -> np.ndarray:
            return np.zeros(2)

    with pytest.raises(TypeError, match=r"'kernel_output', 'kernel_update'"):
        NothingCompiled()

    class NoInit(CompiledPlant):  # the abstract init is required too
        kernel_output = lti_output
        kernel_update = lti_update

    with pytest.raises(TypeError, match="abstract"):
        NoInit()


# ---------------------------------------------------------------- measurement noise


def test_noise_level_draws_white_noise_per_output():
    level = NoiseLevel((2e-6, 0.5), ("m", "V"))
    assert (level.n_outputs, level.units) == (2, ("m", "V"))
    v = level.draw(200_000, seed=7)
    assert v.shape == (200_000, 2)
    np.testing.assert_allclose(v.std(axis=0), [2e-6, 0.5], rtol=0.01)
    # the same draw as white_noise with each column scaled by its rms, bit for bit
    z = np.random.default_rng(7).standard_normal((200_000, 2))
    np.testing.assert_array_equal(v, z * [2e-6, 0.5])
    np.testing.assert_array_equal(v[:, :1], white_noise(200_000, 7, 2e-6)[:, :1])
    assert NoiseLevel((1.0, 1.0), "bit").units == ("bit", "bit")
    np.testing.assert_array_equal(NoiseLevel((0.0,), "m").draw(3, seed=1), np.zeros((3, 1)))


@pytest.mark.parametrize(
    ("rms", "unit", "match"),
    [
        ((1.0, -1.0), "m", r"noise rms\[1\] must be non-negative"),
        ((float("nan"),), "m", r"noise rms\[0\]"),
        ((), "m", "one value per output"),
        ((1.0, 2.0), ("m",), "one value per output"),
        ((1.0,), "m\n", "single-line string"),
        (1.0, "m", "one value per output"),
    ],
)
def test_noise_level_refuses(rms, unit, match):
    with pytest.raises(ValueError, match=match):
        NoiseLevel(rms, unit)


def test_every_twin_has_one_noise_level():
    from microfab.plants.galvo_slm import galvo_slm_twin
    from microfab.plants.lmw_focus import lmw_focus_twin
    from microfab.plants.lmw_stage import lmw_stage_twin
    from microfab.plants.nanomanipulator import nanomanipulator_twin
    from microfab.plants.xy_stage import xy_stage_twin

    units = {
        galvo_slm_twin: ("bit", "bit"),
        lmw_focus_twin: ("V", "m"),
        lmw_stage_twin: ("m", "m"),
        nanomanipulator_twin: ("mm", "mm"),
        xy_stage_twin: ("m", "m"),
    }
    for make, want in units.items():
        twin = make()
        assert isinstance(twin, NoisyOutputs)
        assert twin.noise_level.units == want
        if make is nanomanipulator_twin:
            # its sensor noise is coloured (calibrated first-order low-pass, rms kept): the
            # same seeded draw passed through the colour; white at time constants 0
            from microfab.plants.nanomanipulator import colour_noise

            tau = np.array(twin.config.noise_time_constant_s)
            np.testing.assert_array_equal(
                twin.noise(5, seed=3), colour_noise(twin.noise_level.draw(5, 3), tau, twin.dt)
            )
            twin = make(noise_time_constant_s=(0.0, 0.0))
        np.testing.assert_array_equal(twin.noise(5, seed=3), twin.noise_level.draw(5, 3))
