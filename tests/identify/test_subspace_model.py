"""Continuous-time form of a model fitted to decimated data (`SubspaceModel.to_continuous`).

The system (issue 34, item 0): 2 inputs, 2 outputs, 4 states in modal form, a 3 Hz mode
of damping 0.3 and a 40 Hz mode of damping 0.1,

    A = diag(osc(3 Hz, 0.3), osc(40 Hz, 0.1)),   osc(f, z) = [[0, 1], [-w^2, -2 z w]],
    B = [[0, 0], [1, 0.4], [0, 0], [0.5, 1]],
    C = [[w1^2, 0, 0.5 w2^2, 0], [0.3 w1^2, 0, w2^2, 0]],   D = 0

(static gain [[1.5, 0.9], [0.8, 1.12]]), sampled with a zero-order hold at 2 kHz (the
input held for each 0.5 ms sample, as a machine's loop holds its set-point) and driven by
20 s of seeded white noise of 1 mm rms. `fit_linear` decimates by 2 (to 1 kHz) and fits
order 4: the poles come back (3.007 Hz, 40.01 Hz), but the inverse ZOH at 1 kHz read the
data as held for 1 ms and its continuous model was 6.4 % off at 40 Hz; converted for
the 0.5 ms hold the data had, it is within 0.2 %.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from microfab.identify.stage_data import StageLinearModel, fit_linear
from microfab.identify.subspace_fit import simulate_ss
from microfab.identify.subspace_model import ContinuousModel, SubspaceModel

DT = 1 / 2000  # the data's rate, 2 kHz
W1, W2 = 2 * np.pi * 3.0, 2 * np.pi * 40.0
BAND_HZ = 250.0  # CONTINUOUS_BAND x the 1 kHz model's Nyquist


def _osc(w: float, z: float) -> np.ndarray:
    return np.array([[0.0, 1.0], [-(w**2), -2 * z * w]])


A = scipy.linalg.block_diag(_osc(W1, 0.3), _osc(W2, 0.1))
B = np.array([[0.0, 0.0], [1.0, 0.4], [0.0, 0.0], [0.5, 1.0]])
C = np.array([[W1**2, 0.0, 0.5 * W2**2, 0.0], [0.3 * W1**2, 0.0, W2**2, 0.0]])
D = np.zeros((2, 2))


def _response(a, b, c, d, s: complex) -> np.ndarray:
    return c @ np.linalg.solve(s * np.eye(a.shape[0]) - a, b) + d


def _rel_error(m: ContinuousModel, f_hz: float) -> float:
    """Largest relative error of the model's 2x2 response against the true one at f."""
    s = 2j * np.pi * f_hz
    true = _response(A, B, C, D, s)
    return float(np.max(np.abs(_response(m.a, m.b, m.c, m.d, s) - true) / np.abs(true)))


@pytest.fixture(scope="module")
def fitted() -> SubspaceModel:
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete((A, B, C, D), DT, method="zoh")
    u = 1e-3 * np.random.default_rng(0).standard_normal((40_000, 2))
    y = simulate_ss(ad, bd, cd, dd, u, np.zeros(4))
    return fit_linear([(u, y)], DT)  # decimated by 2 to 1 kHz, as measured runs are


def test_the_fit_is_decimated_and_finds_the_modes(fitted):
    assert fitted.dt == pytest.approx(2 * DT)
    s = fitted.continuous_poles()
    np.testing.assert_allclose(np.unique(np.round(np.abs(s) / (2 * np.pi), 1)), [3.0, 40.0])


def test_continuous_model_of_decimated_data_is_within_1_percent_at_40_hz(fitted):
    held = fitted.to_continuous(hold_dt=DT)
    old = fitted.to_continuous()  # the inverse ZOH at the model's 1 ms
    assert _rel_error(held, 40.0) < 0.01
    assert _rel_error(old, 40.0) > 0.05  # the lead of 0.25 ms the 1 ms hold assumed
    # and not worse elsewhere in the band: as close to the truth as the fitted discrete
    # model itself is (its own error against the 2 kHz truth)
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete((A, B, C, D), DT, method="zoh")
    for f in (0.0, 0.5, 1.0, 3.0, 10.0, 20.0, 40.0, 80.0, 150.0, BAND_HZ):
        zd, z0 = np.exp(2j * np.pi * f * fitted.dt), np.exp(2j * np.pi * f * DT)
        true_d = _response(ad, bd, cd, dd, z0)
        floor = np.max(np.abs(_response(fitted.a, fitted.b, fitted.c, fitted.d, zd) - true_d))
        floor = floor / np.min(np.abs(true_d))
        assert _rel_error(held, f) <= min(_rel_error(old, f), floor) + 1e-3, f
    np.testing.assert_allclose(held.a, old.a)  # same poles: only B and D move
    np.testing.assert_allclose(held.c, old.c)


def test_stage_model_converts_for_the_hold_of_its_runs(fitted):
    stage = StageLinearModel(model=fitted, input_dt=DT, decimate=2)
    got, want = stage.continuous(), fitted.to_continuous(hold_dt=DT)
    np.testing.assert_array_equal(got.b, want.b)
    np.testing.assert_array_equal(got.d, want.d)


def test_static_gain_is_kept(fitted):
    held, old = fitted.to_continuous(hold_dt=DT), fitted.to_continuous()
    np.testing.assert_allclose(_response(held.a, held.b, held.c, held.d, 0.0),
                               _response(old.a, old.b, old.c, old.d, 0.0), rtol=1e-6)  # fmt: skip


def test_a_hold_of_one_model_sample_is_the_inverse_zoh(fitted):
    a, b = fitted.to_continuous(), fitted.to_continuous(hold_dt=fitted.dt)
    np.testing.assert_array_equal(a.b, b.b)
    # the least squares at hold_dt = dt (just below: not the closed form) gives it back
    ls = fitted.to_continuous(hold_dt=fitted.dt * (1 - 1e-6))
    np.testing.assert_allclose(ls.b, a.b, rtol=0, atol=1e-4 * np.abs(a.b).max())
    np.testing.assert_allclose(ls.d, a.d, rtol=0, atol=1e-4)


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [({"hold_dt": 0.0}, "hold_dt must be"), ({"hold_dt": 2e-3}, "longer than the model's dt"),
     ({"hold_dt": DT, "band": 0.0}, "band must be in"),
     ({"hold_dt": DT, "band": 1.5}, "band must be in")],
)  # fmt: skip
def test_refusals(fitted, kwargs, says):
    with pytest.raises(ValueError, match=says):
        fitted.to_continuous(**kwargs)
