"""The acoustics with the meniscus as an input: fed the lumped spring, they are the one-way
model; the drive's slopes; the meniscus pressure acts against the outflow."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.plants.printhead import Printhead, nozzle_flow, printhead_state_space
from microfab.plants.printhead_coupled import discrete_acoustics, drive_slopes
from microfab.trajectory.waveform import seed003_waveform

RHO, ETA, SIGMA = 1000.0, 1e-3, 0.072


def _head() -> Printhead:
    return Printhead(gain_m3_per_v=9.67e-15)


def test_fed_the_lumped_spring_the_coupled_acoustics_are_the_one_way_model() -> None:
    # the meniscus counted once: closing the loop with p_m = V_m / C_m gives back the
    # model whose meniscus is the lumped spring (explicit lag of one 50 ns step)
    head = _head()
    ac = discrete_acoustics(head, density_kg_m3=RHO, viscosity_pa_s=ETA)
    n = 4000  # 200 µs
    wave = seed003_waveform(50.0)
    s = drive_slopes(wave, duration_s=n * ac.dt_s, dt_s=ac.dt_s)
    stiffness = 8.0 * SIGMA / (math.pi * head.nozzle_radius_m**4)
    x = np.zeros(ac.phi.shape[0])
    vol, q = 0.0, [0.0]
    for k in range(n):
        x = ac.phi @ x + ac.gamma_drive * s[k] + ac.gamma_pressure * (stiffness * vol)
        qn = float(ac.flow_row @ x)
        vol += 0.5 * (q[-1] + qn) * ac.dt_s
        q.append(qn)
    v = np.array(q) / head.nozzle_area_m2
    ref = nozzle_flow(head, wave, density_kg_m3=RHO, viscosity_pa_s=ETA,
                      surface_tension_n_m=SIGMA, duration_s=n * ac.dt_s)  # fmt: skip
    assert np.max(np.abs(v - ref.velocity_m_s)) < 3e-4 * ref.peak_velocity_m_s


def test_the_meniscus_input_replaces_the_spring_and_pushes_back() -> None:
    a1, b1, _, _ = printhead_state_space(
        _head(), density_kg_m3=RHO, viscosity_pa_s=ETA, surface_tension_n_m=SIGMA
    )
    a2, b2, _c2, d2 = printhead_state_space(
        _head(), density_kg_m3=RHO, viscosity_pa_s=ETA, surface_tension_n_m=SIGMA,
        meniscus_input=True,
    )  # fmt: skip
    assert b2.shape == (a2.shape[0], 2) and d2.shape == (1, 2)
    assert np.count_nonzero(a2[:, -1]) == 0  # nothing reads the meniscus volume any more
    assert np.count_nonzero(a1[:, -1]) == 1  # the spring did
    np.testing.assert_array_equal(b1[:, 0], b2[:, 0])
    # a steady meniscus pressure draws liquid back: the nozzle flow goes negative
    ac = discrete_acoustics(_head(), density_kg_m3=RHO, viscosity_pa_s=ETA)
    x = np.zeros(ac.phi.shape[0])
    for _ in range(200):
        x = ac.phi @ x + ac.gamma_pressure * 1000.0
    assert float(ac.flow_row @ x) < 0.0


def test_drive_slopes_keep_the_voltage_at_the_step_ends() -> None:
    wave = seed003_waveform(50.0)
    dt = 0.07e-6  # corners fall inside steps
    s = drive_slopes(wave, duration_s=100e-6, dt_s=dt)
    v = np.concatenate(([0.0], np.cumsum(s) * dt))
    t = np.arange(s.size + 1) * dt
    np.testing.assert_allclose(v, wave.voltage(t), atol=1e-9)
    with pytest.raises(ValueError, match="dt_s"):
        drive_slopes(wave, duration_s=1e-6, dt_s=0.0)
    with pytest.raises(ValueError, match="dt_s"):
        discrete_acoustics(_head(), density_kg_m3=RHO, viscosity_pa_s=ETA, dt_s=-1.0)
