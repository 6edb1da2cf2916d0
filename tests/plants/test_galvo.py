"""Tests of the galvo scanner twin (seed 000 §2-3.1)."""

from __future__ import annotations

import dataclasses
import re
import tomllib
from importlib import resources

import numpy as np
import pytest

from microfab.control.margins import loop_margins
from microfab.machines.galvo.machine import (
    complementary_sensitivity,
    controller_tf,
    discrete_controller,
    open_loop,
)
from microfab.plants.galvo import FS_HZ, GalvoAxis, default_galvo_axes
from microfab.sim.lti_fast import closed_loop_ss

CROSSOVER_HZ = 2000.0  # seed 000 §3.1: w_c = 2 pi 2000


@pytest.fixture(scope="module")
def axes() -> dict[str, GalvoAxis]:
    return default_galvo_axes()


@pytest.fixture(scope="module")
def margins(axes):
    return {name: loop_margins(open_loop(ax)) for name, ax in axes.items()}


def test_default_axes_carry_seed_constants(axes):
    assert tuple(axes) == ("x", "y")
    # seed 000 §3.1: resonances of x at 31.26/41.70 kHz and of y at 25.71/31.55 kHz
    assert axes["x"].resonances_hz == pytest.approx((31.26e3, 41.70e3))
    assert axes["y"].resonances_hz == pytest.approx((25.71e3, 31.55e3))
    # seed 000 §4.3: the 0.6 mm square is 1 V (x) and 1.44 V (y) of encoder signal
    assert axes["x"].amplitude_v == 1.0
    assert axes["y"].amplitude_v == 1.44
    # seed 000 §4.2: 0.3 mm/V, so that 1 V of x is the 0.3 mm half side; y keeps 0.3 mm
    assert axes["x"].amplitude_v * axes["x"].scale_mm_per_v == pytest.approx(0.3)
    assert axes["y"].amplitude_v * axes["y"].scale_mm_per_v == pytest.approx(0.3)
    for ax in axes.values():
        assert ax.fs_hz == FS_HZ == 1e6  # seed 000 §3.1: 1 Msps
        assert ax.crossover_hz == CROSSOVER_HZ
        assert ax.dt == pytest.approx(1e-6)


def test_default_axes_load_calibration_file(axes):
    text = resources.files("microfab.data").joinpath("galvo_twin.toml").read_text()
    cal = tomllib.loads(text)["axes"]
    for name, ax in axes.items():
        assert ax.name == name
        assert ax.rigid_pole_hz == float(cal[name]["rigid_pole_hz"])
        assert ax.gain_ratio == float(cal[name]["gain_ratio"])
        assert ax.noise_rms_v == float(cal[name]["noise_rms_v"])
        assert ax.noise_rms_v > 0


def test_calibration_file_is_sourced_and_read_from_a_path(tmp_path):
    text = resources.files("microfab.data").joinpath("galvo_twin.toml").read_text()
    data = tomllib.loads(text)["axes"]
    for name in ("x", "y"):
        for key in ("rigid_pole_hz", "gain_ratio", "noise_rms_v"):
            assert data[name][f"{key}_source"].startswith("calibrated: `microfab calibrate galvo`")
    copy = tmp_path / "twin.toml"
    copy.write_text(re.sub(r"(?m)^rigid_pole_hz = .*$", "rigid_pole_hz = 99.0", text, count=1))
    assert default_galvo_axes(copy)["x"].rigid_pole_hz == 99.0
    # a value without its source is refused, naming the file, the axis and the key
    lines = [ln for ln in text.splitlines() if not ln.startswith("gain_ratio_source")]
    copy.write_text("\n".join(lines))
    with pytest.raises(ValueError, match=r"axes\.x\].*gain_ratio has no gain_ratio_source"):
        default_galvo_axes(copy)
    # a value the axis refuses names the file and the axis
    y = text.index("[axes.y]")
    copy.write_text(text[:y] + re.sub(r"(?m)^noise_rms_v = .*$", "noise_rms_v = -1.0", text[y:]))
    with pytest.raises(ValueError, match=r"twin\.toml \[axes\.y\].*noise_rms_v"):
        default_galvo_axes(copy)


def test_nominal_design_crosses_over_at_2khz(axes):
    # eq. (1) normalises |C G| = 1 at w_c on the nominal model (gain_ratio 1); the discrete
    # loop (Tustin controller, ZOH plant, one sample delay) keeps it within a few percent.
    for ax in axes.values():
        m = loop_margins(open_loop(ax.with_calibration(gain_ratio=1.0)), n_points=20_000)
        assert m.pm_freq_hz == pytest.approx(CROSSOVER_HZ, rel=0.05), (ax.name, m.pm_freq_hz)


