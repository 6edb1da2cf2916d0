"""PID baseline (seed 001 Fig. 8): tuning rule, margins on eq. 9, kernel == Python, refusals."""

from __future__ import annotations

import numpy as np
import pytest

import control
from microfab.control.base import ReferenceWindow
from microfab.control.margins import loop_margins
from microfab.control.pid import PID, PIDGains, pid_frequency_response
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI, block_diag, discretize
from microfab.sim.loop import simulate, simulate_python

DT = 1e-4  # assumed 10 kHz (shared contract of the seed 001 twin)
# seed 001 eq. (9), mm/V
PX = ((548248.13,), (1.0, 14.88, 101793.23))
PY = ((319852.42,), (1.0, 18.52, 99664.23))


def eq9_plant() -> LTIPlant:
    """Stand-in of the twin: ZOH of eq. 9 per axis (x, y)."""
    return LTIPlant(block_diag(discretize(control.tf(*PX), DT), discretize(control.tf(*PY), DT)))


def circle(n_periods: int, period_s: float = 1.0, radius: float = 0.075) -> tuple:
    """A 0.15 mm circle at 1 Hz (seed 001 §4.2), positions mm, with velocity, acceleration."""
    n = round(period_s / DT) * n_periods
    t = np.arange(n) * DT
    w = 2 * np.pi / period_s
    pos = radius * np.column_stack([np.cos(w * t), np.sin(w * t)])
    vel = radius * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    return pos, vel, -(w**2) * pos


def discrete_loop(g: PIDGains, plant: tuple) -> DiscreteLTI:
    """Open loop of the Tustin PID and the ZOH plant, as a python-control-built model."""
    c = (
        control.tf([g.kp], [1.0], DT)
        + control.tf([g.ki * DT / 2, g.ki * DT / 2], [1.0, -1.0], DT)
        + control.tf([2 * g.kd, -2 * g.kd], [2 * g.tf + DT, -(2 * g.tf - DT)], DT)
    )
    L = control.ss(c) * control.ss(control.c2d(control.tf(*plant), DT, "zoh"))
    return DiscreteLTI(L.A, L.B, L.C, L.D, DT)


@pytest.mark.parametrize("bw, pm", [(200.0, 45.0), (120.0, 60.0)])
def test_tuned_loop_has_the_stated_crossover_and_margin_and_is_stable(bw: float, pm: float):
    pid = PID.tuned([PX, PY], bandwidth_hz=bw, phase_margin_deg=pm, dt=DT)
    for g, plant in zip(pid.gains, (PX, PY), strict=True):
        L = discrete_loop(g, plant)
        m = loop_margins(L)
        assert m.pm_freq_hz == pytest.approx(bw, rel=1e-4)
        assert m.pm_deg == pytest.approx(pm, abs=0.05)
        assert m.gm_db > 6.0  # the rule leaves a gain margin above the crossover
        cl = control.feedback(control.ss(L.A, L.B, L.C, L.D, DT), 1)
        assert np.max(np.abs(control.poles(cl))) < 1.0
        # our frequency response of the kernel's PID is the one python-control builds
        f = np.array([1.0, 50.0, bw, 1000.0])
        Lc = (
            pid_frequency_response(g, f, DT)
            * discretize(control.tf(*plant), DT).frequency_response(f)[:, 0, 0]
        )
        np.testing.assert_allclose(Lc, L.frequency_response(f)[:, 0, 0], rtol=1e-9)
    # feedforward gains are the model inverse (a0, a1, 1) / K
    gx = pid.gains[0]
    assert gx.ff == pytest.approx((101793.23 / 548248.13, 14.88 / 548248.13, 1 / 548248.13))


