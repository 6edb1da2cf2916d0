"""Sliding-mode focus search (seed 004 eqs. 16-17): the continuous sign and relay, both
laws reaching focus from 500 µm, the continuous law's steady oscillation against the
discontinuous one's, kernel == Python, refusals."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numba import njit

from microfab.control.focus import (
    SlidingModeFocus,
    SlidingModeFocusConfig,
    chi,
    chi_scalar,
    dark_field_area,
    dark_field_area_scalar,
    relay,
    relay_scalar,
)
from microfab.plants.base import CompiledPlant
from microfab.sim.loop import simulate, simulate_python

DT = 1e-4  # assumed 10 kHz
Z_R = 86e-6  # m, Rayleigh length of the stand-in (task brief)
HALF_DOF = 27e-6  # m: half the 54 µm depth of focus, seed 004 §II-A
TAU = 5e-3  # s, velocity lag of the stand-in z stage (assumed)
NOISE = 5e-5  # detector noise RMS, units of the detector gain (assumed: small)


@njit(cache=True)
def _fp_output(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    d = (x[0] - p[3]) / p[4]
    y[0] = p[1] + p[2] * (1.0 + d * d)
    y[1] = x[0]


@njit(cache=True)
def _fp_update(p: np.ndarray, x: np.ndarray, u: np.ndarray) -> None:
    # z stage with a velocity lag, exact over the sample for a held command
    a, tau, dt = p[5], p[6], p[0]
    v = x[1]
    x[0] += u[0] * dt + tau * (1.0 - a) * (v - u[0])
    x[1] = a * v + (1.0 - a) * u[0]


class FocusStandIn(CompiledPlant):
    """``y = offset + gain (1 + ((z − z_f)/z_R)²)``, outputs ``(y, z)``; command ż (m/s)."""

    kernel_output: Any = _fp_output
    kernel_update: Any = _fp_update

    def __init__(self, z0: float, z_focus: float = 0.0, offset: float = 0.1) -> None:
        self.params = np.array([DT, offset, 1.0, z_focus, Z_R, math.exp(-DT / TAU), TAU])
        self.z0 = z0
        self.n_inputs, self.n_outputs, self.dt = 1, 2, DT

    def init(self) -> np.ndarray:
        return np.array([self.z0, 0.0])

    def output(self, state: np.ndarray) -> np.ndarray:
        y = np.empty(2)
        _fp_output(self.params, state, y)
        return y

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        new = np.array(state, dtype=float)
        _fp_update(self.params, new, np.asarray(command, dtype=float))
        return new


def search(continuous: bool, z0: float, seed: int, n: int = 30000, python: bool = False):
    ctrl = SlidingModeFocus(SlidingModeFocusConfig(continuous=continuous))
    rng = np.random.default_rng(seed)
    noise = np.column_stack([NOISE * rng.standard_normal(n), np.zeros(n)])
    run = simulate_python if python else simulate
    return run(FocusStandIn(z0), ctrl, np.zeros((n, 1)), noise)


RUNS = [(500e-6, 1), (-500e-6, 2), (500e-6, 3), (-500e-6, 4)]


@pytest.fixture(scope="module")
def runs() -> dict[bool, list[np.ndarray]]:
    """z (m) of 3 s searches from ±500 µm off focus, each law, seeded noise."""
    return {c: [search(c, z0, s).output[:, 1] for z0, s in RUNS] for c in (False, True)}


def test_relay_continuity_fixes_slope_and_offset():
    h = 0.3
    assert relay(-h, h) == 1.0 and relay(h, h) == 0.0  # v(−h) = 1, v(h) = 0
    s = np.linspace(-0.9 * h, 0.9 * h, 7)
    m = np.diff(relay(s, h)) / np.diff(s)
    np.testing.assert_allclose(m, -1.0 / (2 * h), rtol=1e-12)  # m = −1/(2h)
    assert relay(0.0, h) == 0.5  # b = 1/2
    grid = np.linspace(-3 * h, 3 * h, 601)
    np.testing.assert_array_equal(relay(grid, h)[grid < -h], 1.0)
    np.testing.assert_array_equal(relay(grid, h)[grid >= h], 0.0)
    np.testing.assert_array_equal(chi(grid, h)[grid >= h], 1.0)
    np.testing.assert_array_equal(chi(grid, h)[grid <= -h], -1.0)
    inner = np.abs(grid) < h
    np.testing.assert_allclose(chi(grid, h)[inner], grid[inner] / h, rtol=1e-15)
    np.testing.assert_allclose([relay_scalar(v, h) for v in grid], relay(grid, h), atol=1e-15)
    np.testing.assert_allclose([chi_scalar(v, h) for v in grid], chi(grid, h), atol=1e-15)
    # the continuous law's speed factor: 2 v(σ) − 1 is the continuous sign of −σ
    np.testing.assert_allclose(2 * relay(grid, h) - 1, chi(-grid, h), atol=1e-15)
    with pytest.raises(ValueError, match="h"):
        chi(grid, 0.0)


@pytest.mark.parametrize("continuous", [False, True])
def test_both_laws_reach_half_the_depth_of_focus_and_stay(runs, continuous):
    for z in runs[continuous]:
        out = np.nonzero(np.abs(z) > HALF_DOF)[0]
        t_in = (out[-1] + 1) * DT  # from here on the stage stays within ±27 µm
        assert t_in < 0.5  # 500 µm at 5 mm/s takes 0.1 s


def test_continuous_law_cuts_the_steady_oscillation_fivefold(runs):
    """Steady: the last second of each 3 s search."""
    pp = {c: np.array([np.ptp(z[-10000:]) for z in runs[c]]) for c in (False, True)}
    assert np.all(pp[True] <= 5e-6)
    assert pp[True].mean() * 5 <= pp[False].mean()
    assert np.all(pp[False] > pp[True])


@pytest.mark.parametrize("continuous", [False, True])
def test_kernel_and_python_step_agree(continuous):
    fast = search(continuous, 300e-6, 7, n=2500)
    slow = search(continuous, 300e-6, 7, n=2500, python=True)
    # the search reversed at least once in this stretch, on both paths alike
    assert np.any(np.diff(np.sign(fast.command[:, 0])) != 0)
    for sig in ("output", "command"):
        a, b = getattr(fast, sig), getattr(slow, sig)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), sig


def test_reads_the_detector_only():
    ctrl = SlidingModeFocus()
    assert (ctrl.n_inputs, ctrl.n_outputs, ctrl.preview) == (1, 1, 1)
    rng = np.random.default_rng(3)
    n = 300
    y = 1.0 + 0.01 * np.cumsum(rng.standard_normal(n))
    outs = []
    for z in (np.zeros(n), rng.standard_normal(n)):
        x = ctrl.init()
        u = np.empty((n, 1))
        for k in range(n):
            SlidingModeFocus.kernel_step(
                ctrl.params, x, np.zeros((1, 1, 1)), 0, np.array([y[k], z[k]]), u[k]
            )
        outs.append(u)
    np.testing.assert_array_equal(outs[0], outs[1])
    x = ctrl.init()
    u1 = np.empty(1)
    SlidingModeFocus.kernel_step(ctrl.params, x, np.zeros((1, 1, 1)), 0, np.array([y[0]]), u1)
    assert u1[0] == outs[0][0, 0]  # a (y,) measurement works alike


def test_config_scaling_and_refusals():
    c = SlidingModeFocusConfig.for_gain(2.0)
    d = SlidingModeFocusConfig()
    assert (c.fall_rate, c.h) == (2 * d.fall_rate, 2 * d.h)
    for kw, words in [
        ({"speed_m_s": 0.0}, ["speed_m_s", "m/s"]),
        ({"fall_rate": -1.0}, ["fall_rate", "detector units/s"]),
        ({"h": 0.0}, ["h (hysteresis)", "detector units"]),
        ({"fall_rate": 100.0, "h": 1e-3}, ["fall_rate * dt", "below", "lower fall_rate"]),
        ({"initial_direction": 0}, ["initial_direction"]),
        ({"continuous": 1}, ["continuous", "true or false"]),
    ]:
        with pytest.raises(ValueError) as err:
            SlidingModeFocusConfig(**kw)
        for w in words:
            assert w in str(err.value), (w, str(err.value))


def test_dark_field_area_is_the_log_spot_area():
    """y = dark + fs exp(−2a²/w²) maps back to ln(w²/2a²), exactly, over a wide range."""
    dark, fs, a = 0.01, 7.5, 3.8e-6
    w = np.geomspace(2e-6, 60e-6, 50)
    y = dark + fs * np.exp(-2 * a * a / (w * w))
    want = np.log(w * w / (2 * a * a))
    np.testing.assert_allclose(dark_field_area(y, dark, fs), want, rtol=0, atol=1e-9)
    got = [dark_field_area_scalar(v, dark, fs) for v in y]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # readings at or beyond the levels are clipped, not NaN
    for v in (dark - 1.0, dark, dark + fs, dark + 2 * fs):
        assert np.isfinite(dark_field_area(v, dark, fs))
        assert np.isfinite(dark_field_area_scalar(v, dark, fs))
    with pytest.raises(ValueError, match="full_scale_v"):
        dark_field_area(1.0, 0.0, 0.0)


def test_dark_field_rule():
    zr, cap, v, tau = 86e-6, 500e-6, 2e-3, 5e-3
    c = SlidingModeFocusConfig.for_dark_field(
        rayleigh_range_m=zr, capture_m=cap, speed_m_s=v, lag_s=tau, dark_v=0.01,
        full_scale_v=7.5,
    )  # fmt: skip
    zeta = cap / zr
    slowest = 2 * zeta / (1 + zeta**2) * v / zr  # d ln q / dt at the far end, 1/s
    assert c.fall_rate == pytest.approx(0.5 * slowest, rel=1e-12)
    assert c.h == pytest.approx(c.fall_rate * tau, rel=1e-12)
    assert c.dark_field == (0.01, 7.5)
    with pytest.raises(ValueError, match="at least the Rayleigh range"):
        SlidingModeFocusConfig.for_dark_field(
            rayleigh_range_m=zr, capture_m=10e-6, speed_m_s=v, lag_s=tau, dark_v=0.0,
            full_scale_v=1.0,
        )  # fmt: skip
    for bad in ((0.0, -1.0), ("a", 1.0), (float("nan"), 1.0)):
        with pytest.raises(ValueError, match="dark_field"):
            SlidingModeFocusConfig(dark_field=bad)  # type: ignore[arg-type]


@njit(cache=True)
def _df_output(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    d = (x[0] - p[3]) / p[4]
    y[0] = p[1] + p[2] * math.exp(-1.0 / (1.0 + d * d))
    y[1] = x[0]


class DarkFieldStandIn(FocusStandIn):
    """A dark-field detector (disc w0/sqrt 2, full scale 7.5 V) on the stand-in stage."""

    kernel_output: Any = _df_output

    def __init__(self, z0: float) -> None:
        super().__init__(z0, offset=0.01)
        p = self.params.copy()
        p[2] = 7.5
        self.params = p

    def output(self, state: np.ndarray) -> np.ndarray:
        y = np.empty(2)
        _df_output(self.params, state, y)
        return y


def test_kernel_and_python_agree_on_the_dark_field_law():
    cfg = SlidingModeFocusConfig.for_dark_field(
        rayleigh_range_m=Z_R, capture_m=400e-6, speed_m_s=2e-3, lag_s=TAU, dark_v=0.01,
        full_scale_v=7.5,
    )  # fmt: skip
    n = 4000
    noise = np.column_stack([6e-5 * np.random.default_rng(5).standard_normal(n), np.zeros(n)])
    fast = simulate(DarkFieldStandIn(400e-6), SlidingModeFocus(cfg), np.zeros((n, 1)), noise)
    slow = simulate_python(DarkFieldStandIn(400e-6), SlidingModeFocus(cfg), np.zeros((n, 1)), noise)
    assert np.any(np.diff(np.sign(fast.command[:, 0])) != 0)
    assert abs(fast.output[-1, 1]) < abs(fast.output[0, 1])  # it moved towards focus
    for sig in ("output", "command"):
        a, b = getattr(fast, sig), getattr(slow, sig)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), sig


def test_dark_field_rule_resolution_floor():
    kw = dict(rayleigh_range_m=86e-6, speed_m_s=2e-3, lag_s=5e-3, dark_v=0.0, full_scale_v=7.5)
    near = SlidingModeFocusConfig.for_dark_field(capture_m=500e-6, resolution_v=5e-4, **kw)
    assert near.h == pytest.approx(near.fall_rate * 5e-3)  # ρτ rules: floor below it
    far = SlidingModeFocusConfig.for_dark_field(capture_m=1.5e-3, resolution_v=5e-4, **kw)
    zeta = 1.5e-3 / 86e-6
    yn = math.exp(-1.0 / (1.0 + zeta**2))
    assert far.h == pytest.approx(2 * 5e-4 / (yn * -math.log(yn) * 7.5), rel=1e-12)
    wide = SlidingModeFocusConfig.for_dark_field(
        capture_m=1.5e-3, resolution_v=5e-4, stop_radius_ratio=1.2, **kw
    )
    assert wide.h < far.h  # a wider disc keeps the far end steeper
    with pytest.raises(ValueError, match="resolution_v"):
        SlidingModeFocusConfig.for_dark_field(capture_m=1e-3, resolution_v=-1.0, **kw)
