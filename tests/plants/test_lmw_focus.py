"""Tests of the seed 004 focus axis twin (z stage, Gaussian beam, spot-size detector)."""

from __future__ import annotations

import math
import tomllib
from importlib import resources

import numpy as np
import pytest

from microfab.control.base import LTIController
from microfab.core.compiled import Compiled
from microfab.plants.base import CompiledPlant, Plant
from microfab.plants.lmw_focus import (
    DOF_GROWTH,
    LMWFocus,
    depth_of_focus,
    kernel_output,
    kernel_update,
    lmw_focus_twin,
    load_params,
)
from microfab.plants.lti import DiscreteLTI
from microfab.sim.loop import is_compiled, simulate, simulate_python

DT = 1e-4
LAMBDA, WAIST = 1065e-9, 10.8e-6  # seed 004 §II.A


def outputs(plant: LMWFocus, s: np.ndarray) -> np.ndarray:
    y = np.empty(2)
    kernel_output(plant.params, s, y)
    return y


def open_loop(plant: LMWFocus, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = plant.init()
    out, states = np.empty((len(u), 2)), np.empty((len(u), 3))
    for k in range(len(u)):
        out[k] = outputs(plant, s)
        kernel_update(plant.params, s, np.array([u[k]]))
        states[k] = s
    return out, states


@pytest.fixture(scope="module")
def twin() -> LMWFocus:
    return lmw_focus_twin()


def test_is_a_compiled_plant(twin):
    assert isinstance(twin, Plant) and isinstance(twin, CompiledPlant)
    assert isinstance(twin, Compiled)
    assert (twin.n_inputs, twin.n_outputs, twin.dt) == (1, 2, DT)
    assert twin.kernels() == (kernel_output, kernel_update)
    assert twin.packed_params().dtype == np.float64


def test_gaussian_beam_and_depth_of_focus(twin):
    c = twin.config
    assert (c.wavelength_m, c.waist_diameter_m, c.m_squared) == (LAMBDA, WAIST, 1.0)
    z_r = math.pi * (WAIST / 2) ** 2 / LAMBDA
    assert c.rayleigh_range_m == pytest.approx(z_r, rel=1e-15)
    assert c.rayleigh_range_m == pytest.approx(86.0e-6, abs=0.05e-6)
    dof = depth_of_focus()
    assert dof == pytest.approx(54e-6, rel=0.05)  # seed 004 §II.A: about 54 µm
    assert dof == pytest.approx(55.08e-6, abs=0.01e-6)
    assert dof == twin.depth_of_focus_m(DOF_GROWTH) == c.depth_of_focus_m()
    # the spot grows by the stated 5 % at the edges, by sqrt(2) one Rayleigh range off
    assert c.spot_radius_m(dof / 2) == pytest.approx(1.05 * WAIST / 2, rel=1e-12)
    assert c.spot_radius_m(-z_r) == pytest.approx(math.sqrt(2) * WAIST / 2, rel=1e-12)
    np.testing.assert_allclose(
        c.spot_radius_m(np.array([0.0, z_r])), [WAIST / 2, WAIST / 2 * 2**0.5]
    )
    # a worse beam (M² = 2) halves the Rayleigh range and the depth of focus
    worse = c.with_(m_squared=2.0)
    assert worse.depth_of_focus_m() == pytest.approx(dof / 2, rel=1e-12)
    assert depth_of_focus(0.1) == pytest.approx(2 * z_r * math.sqrt(1.1**2 - 1), rel=1e-12)


def test_detector_minimum_at_focus(twin):
    c = twin.config
    z = np.linspace(-300e-6, 300e-6, 601) + 0.37e-6
    ys = []
    for zk in z:
        s = twin.init()
        s[0] = zk
        ys.append(outputs(twin, s)[0])
        np.testing.assert_allclose(twin.output(s)[0], ys[-1], rtol=1e-14)
    ys = np.array(ys)
    i = int(np.argmin(ys))
    assert abs(z[i] - c.focus_position_m) <= 0.5e-6
    assert np.all(np.diff(ys[: i + 1]) < 0) and np.all(np.diff(ys[i:]) > 0)  # one minimum
    s = twin.init()
    s[0] = c.focus_position_m
    assert outputs(twin, s)[0] == pytest.approx(c.offset_v + c.gain_v, rel=1e-15)
    # y = offset + gain (w / w0)²
    s[0] = 120e-6
    want = c.offset_v + c.gain_v * (c.spot_radius_m(120e-6) / c.waist_radius_m) ** 2
    assert outputs(twin, s)[0] == pytest.approx(want, rel=1e-13)
    assert c.detector_v(120e-6) == pytest.approx(want, rel=1e-13)


def test_moving_focus_plane(twin):
    rate = 1e-5  # 1 mrad tilt under 10 mm/s
    moving = lmw_focus_twin(surface_rate_m_s=rate, focus_position_m=20e-6)
    s = moving.init()
    s[2] = 5000.0  # 0.5 s in: z_f = 20 µm + 5 µm
    assert moving.time_s(s) == pytest.approx(0.5)
    assert moving.focus_position_m(s) == pytest.approx(25e-6, rel=1e-12)
    z = np.linspace(0.0, 50e-6, 501)
    ys = []
    for zk in z:
        s[0] = zk
        ys.append(outputs(moving, s)[0])
    assert z[int(np.argmin(ys))] == pytest.approx(25e-6, abs=0.05e-6)
    # the counter advances one sample per update
    _y, states = open_loop(moving, np.zeros(10))
    assert states[-1, 2] == 10.0


def test_z_stage_is_the_zoh_of_the_velocity_lag():
    plant = lmw_focus_twin(quantisation=False)
    rng = np.random.default_rng(4)
    u = np.repeat(rng.uniform(-1.5e-3, 1.5e-3, 30), 50)  # below the 2 mm/s limit
    y, _states = open_loop(plant, u)
    lm = plant.linear_model()
    x = np.array([plant.config.start_position_m, 0.0])
    ref = np.empty(len(u))
    for k in range(len(u)):
        ref[k] = (lm.C @ x)[0]
        x = lm.A @ x + lm.B[:, 0] * u[k]
    span = np.max(np.abs(ref - ref[0]))
    assert span > 1e-5
    assert np.max(np.abs(y[:, 1] - ref)) < 1e-12 * span
    # time constant and speed limit
    tau, vmax = plant.config.velocity_lag_s, plant.config.speed_limit_m_s
    n_tau = round(tau / DT)
    _y, st = open_loop(plant, np.full(n_tau, 1e-3))
    assert st[-1, 1] == pytest.approx(1e-3 * -math.expm1(-1.0), rel=1e-12)
    _y, st = open_loop(plant, np.full(20 * n_tau, -1.0))
    assert st[-1, 1] == pytest.approx(-vmax, rel=1e-8)
    assert np.all(np.abs(st[:, 1]) <= vmax * (1 + 1e-15))
    # the test can fail: the limit changes the response of the fast commands
    u2 = u * 3.0
    y2, _ = open_loop(plant, u2)
    x = np.array([plant.config.start_position_m, 0.0])
    ref2 = np.empty(len(u))
    for k in range(len(u)):
        ref2[k] = (lm.C @ x)[0]
        x = lm.A @ x + lm.B[:, 0] * u2[k]
    assert np.max(np.abs(y2[:, 1] - ref2)) > 1e-6


def test_encoder_quantisation(twin):
    s = twin.init()
    for z, want in ((12.34e-6, 12.3e-6), (12.36e-6, 12.4e-6), (-0.04e-6, 0.0), (-0.06e-6, -0.1e-6)):
        s[0] = z
        assert outputs(twin, s)[1] == pytest.approx(want, abs=1e-18)
        assert twin.output(s)[1] == outputs(twin, s)[1]
    raw = lmw_focus_twin(quantisation=False)
    s[0] = 12.34e-6
    assert outputs(raw, s)[1] == 12.34e-6


def _z_loop(kp_per_s: float) -> LTIController:
    """u = kp (z_ref - z): a proportional position loop on the encoder (no dynamics)."""
    return LTIController(
        DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), [[0.0, kp_per_s]], DT)
    )


