"""Plug-in RC (seed 001 §3.3, Figs. 6-7): convergence on the circle, kernel == Python,
file-based update == per-sample rule, windows and carry, atomic state and resume, refusals."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest
from numba import njit

import control
from microfab.control.base import CompiledController, LTIController, ReferenceWindow
from microfab.control.pid import PID, pid_frequency_response
from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import (
    PluginRC,
    RCConfig,
    learning_factor,
    period_samples,
    rc_update,
)
from microfab.plants.base import LTIPlant
from microfab.plants.lti import DiscreteLTI, block_diag, discretize
from microfab.sim.loop import simulate, simulate_python

DT = 1e-4  # assumed 10 kHz (shared contract of the seed 001 twin)
PX = ((548248.13,), (1.0, 14.88, 101793.23))  # seed 001 eq. (9), mm/V
PY = ((319852.42,), (1.0, 18.52, 99664.23))


def eq9_plant() -> LTIPlant:
    return LTIPlant(block_diag(discretize(control.tf(*PX), DT), discretize(control.tf(*PY), DT)))


def tuned_pid() -> PID:
    return PID.tuned([PX, PY], bandwidth_hz=200.0, phase_margin_deg=45.0, dt=DT)


def circle(n_samples: int, period_s: float, radius: float = 0.075) -> tuple:
    t = np.arange(n_samples) * DT
    w = 2 * np.pi / period_s
    pos = radius * np.column_stack([np.cos(w * t), np.sin(w * t)])
    vel = radius * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    return pos, vel, -(w**2) * pos


def rms_per_period(e: np.ndarray, n: int) -> np.ndarray:
    return np.sqrt(np.mean(np.sum(e.reshape(-1, n, e.shape[1]) ** 2, axis=2), axis=1))


@njit(cache=True)
def _preview_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    # a toy preview controller that reads every row and order of its window
    for a in range(ym.shape[0]):
        acc = 0.0
        for i in range(3):
            for d in range(ref.shape[1]):
                acc += p[i] * ref[k + i, d, a] / (1.0 + d)
        u[a] = acc - ym[a] + 0.5 * x[a]
        x[a] = u[a]


class PreviewToy(CompiledController):
    """Test-local compiled controller with preview 3."""

    kernel_step: Any = _preview_step

    def __init__(self) -> None:
        self.params = np.array([0.5, 0.3, 0.2])
        self.preview = 3
        self.n_axes = 2

    def init(self) -> np.ndarray:
        return np.zeros(2)

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        x = state.copy()
        u = np.empty(2)
        orders = [window.position, window.velocity, window.acceleration, window.jerk]
        for a in range(2):
            acc = 0.0
            for i in range(3):
                for d, arr in enumerate(orders):
                    if arr is not None:
                        acc += self.params[i] * arr[i, a] / (1.0 + d)
            u[a] = acc - measurement[a] + 0.5 * x[a]
            x[a] = u[a]
        return u, x


def test_rc_around_pid_cuts_the_circle_error_5x_within_10_periods():
    """Noise off, 1 Hz 0.15 mm circle (seed 001 §4.2) on eq. 9: per-period RMS."""
    n = 10000
    pos, vel, acc = circle(10 * n, 1.0)
    plant = eq9_plant()
    pid = tuned_pid()
    base = simulate(plant, pid, pos, derivatives=(vel, acc))
    rc = PluginRC(pid, RCConfig(period_s=1.0, dt=DT))
    res = simulate(plant, rc, pos, derivatives=(vel, acc))
    r_pid = rms_per_period(base.reference - base.output, n)
    r_rc = rms_per_period(res.reference - res.output, n)
    # the first period runs without correction: the same as PID alone
    assert r_rc[0] == pytest.approx(r_pid[0], rel=1e-12)
    assert r_rc[-1] * 5 <= r_pid[-1]
    assert np.all(np.diff(r_rc[1:]) < 0)  # contracts period after period


def test_default_rc_contracts_on_the_tuned_pid_loop():
    f = np.geomspace(0.5, 4999.0, 3000)
    cfg = RCConfig(period_s=1.0, dt=DT)
    for g, plant in zip(tuned_pid().gains, (PX, PY), strict=True):
        L = (
            pid_frequency_response(g, f, DT)
            * (discretize(control.tf(*plant), DT).frequency_response(f)[:, 0, 0])
        )
        lf = learning_factor(cfg, f, L / (1 + L))
        assert lf.max() < 0.7
        assert lf[0] < 1e-2  # at the fundamental the error nearly vanishes in one period


@pytest.mark.parametrize("derivatives", ["zero", "memory"])
@pytest.mark.parametrize("carry", [False, True])
def test_kernel_and_python_loops_agree(derivatives: str, carry: bool):
    n = 40
    cfg = RCConfig(
        period_s=n * DT,
        dt=DT,
        tau_s=3e-4,
        gain=0.8,
        lead_samples=3,
        carry=carry,
        derivatives=derivatives,  # type: ignore[arg-type]
        windows=((5, 2), (130, 1), (170, 2)),
    )
    pos, vel, acc = circle(300, n * DT)
    rng = np.random.default_rng(3)
    noise = 1e-5 * rng.normal(size=pos.shape)
    for inner in (tuned_pid(), PreviewToy()):
        rc = PluginRC(inner, cfg)
        a = simulate(eq9_plant(), rc, pos, noise, derivatives=(vel, acc), periodic=True)
        b = simulate_python(eq9_plant(), rc, pos, noise, derivatives=(vel, acc), periodic=True)
        np.testing.assert_allclose(a.command, b.command, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(
            a.final_state.controller, b.final_state.controller, rtol=1e-12, atol=1e-15
        )


def test_outside_windows_the_inner_controller_runs_alone_and_memory_restarts():
    n = 50
    pos, vel, acc = circle(400, n * DT)
    pid = tuned_pid()
    for carry in (False, True):
        cfg = RCConfig(period_s=n * DT, dt=DT, carry=carry, windows=((100, 3), (300, 2)))
        rc = PluginRC(pid, cfg)
        res = simulate(eq9_plant(), rc, pos[:100], derivatives=(vel[:100], acc[:100]))
        alone = simulate(eq9_plant(), pid, pos[:100], derivatives=(vel[:100], acc[:100]))
        np.testing.assert_array_equal(res.command, alone.command)  # before the first window
        st = res.final_state
        res = simulate(
            eq9_plant(), rc, pos[100:301], state=st, derivatives=(vel[100:301], acc[100:301])
        )
        mem = rc.memory_of(res.final_state.controller)
        assert mem.samples == 301
        # one sample into the second window: its memory is empty unless carried
        if carry:
            assert np.abs(mem.memory).max() > 1e-6
        else:
            np.testing.assert_array_equal(mem.memory, 0.0)
            np.testing.assert_array_equal(mem.error, 0.0)


def test_file_based_update_equals_the_per_sample_rule():
    n = 100
    cfg = RCConfig(period_s=n * DT, dt=DT, tau_s=5e-4, lead_samples=4)
    pos, vel, acc = circle(4 * n, n * DT)
    rc = PluginRC(tuned_pid(), cfg)
    plant = eq9_plant()
    st = None
    file_mem = RCMemory.initial(cfg, 2)
    for j in range(4):
        sl = slice(j * n, (j + 1) * n)
        res = simulate(plant, rc, pos[sl], state=st, derivatives=(vel[sl], acc[sl]))
        st = res.final_state
        err = res.reference - res.measured
        sim_mem = rc.memory_of(st.controller)
        # the correction applied in this period is the file-based next correction
        np.testing.assert_array_equal(sim_mem.memory, file_mem.next_correction())
        file_mem = file_mem.after_period(err)
        np.testing.assert_array_equal(sim_mem.memory, file_mem.memory)
        np.testing.assert_array_equal(sim_mem.error, file_mem.error)
        assert sim_mem.samples == file_mem.samples
    # rc_update is the same step on plain arrays
    np.testing.assert_array_equal(
        rc_update(file_mem.memory, file_mem.error, cfg), file_mem.next_correction()
    )


def test_interrupted_run_resumes_bit_identically(tmp_path):
    n = 60
    cfg = RCConfig(period_s=n * DT, dt=DT, lead_samples=2)
    pos, vel, acc = circle(5 * n, n * DT)
    rc = PluginRC(tuned_pid(), cfg)
    whole = simulate(eq9_plant(), rc, pos, derivatives=(vel, acc))
    cut = 2 * n + 17
    first = simulate(eq9_plant(), rc, pos[:cut], derivatives=(vel[:cut], acc[:cut]))
    path = rc.save_state(first.final_state.controller, tmp_path / "rc_state.npz")
    # a fresh controller object (as after a restart) reads the state back
    rc2 = PluginRC(tuned_pid(), cfg)
    st = first.final_state
    st.controller = rc2.load_state(path)
    rest = simulate(eq9_plant(), rc2, pos[cut:], state=st, derivatives=(vel[cut:], acc[cut:]))
    np.testing.assert_array_equal(np.vstack([first.command, rest.command]), whole.command)
    np.testing.assert_array_equal(rest.final_state.controller, whole.final_state.controller)
    assert not list(tmp_path.glob(".*tmp"))  # atomic write left no temporary file


def test_saved_state_is_checked(tmp_path):
    cfg = RCConfig(period_s=20 * DT, dt=DT)
    rc = PluginRC(tuned_pid(), cfg)
    path = rc.save_state(rc.init(), tmp_path / "s.npz")
    mem = RCMemory.load(path)
    assert mem.config == cfg and mem.samples == 0
    other = PluginRC(tuned_pid(), RCConfig(period_s=20 * DT, dt=DT, gain=0.5))
    with pytest.raises(ValueError, match="another RC config"):
        other.load_state(path)
    lti = LTIController(DiscreteLTI([[1.0]], [[1.0]], [[0.1]], [[1.0]], DT))
    with pytest.raises(ValueError, match="saved with another inner controller"):
        PluginRC(lti, cfg, n_axes=2).load_state(path)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not an npz")
    with pytest.raises(ValueError, match="not a readable RC state"):
        RCMemory.load(bad)
    with pytest.raises(FileNotFoundError, match="no RC state"):
        RCMemory.load(tmp_path / "missing.npz")
    with pytest.raises(ValueError, match="holds NaN or inf"):
        rc_update(np.full((20, 2), np.nan), np.zeros((20, 2)), cfg)
    with pytest.raises(ValueError, match=r"must be shaped \(N = 20 samples"):
        rc_update(np.zeros((19, 2)), np.zeros((19, 2)), cfg)
    with pytest.raises(ValueError, match="error_period must be finite"):
        RCMemory.initial(cfg, 2).after_period(np.zeros((20, 3)))


def test_one_class_per_inner_kernel_and_pickle():
    cfg = RCConfig(period_s=20 * DT, dt=DT)
    a = PluginRC(tuned_pid(), cfg)
    b = PluginRC(tuned_pid(), cfg)
    lti = LTIController(DiscreteLTI([[1.0]], [[1.0]], [[0.1]], [[1.0]], DT))
    c = PluginRC(lti, cfg, n_axes=1)
    assert type(a) is type(b) and type(a) is not type(c)
    assert isinstance(a, PluginRC) and isinstance(a, CompiledController)
    clone = pickle.loads(pickle.dumps(a))
    np.testing.assert_array_equal(clone.params, a.params)
    with pytest.raises(TypeError, match="PluginRC wraps a CompiledController"):
        PluginRC(object(), cfg)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"period_s": 1.5e-4}, r"period_s must be a whole number \(>= 2\) of samples"),
        ({"period_s": float("nan")}, "period_s must be positive and finite, got nan"),
        ({"tau_s": 0.0}, r"tau_s \(RC low-pass Q time constant\) must be positive"),
        ({"tau_s": -1e-3}, "tau_s"),
        ({"gain": 0.0}, r"gain \(RC learning gain k_r\) must lie in \(0, 2\]"),
        ({"gain": float("nan")}, "gain"),
        ({"lead_samples": 100}, r"lead_samples must be below the period \(100 samples\)"),
        ({"lead_samples": 1.0}, "lead_samples must be an integer"),
        ({"derivatives": "spline"}, "derivatives must be one of zero, memory"),
        ({"carry": 1}, "carry must be true or false"),
        ({"windows": ((0, 2), (150, 1))}, "window 1 starts at sample 150, before"),
        ({"windows": ((0, 0),)}, "window 0 n_periods must be an integer >= 1"),
        ({"windows": ()}, "at least one"),
    ],
)
def test_config_refused(kwargs: dict, match: str):
    base: dict[str, Any] = {"period_s": 100 * DT, "dt": DT}
    with pytest.raises(ValueError, match=match):
        RCConfig(**(base | kwargs))


def test_period_samples():
    assert period_samples(1.0, 1e-4) == 10000
    assert period_samples(0.3, 1e-4) == 3000  # 0.3 / 1e-4 = 2999.9999999999995
    with pytest.raises(ValueError, match="multiple of dt"):
        period_samples(0.30005, 1e-4)