def test_kernel_and_python_step_agree():
    rng = np.random.default_rng(1)
    gains = [
        PIDGains(kp=1.3, ki=40.0, kd=2e-3, tf=1e-4, ff=(0.2, 3e-5, 2e-6)),
        PIDGains(kp=0.7, ki=0.0, kd=0.0, tf=5e-4, ff=(0.3, 6e-5, 3e-6)),
    ]
    for ff in (False, True):
        pid = PID(gains=gains, dt=DT, feedforward=ff)
        n = 300
        R = rng.normal(size=(n, 3, 2))
        ym = rng.normal(size=(n, 2))
        xs, xk = pid.init(), pid.init()
        u = np.empty(2)
        for k in range(n):
            up, xs = pid.step(xs, ReferenceWindow.from_array(R[k : k + 1]), ym[k])
            PID.kernel_step(pid.params, xk, R, k, ym[k], u)
            np.testing.assert_allclose(u, up, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(xk, xs, rtol=1e-12, atol=1e-12)


def test_tracks_the_circle_as_its_sensitivity_predicts():
    pid = PID.tuned([PX, PY], bandwidth_hz=200.0, phase_margin_deg=45.0, dt=DT)
    pos, vel, acc = circle(3)
    res = simulate(eq9_plant(), pid, pos, derivatives=(vel, acc))
    e = res.reference - res.output
    last = e[-10000:]
    # steady state: amplitude |S(j 2 pi 1 Hz)| * 0.075 mm per axis
    for a, (g, plant) in enumerate(zip(pid.gains, (PX, PY), strict=True)):
        L = discrete_loop(g, plant).frequency_response(np.array([1.0]))[0, 0, 0]
        amp = abs(1.0 / (1.0 + L)) * 0.075
        assert np.sqrt(np.mean(last[:, a] ** 2)) == pytest.approx(amp / np.sqrt(2), rel=1e-3)
    rms = np.sqrt(np.mean(np.sum(last**2, axis=1)))
    assert rms < 1e-3  # sub-micron on the linear stand-in
    # the model-inverse feedforward removes most of the remaining error
    pid_ff = PID(gains=pid.gains, dt=DT, feedforward=True)
    res_ff = simulate(eq9_plant(), pid_ff, pos, derivatives=(vel, acc))
    e_ff = (res_ff.reference - res_ff.output)[-10000:]
    assert np.sqrt(np.mean(np.sum(e_ff**2, axis=1))) < rms / 10


def test_compiled_and_python_loops_agree():
    pid = PID.tuned([PX, PY], bandwidth_hz=200.0, phase_margin_deg=45.0, dt=DT, feedforward=True)
    pos, vel, acc = circle(1, period_s=0.02)
    a = simulate(eq9_plant(), pid, pos, derivatives=(vel, acc))
    b = simulate_python(eq9_plant(), pid, pos, derivatives=(vel, acc))
    np.testing.assert_allclose(a.command, b.command, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a.output, b.output, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kp": -1.0}, "kp must be non-negative"),
        ({"ki": float("nan")}, "ki must be non-negative and finite, got nan"),
        ({"tf": 0.0}, r"tf \(derivative filter time constant\) must be positive"),
        ({"ff": (0.0, 1.0)}, "ff must hold 3"),
        ({"ff": (0.0, float("inf"), 0.0)}, "feedforward gain f1 must be finite"),
    ],
)
def test_gains_refused(kwargs: dict, match: str):
    base = {"kp": 1.0, "ki": 1.0, "kd": 0.0, "tf": 1e-3}
    with pytest.raises(ValueError, match=match):
        PIDGains(**(base | kwargs))


def test_design_refusals():
    with pytest.raises(ValueError, match=r"phase_margin_deg must lie in \(0, 90\)"):
        PIDGains.design(PX, bandwidth_hz=200.0, phase_margin_deg=95.0)
    with pytest.raises(ValueError, match=r"cannot be reached at bandwidth_hz = 200\.0 Hz"):
        PIDGains.design(PX, bandwidth_hz=200.0, phase_margin_deg=85.0, filter_ratio=2.0)
    with pytest.raises(ValueError, match="bandwidth_hz must lie below a quarter"):
        PIDGains.design(PX, bandwidth_hz=3000.0)
    with pytest.raises(ValueError, match="bandwidth_hz must be positive"):
        PIDGains.design(PX, bandwidth_hz=float("nan"))
    with pytest.raises(ValueError, match="integral_ratio and filter_ratio must exceed 1"):
        PIDGains.design(PX, bandwidth_hz=200.0, integral_ratio=0.5)
    with pytest.raises(ValueError, match="one value or one per axis"):
        PID.tuned([PX, PY], bandwidth_hz=[100.0])
    with pytest.raises(ValueError, match="non-empty sequence of PIDGains"):
        PID(gains=[], dt=DT)
    with pytest.raises(ValueError, match="dt must be positive"):
        PID(gains=[PIDGains(kp=1.0, ki=0.0, kd=0.0, tf=1.0)], dt=0.0)