def test_compiled_and_python_loops_agree():
    plant = lmw_focus_twin(surface_rate_m_s=1e-5)
    n = 500
    t = np.arange(n) * DT
    ref = np.column_stack([np.zeros(n), 5e-4 - 200e-6 * np.sin(2 * np.pi * 4 * t)])
    noise = np.random.default_rng(5).normal(0.0, 1.0, (n, 2)) * [plant.noise_rms()[0], 0.0]
    ctrl = _z_loop(20.0)
    assert is_compiled(plant, ctrl)
    fast = simulate(plant, ctrl, ref, noise)
    slow = simulate_python(plant, ctrl, ref, noise)
    assert np.ptp(fast.output[:, 1]) > 1e-5 and np.ptp(fast.output[:, 0]) > 0.01
    np.testing.assert_allclose(slow.output[:, 1], fast.output[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(slow.output[:, 0], fast.output[:, 0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(slow.command, fast.command, rtol=0, atol=1e-12)
    np.testing.assert_allclose(slow.final_state.plant, fast.final_state.plant, rtol=1e-12)
    np.testing.assert_allclose(fast.measured - fast.output, noise, rtol=0, atol=1e-15)
    assert fast.final_state.plant[2] == n


def test_noise_is_exposed_not_added(twin):
    np.testing.assert_array_equal(twin.noise_rms(), [5e-4, 0.0])
    s = twin.init()
    np.testing.assert_array_equal(outputs(twin, s), outputs(twin, s))


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"velocity_lag_s": 0.0}, "velocity_lag_s must be positive"),
        ({"speed_limit_m_s": -1.0}, "speed_limit_m_s must be positive"),
        ({"m_squared": 0.5}, "m_squared must be >= 1"),
        ({"gain_v": -0.05}, r"gain_v \(detector gain; > 0 for a minimum at focus\)"),
        ({"wavelength_m": float("nan")}, "wavelength_m"),
        ({"surface_rate_m_s": float("inf")}, "surface_rate_m_s must be finite"),
        ({"quantisation": "yes"}, "quantisation must be true or false"),
        ({"noise_rms_v": -1e-3}, "noise_rms_v must be non-negative"),
        ({"pinhole_m": 1e-5}, "unknown focus parameter"),
    ],
)
def test_bad_parameters_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        lmw_focus_twin(**changes)


