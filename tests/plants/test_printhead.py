from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import cumulative_trapezoid, solve_ivp
from scipy.optimize import brentq

from microfab.plants import printhead as acoustics
from microfab.plants.printhead import (
    NozzleFlow,
    Printhead,
    calibrate_gain,
    nozzle_flow,
    printhead_state_space,
)
from microfab.process.inkjet.dispenser import default_printhead
from microfab.trajectory.waveform import Waveform, seed003_waveform

US = 1e-6
WATER = {"density_kg_m3": 1000.0, "viscosity_pa_s": 1e-3, "surface_tension_n_m": 0.072}


def _mode_frequencies_hz(head: Printhead, **fluid: float) -> np.ndarray:
    a_mat, *_ = printhead_state_space(head, **fluid)
    lam = np.linalg.eigvals(a_mat)
    return np.sort(lam.imag[lam.imag > 1.0]) / (2 * math.pi)


# --- (a) resonances against closed-form acoustics -------------------------------------


def test_closed_nozzle_limit_is_a_quarter_wave_resonator() -> None:
    # A tiny, long nozzle has a huge inertance: the nozzle end is closed, the reservoir end
    # is p = 0, so f_n = (2n - 1) c / (4 L).
    head = Printhead(
        nozzle_radius_m=2e-6, nozzle_length_m=1e-3, inlet_impedance_ratio=0.0, cells=30
    )
    f = _mode_frequencies_hz(
        head, density_kg_m3=1000.0, viscosity_pa_s=0.0, surface_tension_n_m=0.0
    )
    c, length = head.wave_speed_m_s, head.channel_length_m
    assert f[0] == pytest.approx(c / (4 * length), rel=0.02)
    assert f[1] == pytest.approx(3 * c / (4 * length), rel=0.02)
    assert c / (4 * length) == pytest.approx(1 / (4 * 30 * US))  # L / c = seed dwell


def test_open_nozzle_limit_is_a_half_wave_resonator() -> None:
    # A nozzle as wide as the channel and vanishingly short, no surface tension: both ends
    # are pressure-release, f_n = n c / (2 L).
    head = Printhead(
        nozzle_radius_m=0.24e-3, nozzle_length_m=1e-7, inlet_impedance_ratio=0.0, cells=30
    )
    f = _mode_frequencies_hz(
        head, density_kg_m3=1000.0, viscosity_pa_s=0.0, surface_tension_n_m=0.0
    )
    c, length = head.wave_speed_m_s, head.channel_length_m
    assert f[0] == pytest.approx(c / (2 * length), rel=0.02)
    assert f[1] == pytest.approx(c / length, rel=0.02)


def test_lossless_modes_match_the_dispersion_relation() -> None:
    # Tube p(0) = 0, lumped nozzle mass M_n and meniscus stiffness K at z = L:
    #   ρ ω² sin(kL) + A k (ω² M_n - K) cos(kL) = 0,  k = ω / c.
    head = Printhead(inlet_impedance_ratio=0.0)
    rho, sigma = 1000.0, 0.072
    c, length = head.wave_speed_m_s, head.channel_length_m
    area = math.pi * head.channel_radius_m**2
    m_n = rho * head.nozzle_length_m / (math.pi * head.nozzle_radius_m**2)
    stiff = 8 * sigma / (math.pi * head.nozzle_radius_m**4)

    def g(f_hz: float) -> float:
        w = 2 * math.pi * f_hz
        k = w / c
        return rho * w * w * math.sin(k * length) + area * k * (w * w * m_n - stiff) * math.cos(
            k * length
        )

    grid = np.linspace(10.0, 40e3, 8001)
    vals = np.array([g(x) for x in grid])
    brackets = np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))
    roots = np.array([brentq(g, grid[i], grid[i + 1]) for i in brackets])
    f = _mode_frequencies_hz(head, density_kg_m3=rho, viscosity_pa_s=0.0, surface_tension_n_m=sigma)
    assert roots.size == 3  # meniscus (Helmholtz) mode + two channel modes below 40 kHz
    np.testing.assert_allclose(f[:3], roots, rtol=2e-3)
    # the lowest mode is the liquid column swinging on the meniscus spring
    helmholtz = 1 / (2 * math.pi * math.sqrt((rho * length / area + m_n) / stiff))
    assert f[0] == pytest.approx(helmholtz, rel=0.05)


