"""Plant protocol, the Compiled base for plants, LTIPlant."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.compiled import Compiled
from microfab.plants.base import CompiledPlant, LTIPlant, Plant, lti_output, lti_update
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
