"""Contour compensator (seed 004 eqs. 5-15, Fig. 7) and Koren's cross-coupled baseline on
a stand-in stage with velocity-dependent friction: contour error cut at 10 mm/s, no
change at 1 mm/s, zero correction under exact tracking and at rest, corner hand-over,
kernel == Python, refusals."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numba import njit

from microfab.control.contour import (
    ContourCompensator,
    ContourConfig,
    path_frame,
    speed_weight,
)
from microfab.control.cross_coupled import CrossCoupled, CrossCoupledConfig
from microfab.control.preview_dob import PreviewDOB, PreviewDOBConfig
from microfab.plants.base import CompiledPlant
from microfab.sim.loop import reference_array, simulate, simulate_python

DT = 1e-4  # assumed 10 kHz
MASS = (1.2, 0.6)  # kg (seed 004 Table I: 0.6 kg a stage; x carries y)
KF = (10.0, 8.0)  # N/A, assumed
RADIUS = 100e-6  # m, seed 004 Fig. 7
# stand-in friction per axis (assumed, "very low friction" slides, seed 004 §II-C):
# F = FC tanh(v / VS) + B v
FC, VS, B = 0.3, 1e-3, 5.0  # N, m/s, N s/m


@njit(cache=True)
def _accel(p: np.ndarray, o: int, v: float, ia: float) -> float:
    return (p[o + 1] * ia - p[o + 3] * math.tanh(v / p[o + 4]) - p[o + 5] * v) / p[o]


@njit(cache=True)
def _fr_output(p: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    y[0] = x[0]
    y[1] = x[3]


@njit(cache=True)
def _fr_update(p: np.ndarray, x: np.ndarray, u: np.ndarray) -> None:
    n = int(p[1])
    h = p[0] / n
    for a in range(2):
        o = 2 + 6 * a
        s = 3 * a
        X, V, ia, lag = x[s], x[s + 1], x[s + 2], p[o + 2]
        for _ in range(n):  # RK4 on (x, v, i_a), the command held
            k1x, k1v, k1i = V, _accel(p, o, V, ia), (u[a] - ia) / lag
            v2, i2 = V + 0.5 * h * k1v, ia + 0.5 * h * k1i
            k2x, k2v, k2i = v2, _accel(p, o, v2, i2), (u[a] - i2) / lag
            v3, i3 = V + 0.5 * h * k2v, ia + 0.5 * h * k2i
            k3x, k3v, k3i = v3, _accel(p, o, v3, i3), (u[a] - i3) / lag
            v4, i4 = V + h * k3v, ia + h * k3i
            k4x, k4v, k4i = v4, _accel(p, o, v4, i4), (u[a] - i4) / lag
            X += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
            V += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
            ia += h / 6.0 * (k1i + 2.0 * k2i + 2.0 * k3i + k4i)
        x[s], x[s + 1], x[s + 2] = X, V, ia


class FrictionStage(CompiledPlant):
    """Two axes ``m ẍ = k i_a − FC tanh(ẋ/VS) − B ẋ``, ``τ i̇_a = i − i_a`` (test stand-in)."""

    kernel_output: Any = _fr_output
    kernel_update: Any = _fr_update

    def __init__(self, lag: float = 50e-6, substeps: int = 4) -> None:
        rows = [[MASS[a], KF[a], lag, FC, VS, B] for a in range(2)]
        self.params = np.array([DT, substeps, *rows[0], *rows[1]], dtype=np.float64)
        self.n_inputs, self.n_outputs, self.dt = 2, 2, DT

    def init(self) -> np.ndarray:
        return np.zeros(6)

    def output(self, state: np.ndarray) -> np.ndarray:
        y = np.empty(2)
        _fr_output(self.params, state, y)
        return y

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        new = np.array(state, dtype=float)
        _fr_update(self.params, new, np.asarray(command, dtype=float))
        return new


def inner() -> PreviewDOBConfig:
    return PreviewDOBConfig(mass_kg=MASS, force_constant_n_per_a=KF)


def circle(speed: float, laps: float) -> tuple:
    """Counter-clockwise circle at constant speed, centre (−R, 0), starting at the origin."""
    w = speed / RADIUS
    t = np.arange(round(laps * 2 * np.pi / w / DT)) * DT
    c, s = np.cos(w * t), np.sin(w * t)
    pos = RADIUS * np.column_stack([c - 1.0, s])
    return pos, speed * np.column_stack([-s, c]), -speed * w * np.column_stack([c, s])


def contour_errors(ctrl, speed: float, laps: int = 3) -> np.ndarray:
    """Distance of the stage from the circle after the first lap, m."""
    pos, vel, acc = circle(speed, laps)
    res = simulate(FrictionStage(), ctrl, pos, derivatives=(vel, acc))
    ce = np.abs(np.linalg.norm(res.output - [-RADIUS, 0.0], axis=1) - RADIUS)
    return ce[len(pos) // laps :]


@pytest.fixture(scope="module")
def fast_errors() -> dict[str, float]:
    return {
        "pdob": contour_errors(PreviewDOB(inner()), 10e-3).max(),
        "contour": contour_errors(ContourCompensator(ContourConfig(inner=inner())), 10e-3).max(),
        "ccc": contour_errors(CrossCoupled(CrossCoupledConfig(inner=inner())), 10e-3).max(),
    }


def test_correction_halves_the_contour_error_at_10_mm_s(fast_errors):
    """Seed 004 Fig. 7: 100 µm circle at 10 mm/s; the friction makes a contour error."""
    assert fast_errors["pdob"] > 0.2e-6  # there is an error to correct
    assert fast_errors["contour"] * 2 <= fast_errors["pdob"]


def test_cross_coupled_baseline_at_equal_bandwidth_also_cuts_it(fast_errors):
    assert fast_errors["ccc"] * 2 <= fast_errors["pdob"]


def test_correction_changes_the_contour_error_little_at_1_mm_s():
    """Seed 004 §IV-D: "almost no significant contribution ... at low speeds"."""
    without = contour_errors(PreviewDOB(inner()), 1e-3, laps=2)
    with_ = contour_errors(ContourCompensator(ContourConfig(inner=inner())), 1e-3, laps=2)
    assert np.max(np.abs(with_ - without)) < 50e-9
    assert abs(with_.max() - without.max()) < 50e-9


def step_on(ctrl, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray, ym: np.ndarray):
    """Run a controller's kernel over given measurements: its state after each sample and
    its commands."""
    R = reference_array(pos, (vel, acc))
    x = ctrl.init()
    u = np.empty((len(pos), 2))
    states = np.empty((len(pos), x.size))
    for k in range(len(pos)):
        type(ctrl).kernel_step(ctrl.params, x, R, k, ym[k], u[k])
        states[k] = x
    return states, u


def test_no_correction_under_exact_tracking_and_at_rest():
    comp = ContourCompensator(ContourConfig(inner=inner()))
    pos, vel, acc = circle(10e-3, 0.5)
    # exact tracking from a start at rest: the reference's first sample held 30 ms
    hold = 300
    pos = np.vstack([np.repeat(pos[:1], hold, 0), pos])
    vel = np.vstack([np.zeros((hold, 2)), vel])
    acc = np.vstack([np.zeros((hold, 2)), acc])
    states, _ = step_on(comp, pos, vel, acc, pos)
    eps, da = states[:, 2], states[:, 0:2]
    assert np.all(eps == 0.0)  # the measured point is the reference point
    assert np.all(da[:hold] == 0.0)  # at rest: off
    # in motion only the two velocity filters' transient is left, decaying to nothing:
    # after it (the differentiator of the positions against the low-pass of the velocity,
    # both Tustin) a normal correction worth less than 20 pm of contour error; along the
    # path the tangential row sees the differentiator's speed bias on the sampled circle,
    # Tustin's warp (ωT)²/12 of the speed (8e-6 here), times k_vt
    stiff = comp.config.inner.k_p + comp.config.k_pc
    t = vel[-200:] / np.linalg.norm(vel[-200:], axis=1)[:, None]
    along = np.einsum("ij,ij->i", da[-200:], t)
    across = np.linalg.norm(da[-200:] - along[:, None] * t, axis=1)
    assert np.max(across) / stiff <= 2e-11
    w_t = 10e-3 / RADIUS * DT
    assert np.max(np.abs(along)) <= 1.5 * comp.config.k_vt * 10e-3 * w_t**2 / 12
    # at rest with an error the correction is off, and Koren's C is zero before any motion
    still = np.zeros((50, 2))
    off = np.full((50, 2), 1e-6)
    assert np.all(step_on(comp, still, still, still, off)[0][:, 0:2] == 0.0)
    ccc = CrossCoupled(CrossCoupledConfig(inner=inner()))
    assert np.all(step_on(ccc, still, still, still, off)[0][:, 0:2] == 0.0)


def test_normal_frame_and_weight():
    w = 10e-3 / RADIUS
    for th in (0.3, 2.0, -1.2):
        vx, vy = -10e-3 * math.sin(th), 10e-3 * math.cos(th)
        ax, ay = -10e-3 * w * math.cos(th), -10e-3 * w * math.sin(th)
        sp, tx, ty, ks = path_frame(vx, vy, ax, ay)
        assert sp == pytest.approx(10e-3)
        assert ks / sp == pytest.approx(1.0 / RADIUS)  # κ = 1/R, counter-clockwise
        # n = t rotated +90° points at the centre
        assert (-ty, tx) == pytest.approx((-math.cos(th), -math.sin(th)))
    assert speed_weight(0.5e-4, 1e-4) == 0.0
    assert speed_weight(2.5e-4, 1e-4) == 1.0
    assert speed_weight(1.5e-4, 1e-4) == pytest.approx(0.5)


def corner_path() -> tuple:
    """+x then +y, each 50 µm from rest to rest (cubic-in-time smooth steps), 15 ms each."""
    n = 150
    s = np.linspace(0.0, 1.0, n)
    f, fd, fdd = 3 * s**2 - 2 * s**3, (6 * s - 6 * s**2) / (n * DT), (6 - 12 * s) / (n * DT) ** 2
    d = 50e-6
    z = np.zeros(n)
    pos = np.vstack([np.column_stack([d * f, z]), np.column_stack([np.full(n, d), d * f])])
    vel = np.vstack([np.column_stack([d * fd, z]), np.column_stack([z, d * fd])])
    acc = np.vstack([np.column_stack([d * fdd, z]), np.column_stack([z, d * fdd])])
    return pos, vel, acc


@pytest.mark.parametrize("make", ["contour", "ccc"])
def test_kernel_and_python_step_agree(make):
    ctrl = (
        ContourCompensator(ContourConfig(inner=inner()))
        if make == "contour"
        else CrossCoupled(CrossCoupledConfig(inner=inner()))
    )
    plant = FrictionStage()
    for pos, vel, acc in (circle(10e-3, 0.6), corner_path()):
        fast = simulate(plant, ctrl, pos, derivatives=(vel, acc))
        slow = simulate_python(plant, ctrl, pos, derivatives=(vel, acc))
        for sig in ("output", "command"):
            a, b = getattr(fast, sig), getattr(slow, sig)
            assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), sig


def test_corner_hand_over_is_continuous():
    """The correction is off at rest and fades in along the new normal over fade_in_s,
    though the reference leaves the speed band within a sample."""
    comp = ContourCompensator(ContourConfig(inner=inner()))
    pos, vel, acc = corner_path()
    res = simulate(FrictionStage(), comp, pos, derivatives=(vel, acc))
    states, u = step_on(comp, pos, vel, acc, res.measured)
    np.testing.assert_array_equal(u, res.command)  # the states are those of the run
    speed = np.linalg.norm(vel, axis=1)
    assert np.all(states[speed < comp.config.min_speed_m_s, 0:2] == 0.0)
    da, w = states[:, 0:2], states[:, 4]
    assert np.max(np.diff(w)) <= DT / comp.config.fade_in_s + 1e-15
    assert w[len(pos) // 2 + 1] < 0.1  # one sample into the second leg: barely on
    assert np.max(np.abs(da)) > 0  # and on it acts (the first leg's settling along x)
    pd = PreviewDOB(inner())
    base = simulate(FrictionStage(), pd, pos, derivatives=(vel, acc))
    jump = np.max(np.abs(np.diff(res.command, axis=0)))
    assert jump <= 1.5 * np.max(np.abs(np.diff(base.command, axis=0)))


@pytest.mark.parametrize(
    "cls, kw, words",
    [
        (ContourConfig, {"bandwidth_hz": 0.0}, ["bandwidth_hz", "Hz"]),
        (ContourConfig, {"damping": -1.0}, ["damping"]),
        (ContourConfig, {"min_speed_m_s": 0.0}, ["min_speed_m_s", "m/s"]),
        (ContourConfig, {"fade_in_s": 1e-5}, ["fade_in_s", "one sample"]),
        (ContourConfig, {"bandwidth_hz": 2000.0}, ["unstable", "contour compensator", "lower"]),
        (CrossCoupledConfig, {"bandwidth_hz": 2000.0}, ["unstable", "cross-coupled", "lower"]),
    ],
)
def test_refusals(cls, kw, words):
    with pytest.raises(ValueError) as err:
        cls(inner=inner(), **kw)
    for w in words:
        assert w in str(err.value), (w, str(err.value))
    one = PreviewDOBConfig(mass_kg=(1.2,), force_constant_n_per_a=(10.0,))
    with pytest.raises(ValueError, match="two axes"):
        cls(inner=one)
