"""TFModel: derived numbers of the seed's model, sampled responses, JSON, python-control."""

from __future__ import annotations

import json

import numpy as np
import pytest

import control
from microfab.identify import TFModel

SEED = TFModel(num=[1.242e11], den=[1.0, 9517.0, 5.773e7, 1.272e11])  # seed 003 part 2 §1


def test_seed_model_derived_numbers():
    assert SEED.static_gain == pytest.approx(1.242e11 / 1.272e11)  # 0.9764 (issue 16 §3)
    (real_hz,) = SEED.real_poles_hz
    ((mode_hz, zeta),) = SEED.complex_modes
    assert real_hz == pytest.approx(550.5, rel=1e-3)  # issue 16 §6
    assert mode_hz == pytest.approx(965.2, rel=1e-3)
    assert zeta == pytest.approx(0.4995, rel=1e-3)
    bw = SEED.bandwidth_hz()
    # half power (-3.0103 dB): 710.19 Hz, issue 16 gives 710.6 (0.06 % apart)
    assert bw == pytest.approx(710.6, rel=1e-3)
    g = abs(SEED.frequency_response(np.array([bw]))[0])
    assert g == pytest.approx(SEED.static_gain / np.sqrt(2), rel=1e-10)
    # python-control takes -3.0 dB exactly: a little lower
    assert control.bandwidth(SEED.to_control()) / (2 * np.pi) < bw
    assert SEED.is_stable and SEED.n_poles == 3 and SEED.n_zeros == 0
    assert SEED.zeros.size == 0


def test_monic_and_proper():
    m = TFModel(num=[0.0, 4.0, 8.0], den=[2.0, 6.0, 4.0], unit="bit/bit")
    np.testing.assert_array_equal(m.den, [1.0, 3.0, 2.0])
    np.testing.assert_array_equal(m.num, [2.0, 4.0])  # leading zero dropped
    np.testing.assert_allclose(np.sort(m.poles.real), [-2.0, -1.0])
    np.testing.assert_allclose(m.zeros, [-2.0])
    with pytest.raises(ValueError, match=r"proper \(no more zeros than poles\), got 2 zeros and 1"):
        TFModel(num=[1.0, 2.0, 3.0], den=[1.0, 1.0])
    with pytest.raises(ValueError, match=r"den's leading coefficient must be non-zero"):
        TFModel(num=[1.0], den=[0.0, 1.0])
    with pytest.raises(ValueError, match=r"num holds NaN/inf"):
        TFModel(num=[np.nan], den=[1.0, 1.0])
    integ = TFModel(num=[5.0], den=[1.0, 10.0, 0.0])
    assert integ.static_gain == np.inf
    assert not integ.is_stable
    with pytest.raises(ValueError, match="unstable"):
        integ.bandwidth_hz()


@pytest.mark.parametrize("dt", [1e-5, 1e-4])
def test_zoh_response_is_python_controls_discretisation(dt: float):
    f = np.array([1.0, 100.0, 965.0, 2000.0, 4000.0])
    sysd = control.c2d(SEED.to_control(), dt, "zoh")
    expected = np.array([complex(control.evalfr(sysd, np.exp(2j * np.pi * x * dt))) for x in f])
    got = SEED.frequency_response(f, sampling="zoh", dt=dt)
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    cont = SEED.frequency_response(f)
    np.testing.assert_allclose(
        cont, [complex(control.evalfr(SEED.to_control(), 2j * np.pi * x)) for x in f], rtol=1e-12
    )
    delay = SEED.frequency_response(f, sampling="delay", dt=dt)
    np.testing.assert_allclose(delay, cont * np.exp(-1j * np.pi * f * dt), rtol=1e-12)
    with pytest.raises(ValueError, match=r"sampling='delay' needs the sample time dt"):
        SEED.frequency_response(f, sampling="delay")


def test_scaled_round_trip():
    for ws in (1.0, 2 * np.pi * 800.0, SEED.scale_rad_s):
        b, a = SEED.scaled(ws)
        back = TFModel.from_scaled(b, a, ws)
        np.testing.assert_allclose(back.den, SEED.den, rtol=1e-14)
        np.testing.assert_allclose(back.num, SEED.num, rtol=1e-14)
    b, a = SEED.scaled(SEED.scale_rad_s)
    assert a[-1] == pytest.approx(1.0)  # the geometric mean of the pole magnitudes
    assert np.all((np.abs(a) > 0.1) & (np.abs(a) < 10))


def test_dict_round_trip_and_refusals():
    d = json.loads(json.dumps(SEED.to_dict()))
    assert d["format"] == "microfab.identify.TFModel" and d["version"] == 1
    assert d["derived"]["bandwidth_hz"] == pytest.approx(SEED.bandwidth_hz())
    assert d["derived"]["complex_modes"][0]["damping"] == pytest.approx(0.4995, rel=1e-3)
    back = TFModel.from_dict(d)
    np.testing.assert_array_equal(back.den, SEED.den)
    np.testing.assert_array_equal(back.num, SEED.num)
    with pytest.raises(ValueError, match=r"unknown key 'poles'"):
        TFModel.from_dict({**d, "poles": []})
    with pytest.raises(ValueError, match=r"version must be 1, got 2"):
        TFModel.from_dict({**d, "version": 2})
    with pytest.raises(ValueError, match=r"the model has no 'den'"):
        TFModel.from_dict({"num": [1.0]})
    with pytest.raises(ValueError, match=r"'num' must be a list of numbers"):
        TFModel.from_dict({"num": ["1"], "den": [1.0, 1.0]})
    with pytest.raises(ValueError, match=r"must be a JSON object"):
        TFModel.from_dict([1, 2])  # type: ignore[arg-type]


def test_control_round_trip_and_formula():
    tf = SEED.to_control()
    back = TFModel.from_control(tf)
    np.testing.assert_allclose(back.den, SEED.den)
    with pytest.raises(ValueError, match="continuous-time"):
        TFModel.from_control(control.tf([1.0], [1.0, -0.5], 1e-5))
    assert SEED.formula() == "(1.242e+11) / (s^3 + 9517 s^2 + 5.773e+07 s + 1.272e+11)"