def test_lossless_without_inlet_loss_has_undamped_modes() -> None:
    head = Printhead(inlet_impedance_ratio=0.0, cells=20)
    a_mat, *_ = printhead_state_space(
        head, density_kg_m3=1000.0, viscosity_pa_s=0.0, surface_tension_n_m=0.072
    )
    lam = np.linalg.eigvals(a_mat)
    assert np.max(np.abs(lam.real)) < 1e-6 * np.max(np.abs(lam.imag))
    lossy, *_ = printhead_state_space(head, **WATER)
    assert np.max(np.linalg.eigvals(lossy).real) < 0


# --- (b) ZOH discretisation against an implicit ODE solver -----------------------------


def test_zoh_matches_radau() -> None:
    head = dataclasses.replace(default_printhead(), cells=12)
    wave = seed003_waveform(50.0)
    duration = 120 * US
    flow = nozzle_flow(head, wave, **WATER, duration_s=duration)
    a_mat, b_mat, c_mat, _ = printhead_state_space(head, **WATER)
    n = head.cells
    # integrate in scaled states (1e5 Pa, 1e-8 m³/s, 1e-13 m³): one atol suits them all
    scale = np.concatenate([np.full(n, 1e5), np.full(n + 1, 1e-8), [1e-13]])
    a_s = a_mat * scale[None, :] / scale[:, None]
    b_s = b_mat[:, 0] / scale

    corners = np.append(wave.breakpoints()[0], duration)
    x = np.zeros(a_mat.shape[0])
    t_out, y_out = [], []
    for t0, t1 in itertools.pairwise(corners):
        u = float(wave.slope(0.5 * (t0 + t1)))
        mask = (flow.t_s >= t0) & (flow.t_s < t1)
        sol = solve_ivp(
            lambda _t, z, u=u: a_s @ z + b_s * u,
            (t0, t1),
            x,
            method="Radau",
            jac=a_s,
            rtol=1e-8,
            atol=1e-12,
            t_eval=np.append(flow.t_s[mask], t1),
        )
        assert sol.success
        t_out.append(sol.t[:-1])
        y_out.append((c_mat[0] * scale) @ sol.y[:, :-1] / head.nozzle_area_m2)
        x = sol.y[:, -1]
    y_ref = np.concatenate(y_out)
    assert np.concatenate(t_out).size == flow.t_s.size - 1
    err = np.max(np.abs(flow.velocity_m_s[:-1] - y_ref))
    assert err <= 1e-6 * np.max(np.abs(y_ref))


def test_matches_scipy_lsim_of_the_state_space() -> None:
    head = dataclasses.replace(default_printhead(), cells=20)
    wave = seed003_waveform(45.0)
    flow = nozzle_flow(head, wave, **WATER, duration_s=150 * US, dt_s=100e-9)
    a_mat, b_mat, c_mat, d_mat = printhead_state_space(head, **WATER)
    sys = signal.StateSpace(a_mat, b_mat, c_mat / head.nozzle_area_m2, d_mat)
    # dV/dt is constant over each step (corners on the 100 ns grid): ZOH input per step
    u = wave.slope(flow.t_s + 50e-9)
    _, y, _ = signal.lsim(sys, u, flow.t_s, interp=False)
    np.testing.assert_allclose(flow.velocity_m_s, y, atol=1e-8 * np.max(np.abs(y)))


# --- (c) linearity ----------------------------------------------------------------------


def test_velocity_is_linear_in_amplitude() -> None:
    head = default_printhead()
    u40 = nozzle_flow(head, seed003_waveform(40.0), **WATER).velocity_m_s
    u70 = nozzle_flow(head, seed003_waveform(70.0), **WATER).velocity_m_s
    np.testing.assert_allclose(u70, 70.0 / 40.0 * u40, rtol=0, atol=1e-12 * np.abs(u70).max())


def test_polarity_convention_mirrors_the_flow() -> None:
    head = default_printhead()
    flipped = dataclasses.replace(head, positive_voltage_expands=False)
    wave = seed003_waveform()
    u = nozzle_flow(head, wave, **WATER).velocity_m_s
    u_flipped = nozzle_flow(flipped, wave, **WATER).velocity_m_s
    np.testing.assert_allclose(u_flipped, -u, atol=1e-12 * np.abs(u).max())


