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
    smooth = lmw_focus_twin(detector_quantisation=False)  # one strict minimum before rounding
    ys = []
    for zk in z:
        s = twin.init()
        s[0] = zk
        ys.append(outputs(smooth, s)[0])
        np.testing.assert_allclose(smooth.output(s)[0], ys[-1], rtol=1e-14)
        np.testing.assert_allclose(twin.output(s)[0], outputs(twin, s)[0], rtol=1e-14)
    ys = np.array(ys)
    i = int(np.argmin(ys))
    assert abs(z[i] - c.focus_position_m) <= 0.5e-6
    assert np.all(np.diff(ys[: i + 1]) < 0) and np.all(np.diff(ys[i:]) > 0)  # one minimum
    # y = offset + y_fs exp(-2 a² / w²), rounded to the converter's count
    cnt = c.adc_count_v
    for zk in (c.focus_position_m, 120e-6, -800e-6):
        s = twin.init()
        s[0] = zk
        w = c.spot_radius_m(zk - c.focus_position_m)
        exact = c.offset_v + c.full_scale_v * math.exp(
            -2.0 * (c.stop_radius_ratio * c.waist_radius_m) ** 2 / w**2
        )
        assert c.detector_v(zk) == pytest.approx(exact, rel=1e-13)
        got = outputs(twin, s)[0]
        assert abs(got - exact) <= 0.5 * cnt + 1e-15
        assert got / cnt == pytest.approx(round(got / cnt), abs=1e-6)


def test_detector_numbers_follow_from_the_components(twin):
    c = twin.config
    # full scale R_f ℜ P: 25 kΩ x 0.6 A/W x 0.5 mW (data file, assumed values)
    assert c.full_scale_v == pytest.approx(2.5e4 * 0.6 * 5e-4, rel=1e-15)
    assert c.adc_count_v == pytest.approx(20.0 / 2**16, rel=1e-15)
    # the disc w0/sqrt 2 maximises the rise at focus: curvature y_fs e^-1 per (Δz/z_R)²
    assert c.curvature_v == pytest.approx(c.full_scale_v / math.e, rel=1e-12)
    dz = 1e-3 * c.rayleigh_range_m
    rise = (c.detector_v(dz) - c.detector_v(0.0)) / (dz / c.rayleigh_range_m) ** 2
    assert rise == pytest.approx(c.curvature_v, rel=1e-5)
    for ratio in (0.5, 0.9):
        assert c.with_(stop_radius_ratio=ratio).curvature_v < c.curvature_v
    # noise budget: RIN, shot and Johnson noise at the focus level, root sum square
    b = c.noise_budget()
    y0 = c.full_scale_v * math.exp(-1.0)
    assert b["rin"] == pytest.approx(y0 * math.sqrt(1e-13 * 5e3), rel=1e-12)
    assert b["shot"] == pytest.approx(
        2.5e4 * math.sqrt(2 * 1.602176634e-19 * y0 / 2.5e4 * 5e3), rel=1e-12
    )
    assert b["johnson"] == pytest.approx(math.sqrt(4 * 1.380649e-23 * 300 * 2.5e4 * 5e3), rel=1e-12)
    parts = (b["rin"], b["shot"], b["johnson"])
    assert b["total"] == pytest.approx(math.sqrt(sum(v * v for v in parts)))
    assert c.noise_rms_v == b["total"]
    assert 40e-6 < b["total"] < 100e-6  # 62.6 µV: below one 305 µV count


def test_moving_focus_plane(twin):
    rate = 1e-5  # 1 mrad tilt under 10 mm/s
    moving = lmw_focus_twin(
        surface_rate_m_s=rate, focus_position_m=20e-6, detector_quantisation=False
    )
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
    noise = np.random.default_rng(5).normal(0.0, 1.0, (n, 2)) * [plant.noise_level.rms[0], 0.0]
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
    assert twin.noise_level.rms == (twin.config.noise_rms_v, 0.0)
    assert twin.noise_level.units == ("V", "m")
    s = twin.init()
    np.testing.assert_array_equal(outputs(twin, s), outputs(twin, s))


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"velocity_lag_s": 0.0}, "velocity_lag_s must be positive"),
        ({"speed_limit_m_s": -1.0}, "speed_limit_m_s must be positive"),
        ({"m_squared": 0.5}, "m_squared must be >= 1"),
        ({"power_w": -1e-3}, "power_w must be positive"),
        ({"stop_radius_ratio": 0.0}, "stop_radius_ratio"),
        ({"rin_db_hz": 3.0}, "rin_db_hz must be negative"),
        ({"adc_bits": 12.0}, "adc_bits"),
        ({"detector_quantisation": 1}, "detector_quantisation must be true or false"),
        ({"transimpedance_ohm": 1e6}, r"outside the converter's ±10 V"),
        ({"wavelength_m": float("nan")}, "wavelength_m"),
        ({"surface_rate_m_s": float("inf")}, "surface_rate_m_s must be finite"),
        ({"quantisation": "yes"}, "quantisation must be true or false"),
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
    assert n_values == 23
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
        r"\[detector\]: missing power_w": text.replace("power_w = 5.0e-4\n", ""),
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