def test_calibrated_open_loop_crossover_near_2khz(axes, margins):
    # seed 000 §3.1 / Fig. 3: bandwidth designed at 2 kHz; the calibrated gain ratio moves
    # the crossover with it, but it stays in 1.5-2.8 kHz.
    for name, ax in axes.items():
        fc = margins[name].pm_freq_hz
        assert 1500.0 <= fc <= 2800.0, (name, fc, ax.gain_ratio)
        # and |L| = 1 there
        L = open_loop(ax).frequency_response(np.array([fc]))[0, 0, 0]
        assert abs(L) == pytest.approx(1.0, rel=1e-3)
        # crossover moves in the direction of the gain ratio
        assert (fc - CROSSOVER_HZ) * (ax.gain_ratio - 1.0) > 0


def test_margins_are_positive(margins):
    for name, m in margins.items():
        assert m.pm_deg > 30.0, (name, m.pm_deg)
        assert m.gm_db > 6.0, (name, m.gm_db)


def test_closed_loop_is_stable(axes):
    for ax in axes.values():
        cl = closed_loop_ss(ax.discrete_plant(), discrete_controller(ax))
        assert np.max(np.abs(cl.poles())) < 1.0
        # the plant alone is only marginally stable (rigid body integrator)
        assert np.max(np.abs(ax.discrete_plant().poles())) == pytest.approx(1.0, abs=1e-9)


def test_complementary_sensitivity_is_one_at_low_frequency(axes):
    for ax in axes.values():
        T = complementary_sensitivity(ax, np.array([0.0, 10.0]))
        assert abs(T[0] - 1.0) < 1e-9  # pole of L at DC
        assert abs(T[1] - 1.0) < 1e-3
        # and rolls off well above the crossover
        assert abs(complementary_sensitivity(ax, np.array([20e3]))[0]) < 0.3


def test_complementary_sensitivity_matches_loop(axes):
    ax = axes["x"]
    f = np.array([100.0, 1000.0, 5000.0])
    L = open_loop(ax).frequency_response(f)[:, 0, 0]
    np.testing.assert_allclose(complementary_sensitivity(ax, f), L / (1 + L), rtol=1e-12)
    # shape follows the input
    assert complementary_sensitivity(ax, np.full((2, 3), 50.0)).shape == (2, 3)


def test_model_structure(axes):
    ax = axes["y"]
    # rigid body (2) + amplifier (1) + 2 modes (2 each) = 7 states; +1 delay state
    assert ax.model().nstates == 7
    assert ax.discrete_plant().n_states == 7 + ax.delay_samples
    # gain_ratio scales the model
    f = 1000.0
    s = 2j * np.pi * f
    g1 = ax.model(gain_ratio=1.0)(s)
    g2 = ax.model(gain_ratio=2.0)(s)
    assert complex(g2) == pytest.approx(2 * complex(g1), rel=1e-9)
    # the controller is designed on the nominal model, independent of gain_ratio
    c1 = controller_tf(ax.with_calibration(gain_ratio=0.5))(s)
    c2 = controller_tf(ax.with_calibration(gain_ratio=2.0))(s)
    assert complex(c1) == pytest.approx(complex(c2), rel=1e-12)


def test_with_calibration_returns_copy(axes):
    ax = axes["x"]
    new = ax.with_calibration(noise_rms_v=0.0)
    assert new.noise_rms_v == 0.0
    assert ax.noise_rms_v > 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        ax.noise_rms_v = 1.0  # type: ignore[misc]


BASE = {
    "name": "x",
    "resonances_hz": (31.26e3, 41.70e3),  # seed 000 §3.1
    "amplitude_v": 1.0,
    "scale_mm_per_v": 0.3,
    "rigid_pole_hz": 100.0,
}


def test_valid_axis_builds():
    ax = GalvoAxis(**BASE)
    assert ax.gain_ratio == 1.0
    GalvoAxis(**{**BASE, "rigid_pole_hz": 0.0})  # a pure double integrator is allowed


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("rigid_pole_hz", -1.0, "rigid_pole_hz"),
        ("rigid_pole_hz", np.nan, "rigid_pole_hz"),
        ("gain_ratio", 0.0, "gain_ratio"),
        ("gain_ratio", -1.0, "gain_ratio"),
        ("resonance_damping", 0.0, "resonance_damping"),
        ("amplifier_bandwidth_hz", -5.0, "amplifier_bandwidth_hz"),
        ("amplitude_v", 0.0, "amplitude_v"),
        ("amplitude_v", np.inf, "amplitude_v"),
        ("scale_mm_per_v", -0.3, "scale_mm_per_v"),
        ("crossover_hz", 0.0, "crossover_hz"),
        ("fs_hz", np.nan, "fs_hz"),
        ("resonances_hz", (31e3, 600e3), "resonances"),
        ("resonances_hz", (-1.0,), "resonances"),
        ("noise_rms_v", -1e-3, "noise_rms_v"),
        ("delay_samples", -1, "delay_samples"),
    ],
)
def test_axis_validation(field, value, match):
    with pytest.raises(ValueError, match=match):
        GalvoAxis(**{**BASE, field: value})
