"""Tests of the SLM galvo twin of seed 003 part 2 (Buls et al., HurryScan25)."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

import control
from microfab.control.setpoint import SetPoint
from microfab.core.compiled import Compiled
from microfab.core.limits import LimitViolation, MachineLimits, check_command
from microfab.plants.base import CompiledPlant, LTIPlant, NoiseLevel, Plant
from microfab.plants.galvo_slm import GalvoSLMPlant, continuous_axis, galvo_slm_twin, load_params
from microfab.plants.lti import discretize
from microfab.plants.sourced_toml import sources_of
from microfab.sim.loop import is_compiled, simulate, simulate_python
from microfab.sim.lti_fast import BlockSimulator

# seed 003 part 2 §1: G(s) = 1.242e11 / (s^3 + 9517 s^2 + 5.773e7 s + 1.272e11)
NUM, DEN = 1.242e11, (1.0, 9517.0, 5.773e7, 1.272e11)
T = 1e-5  # seed 003 part 2 §2: "fs = 1e-5" read as the period


@pytest.fixture(scope="module")
def twin() -> GalvoSLMPlant:
    return galvo_slm_twin()


def test_every_value_is_sourced_and_the_seed_numbers_are_the_seeds():
    src = sources_of(None, "galvo_slm.toml")
    assert len(src) == 12
    for key in ("numerator", "denominator_s2", "denominator_s1", "denominator_s0"):
        assert src[f"model.{key}"].startswith("seed 003 part 2 §1")
    for key, text in src.items():
        assert text.startswith(("seed 003", "assumed:")), key
    c = load_params()
    assert (c.numerator, *c.denominator) == (NUM, *DEN)
    assert c.sample_time_s == T
    assert c.static_gain == pytest.approx(0.9764, abs=5e-5)  # 1.242e11 / 1.272e11


def test_a_data_file_with_an_unknown_key_is_refused(tmp_path):
    text = tmp_path / "x.toml"
    body = resources.files("microfab.data").joinpath("galvo_slm.toml").read_text()
    text.write_text(body + 'extra = 1.0\nextra_source = "assumed: nothing"\n')
    with pytest.raises(ValueError, match="unknown key 'extra'"):
        load_params(text)


def test_the_realisation_is_the_seeds_transfer_function(twin):
    seed = control.tf([NUM], list(DEN))
    f = np.array([1.0, 10.0, 100.0, 550.0, 965.0, 2000.0, 1e4])
    w = 2j * np.pi * f
    ours = control.tf(twin.continuous_axis())
    np.testing.assert_allclose(ours(w), seed(w), rtol=1e-9)
    # derived poles (issue 16 acceptance): 550.5 Hz real; 965.2 Hz, zeta 0.4995
    a, wn, zeta = twin.config.factors()
    assert a / (2 * np.pi) == pytest.approx(550.5, rel=1e-3)
    assert wn / (2 * np.pi) == pytest.approx(965.2, rel=1e-3)
    assert zeta == pytest.approx(0.4995, abs=1e-4)


def test_the_discrete_axis_is_the_zoh_of_the_seeds_model(twin):
    ref = discretize(control.tf([NUM], list(DEN)), T, "zoh")
    u = np.zeros((1000, 1))
    u[3:] = 1000.0
    u[150:] = -250.0
    y_ref = BlockSimulator(ref, block=16).run(u)
    y = BlockSimulator(twin.axis_model, block=16).run(u)
    np.testing.assert_allclose(y, y_ref, rtol=0, atol=1e-8 * 1000)
    assert y[-1, 0] == pytest.approx(-250.0 * NUM / DEN[-1], rel=1e-6)


def test_it_is_a_compiled_lti_plant_with_two_identical_axes(twin):
    assert isinstance(twin, Plant) and isinstance(twin, CompiledPlant)
    assert isinstance(twin, LTIPlant) and isinstance(twin, Compiled)
    assert (twin.n_inputs, twin.n_outputs, twin.dt) == (2, 2, T)
    assert twin.axes == ("x", "y")
    assert is_compiled(twin, SetPoint(2))
    r = np.zeros((300, 2))
    r[10:] = [2000.0, -700.0]
    out = simulate(twin, SetPoint(2), r).output
    # one axis's response scales to the other's: identical axes
    np.testing.assert_allclose(out[:, 1], out[:, 0] * (-700.0 / 2000.0), rtol=0, atol=1e-9)


def test_compiled_python_and_lifted_paths_agree(twin):
    rng = np.random.default_rng(4)
    r = np.repeat(rng.uniform(-3e4, 3e4, (30, 2)), 20, axis=0)
    noise = twin.noise(r.shape[0], seed=2)
    a = simulate(twin, SetPoint(2), r, noise)
    b = simulate_python(twin, SetPoint(2), r, noise)
    c = BlockSimulator(twin.sys, block=32).run(r)
    np.testing.assert_allclose(a.output, b.output, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.output, c, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.measured - a.output, noise, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(a.command, r)  # the set point is the command


def test_noise_is_seeded_and_has_the_assumed_rms(twin):
    a, b = twin.noise(200_000, seed=7), twin.noise(200_000, seed=7)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, twin.noise(200_000, seed=8))
    # std error of the rms estimate 0.3 / sqrt(2 n) = 4.7e-4 bit: 6 of them allowed
    np.testing.assert_allclose(a.std(axis=0), 0.3, atol=3e-3)
    assert twin.noise_level == NoiseLevel((0.3, 0.3), "bit")


def test_mirror_mode_option():
    twin = galvo_slm_twin(mirror_mode=True)
    assert twin.axis_model.n_states == 5
    poles = np.linalg.eigvals(continuous_axis(twin.config, mirror_mode=True).A)
    pair = poles[np.argmax(np.abs(poles))]
    assert abs(pair) / (2 * np.pi) == pytest.approx(3000.0, rel=1e-9)
    assert -pair.real / abs(pair) == pytest.approx(0.02, rel=1e-9)
    # unit static gain of the mode: the twin keeps G(0)
    dc = twin.axis_model.frequency_response(np.array([0.0]))[0, 0, 0].real
    assert dc == pytest.approx(twin.static_gain, rel=1e-9)
    # the mode shows as a resonance peak relative to the plain twin near 3 kHz
    f = np.array([2900.0, 2990.0, 3000.0, 3010.0, 3100.0])
    plain = galvo_slm_twin().axis_model.frequency_response(f)[:, 0, 0]
    ratio = np.abs(twin.axis_model.frequency_response(f)[:, 0, 0] / plain)
    assert ratio.argmax() == 2 and ratio.max() > 20  # 1 / (2 zeta) = 25


def test_field_limits_in_bit_and_in_metres(twin):
    lim = twin.axis_limits()
    assert set(lim) == {"x", "y"} and lim["x"].position == 32768.0 and lim["x"].unit == "bit"
    ml = MachineLimits.seed003_slm()
    assert ml.workspace[0] == pytest.approx((-lim["x"].position * 1.5e-6, 32768 * 1.5e-6))
    assert ml.velocity[0] == pytest.approx(lim["x"].velocity * 1.5e-6)
    assert ml.acceleration[0] == pytest.approx(lim["x"].acceleration * 1.5e-6)
    ok = np.linspace(0.0, 30000.0, 901)[:, None] * [1.0, -1.0]  # 33.3 bit per tick: 5 m/s
    check_command(ok, T, lim, ("x", "y"), periodic=False)
    bad = ok.copy()
    bad[-1, 1] = -32769.0
    with pytest.raises(LimitViolation, match=r"axis y: position -3.277e\+04 bit"):
        check_command(bad, T, lim, ("x", "y"), periodic=False)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"denominator_s0": 1e13}, "not Hurwitz"),
        ({"mirror_mode_hz": 6e4}, "mirror_mode_hz must lie in"),
        ({"mirror_mode_damping": 0.0}, "mirror_mode_damping must lie in"),
        ({"noise_rms_bit": -0.1}, "noise_rms_bit must be non-negative"),
        ({"bogus": 1.0}, "unknown galvo parameter"),
    ],
)
def test_bad_parameters_are_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        load_params().with_(**changes)