def _text() -> str:
    return resources.files("microfab.data").joinpath("lmw_focus.toml").read_text()


def test_data_file_values_have_sources():
    data = tomllib.loads(_text())
    n_values = 0
    for table in data.values():
        for key in table:
            if key.endswith("_source"):
                continue
            n_values += 1
            assert table[f"{key}_source"].startswith(("seed 004 ", "assumed: ")), key
    assert n_values == 15
    assert data["beam"]["wavelength_m_source"].startswith("seed 004 §II.A")
    assert data["beam"]["waist_diameter_m_source"].startswith("seed 004 §II.A")


def test_data_file_strictness(tmp_path):
    text = _text()
    good = tmp_path / "good.toml"
    good.write_text(text)
    assert load_params(good) == load_params()
    cases = {
        r"\[beam\]: unknown key 'pinhole_m'": text.replace(
            "[beam]\n", '[beam]\npinhole_m = 1e-5\npinhole_m_source = "x"\n'
        ),
        "m_squared has no m_squared_source": text.replace("m_squared_source", "m_squared_why"),
        r"unknown section \[axes\]": text + '\n[axes.x]\nk = 1\nk_source = "x"\n',
        r"\[detector\]: missing gain_v": text.replace("gain_v = 0.05\n", ""),
        "waist_diameter_m must be positive": text.replace(
            "waist_diameter_m = 1.08e-5", "waist_diameter_m = -1.08e-5"
        ),
    }
    for want, bad_text in cases.items():
        assert bad_text != text, want
        bad = tmp_path / "bad.toml"
        bad.write_text(bad_text)
        with pytest.raises(ValueError, match=want):
            load_params(bad)