# --- (d) displacement consistent with velocity ----------------------------------------


def test_displacement_is_the_integral_of_velocity() -> None:
    flow = nozzle_flow(default_printhead(), seed003_waveform(), **WATER, duration_s=120 * US)
    ref = cumulative_trapezoid(flow.velocity_m_s, flow.t_s, initial=0.0)
    np.testing.assert_allclose(flow.displacement_m, ref, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(flow.displacement(flow.t_s), ref, rtol=1e-12, atol=1e-18)

    rng = np.random.default_rng(3)
    t = rng.uniform(0.0, flow.t_s[-1], 400)
    h = 1e-3 * flow.dt_s  # stays inside one interval almost surely; quadratic => exact
    k = np.floor(t / flow.dt_s)
    t = np.clip(t, (k + 0.01) * flow.dt_s, (k + 0.99) * flow.dt_s)
    fd = (flow.displacement(t + h) - flow.displacement(t - h)) / (2 * h)
    np.testing.assert_allclose(fd, flow.velocity(t), rtol=0, atol=1e-7 * flow.peak_velocity_m_s)
    # velocity interpolates linearly between samples
    mid = 0.5 * (flow.t_s[:-1] + flow.t_s[1:])
    np.testing.assert_allclose(
        flow.velocity(mid),
        0.5 * (flow.velocity_m_s[:-1] + flow.velocity_m_s[1:]),
        rtol=1e-12,
        atol=1e-12 * flow.peak_velocity_m_s,
    )
    vol = flow.volume_m3(flow.t_s[-1])
    assert vol == pytest.approx(math.pi * flow.nozzle_radius_m**2 * ref[-1], rel=1e-12)


def test_before_start_is_zero_and_after_end_raises() -> None:
    flow = nozzle_flow(default_printhead(), seed003_waveform(), **WATER, duration_s=80 * US)
    np.testing.assert_array_equal(flow.velocity([-1.0, -1e-9]), [0.0, 0.0])
    np.testing.assert_array_equal(flow.displacement([-1.0]), [0.0])
    assert float(flow.velocity(80 * US)) == pytest.approx(flow.velocity_m_s[-1])
    with pytest.raises(ValueError, match="beyond the end"):
        flow.velocity(81 * US)
    with pytest.raises(ValueError, match="beyond the end"):
        flow.displacement(np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match="beyond the end"):
        flow.volume_m3(float("nan"))


# --- (e) viscosity ----------------------------------------------------------------------


def test_higher_viscosity_lowers_the_peak_velocity() -> None:
    head = default_printhead()
    peaks = [
        nozzle_flow(
            head,
            seed003_waveform(),
            density_kg_m3=1000.0,
            viscosity_pa_s=eta,
            surface_tension_n_m=0.072,
        ).peak_velocity_m_s
        for eta in (1e-3, 1e-2, 5e-2, 2e-1)
    ]
    assert all(a > b for a, b in itertools.pairwise(peaks))
    assert peaks[-1] < 0.7 * peaks[0]


# --- (f) calibration --------------------------------------------------------------------


def test_calibrate_gain_hits_the_target() -> None:
    head = Printhead(cells=30, gain_m3_per_v=3e-13)
    wave = seed003_waveform(60.0)
    cal = calibrate_gain(head, wave, **WATER, target_peak_velocity_m_s=5.5)
    assert dataclasses.replace(cal, gain_m3_per_v=head.gain_m3_per_v) == head
    peak = nozzle_flow(cal, wave, **WATER).peak_velocity_m_s
    assert peak == pytest.approx(5.5, rel=1e-9)


# --- (g) seed operating point -----------------------------------------------------------


def test_seed_waveform_ejects_during_the_echo_plateau() -> None:
    head = default_printhead()
    flow = nozzle_flow(head, seed003_waveform(50.0), **WATER)
    assert 1.0 < flow.peak_velocity_m_s < 20.0
    # fill-before-fire: inflow while the tube is held expanded, main jet after the fall
    t = flow.t_s
    assert np.all(flow.velocity_m_s[(t > 8 * US) & (t < 30 * US)] < 0)
    t_peak = t[np.argmax(flow.velocity_m_s)]
    assert 36 * US < t_peak < 69 * US
    # the ejected volume is of the order of an orifice-sized drop (0.1 to 10 nL)
    vol = float(flow.volume_m3(69 * US) - flow.volume_m3(33 * US))
    assert 1e-13 < vol < 1e-11


def test_bogy_talke_dwell_near_acoustic_travel_time_is_near_optimal() -> None:
    head = dataclasses.replace(default_printhead(), cells=30)
    dwells = np.array([5, 15, 30, 45, 60]) * US
    peaks = np.array(
        [
            nozzle_flow(
                head,
                Waveform(kind="unipolar", amplitude_v=50.0, dwell_s=d),
                **WATER,
                duration_s=d + 60 * US,
                dt_s=100e-9,
            ).peak_velocity_m_s
            for d in dwells
        ]
    )
    assert head.travel_time_s == pytest.approx(30 * US)
    assert peaks[2] >= 0.95 * peaks.max()
    assert peaks[2] > 1.3 * peaks[0] and peaks[2] > 1.3 * peaks[-1]


# --- (h) ring-down ----------------------------------------------------------------------


def test_residual_oscillation_decays() -> None:
    head = default_printhead()
    rho, sigma = 1000.0, 0.072
    wave = seed003_waveform(50.0)
    a_mat, b_mat, c_mat, d_mat = printhead_state_space(head, **WATER)
    dt = 100e-9
    t = np.arange(3001) * dt  # 0 to 300 µs
    _, _, x = signal.lsim(
        signal.StateSpace(a_mat, b_mat, c_mat, d_mat), wave.slope(t + dt / 2), t, interp=False
    )
    n = head.cells
    dz = head.channel_length_m / n
    area = math.pi * head.channel_radius_m**2
    c = head.wave_speed_m_s
    cell_c = area * dz / (rho * c * c)
    face_m = np.full(n, rho * dz / area)
    face_m[0] /= 2
    m_t = rho * head.nozzle_length_m / (math.pi * head.nozzle_radius_m**2) + rho * dz / area / 2
    stiff = 8 * sigma / (math.pi * head.nozzle_radius_m**4)
    energy = 0.5 * (
        cell_c * np.sum(x[:, :n] ** 2, axis=1)
        + np.sum(face_m * x[:, n : 2 * n] ** 2, axis=1)
        + m_t * x[:, 2 * n] ** 2
        + stiff * x[:, 2 * n + 1] ** 2
    )
    assert energy[-1] < 0.05 * energy.max()
    # no energy enters once the drive is off: it only decreases
    after = energy[t > wave.duration_s]
    assert np.all(np.diff(after) <= 1e-12 * energy.max())


# --- (i) validation ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"nozzle_radius_m": 0.0}, "nozzle_radius_m"),
        ({"nozzle_radius_m": 0.3e-3}, "smaller than channel_radius_m"),
        ({"nozzle_length_m": -1e-6}, "nozzle_length_m"),
        ({"channel_radius_m": float("nan")}, "channel_radius_m"),
        ({"channel_length_m": 0.0}, "channel_length_m"),
        ({"wave_speed_m_s": -1200.0}, "wave_speed_m_s"),
        ({"gain_m3_per_v": 0.0}, "gain_m3_per_v"),
        ({"inlet_impedance_ratio": -0.1}, "inlet_impedance_ratio"),
        ({"actuator_start_fraction": 0.8, "actuator_end_fraction": 0.2}, "actuator"),
        ({"actuator_end_fraction": 1.2}, "actuator"),
        ({"cells": 3}, "cells"),
        ({"cells": 10.0}, "cells"),
    ],
)
def test_printhead_validation(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Printhead(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("fluid", "match"),
    [
        ({"density_kg_m3": 0.0}, "density_kg_m3"),
        ({"viscosity_pa_s": -1e-3}, "viscosity_pa_s"),
        ({"surface_tension_n_m": -0.01}, "surface_tension_n_m"),
    ],
)
def test_fluid_validation(fluid: dict[str, float], match: str) -> None:
    args = {**WATER, **fluid}
    with pytest.raises(ValueError, match=match):
        printhead_state_space(Printhead(cells=8), **args)
    with pytest.raises(ValueError, match=match):
        nozzle_flow(Printhead(cells=8), seed003_waveform(), **args)


def test_run_and_calibration_validation() -> None:
    head = Printhead(cells=8)
    wave = seed003_waveform()
    with pytest.raises(ValueError, match="duration_s"):
        nozzle_flow(head, wave, **WATER, duration_s=0.0)
    with pytest.raises(ValueError, match="dt_s"):
        nozzle_flow(head, wave, **WATER, dt_s=-1e-9)
    with pytest.raises(ValueError, match="at least one step"):
        nozzle_flow(head, wave, **WATER, duration_s=1e-9, dt_s=5e-8)
    with pytest.raises(ValueError, match="target_peak_velocity_m_s"):
        calibrate_gain(head, wave, **WATER, target_peak_velocity_m_s=0.0)


def test_nozzle_flow_record_validation() -> None:
    t = np.array([0.0, 1.0, 2.0])
    ok = {"velocity_m_s": np.zeros(3), "displacement_m": np.zeros(3), "nozzle_radius_m": 1e-4}
    with pytest.raises(ValueError, match="uniform"):
        NozzleFlow(t_s=np.array([0.0, 1.0, 3.0]), **ok)
    with pytest.raises(ValueError, match="uniform"):
        NozzleFlow(t_s=t + 1.0, **ok)
    with pytest.raises(ValueError, match="same shape"):
        NozzleFlow(
            t_s=t, velocity_m_s=np.zeros(2), displacement_m=np.zeros(3), nozzle_radius_m=1e-4
        )
    with pytest.raises(ValueError, match="nozzle_radius_m"):
        NozzleFlow(t_s=t, velocity_m_s=np.zeros(3), displacement_m=np.zeros(3), nozzle_radius_m=0)
    flow = NozzleFlow(t_s=t, **ok)
    with pytest.raises(ValueError):
        flow.velocity_m_s[0] = 1.0  # read-only


def test_near_defective_model_uses_the_doubling_route_accurately() -> None:
    # Lossless, no surface tension, ideal p = 0 inlet: a uniform flow through the channel
    # is a free (Jordan-block) mode, so the eigenvectors are near-singular.
    head = Printhead(cells=16, inlet_impedance_ratio=0.0, gain_m3_per_v=1e-14)
    fluid = {"density_kg_m3": 1000.0, "viscosity_pa_s": 0.0, "surface_tension_n_m": 0.0}
    a_bal, b_bal, c_bal = acoustics._balanced_model(head, *fluid.values())
    assert acoustics._markov_modal(a_bal, b_bal, c_bal, 1e-7, 10) is None
    wave = seed003_waveform()
    flow = nozzle_flow(head, wave, **fluid, duration_s=150 * US, dt_s=100e-9)
    a_mat, b_mat, c_mat, d_mat = printhead_state_space(head, **fluid)
    sys = signal.StateSpace(a_mat, b_mat, c_mat / head.nozzle_area_m2, d_mat)
    _, y, _ = signal.lsim(sys, wave.slope(flow.t_s + 50e-9), flow.t_s, interp=False)
    np.testing.assert_allclose(flow.velocity_m_s, y, atol=1e-8 * np.max(np.abs(y)))


def test_the_scalar_path_is_the_array_path_bit_for_bit() -> None:
    # NozzleFlow.at repeats the arithmetic of velocity/displacement without the array
    # overhead; the jet solvers' results depend on every bit, so the two must agree exactly
    flow = nozzle_flow(default_printhead(), seed003_waveform(50.0), density_kg_m3=1000.0,
                       viscosity_pa_s=2e-3, surface_tension_n_m=0.07)  # fmt: skip
    rng = np.random.default_rng(3)
    times = np.concatenate(([-1e-6, 0.0, flow.t_s[-1]], flow.t_s[::97], rng.random(300) * 3e-4))
    for t in times:
        v, x = flow.at(float(t))
        assert v == float(flow.velocity(t)) and x == float(flow.displacement(t)), t
    with pytest.raises(ValueError, match="beyond the end"):
        flow.at(flow.t_s[-1] + 1e-6)
    with pytest.raises(ValueError, match="beyond the end"):
        flow.at(float("nan"))
