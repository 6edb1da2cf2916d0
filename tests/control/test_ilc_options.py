"""ILC options for machines other than the twin: per-axis gains, a model from a measured
FRF, the P-type law and the divergence monitor."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.control.ilc import ConvergenceError, FrequencyILC, ILCConfig, Trial
from microfab.trajectory.periodic import square_scan

FS = 1e6
DT = 1 / FS
AXES = ("x", "y")
HALF = (1.0, 1.44)


def lag_frf(f: np.ndarray) -> np.ndarray:
    """A stable stand-in loop per axis: first-order lag at 3 kHz and 4 samples of delay."""
    f = np.asarray(f, dtype=float)
    p = 1.0 / (1 + 1j * f / 3000.0) * np.exp(-2j * np.pi * f * 4 * DT)
    return np.column_stack([p, 0.8 * p])


def output(u: np.ndarray, frf=lag_frf) -> np.ndarray:
    n = u.shape[0]
    return np.fft.irfft(np.fft.rfft(u, axis=0) * frf(np.fft.rfftfreq(n, DT)), n=n, axis=0)


def trial(ref: np.ndarray, u: np.ndarray, y: np.ndarray) -> Trial:
    return Trial(dt=DT, reference=ref, input=u, output=y, axes=AXES)


@pytest.fixture
def ref() -> np.ndarray:
    return square_scan(1000, HALF, FS)


def test_axis_gains_set_each_axis_contraction(ref):
    """With the exact model, E_{i+1} = (1 - rho_a) E_i on each axis's learned harmonics."""
    cfg = ILCConfig(gain=0.4, axis_gains={"y": 1.0})
    ilc = FrequencyILC(ref, DT, AXES, cfg, model=lag_frf)
    u = ilc.initial_input()
    e = []
    for _ in range(3):
        y = output(u)
        e.append(np.fft.rfft(y - ref, axis=0))
        u = ilc.update(trial(ref, u, y))
    m = ilc.state.mask
    np.testing.assert_allclose(e[1][m[:, 0], 0], 0.6 * e[0][m[:, 0], 0], atol=1e-9)
    assert np.abs(e[1][m[:, 1], 1]).max() < 1e-9  # rho = 1 with the exact model: one step
    assert cfg.gain_of("x") == 0.4 and cfg.gain_of("y") == 1.0
    with pytest.raises(ValueError, match=r"axis gain of 'y'"):
        ILCConfig(axis_gains={"y": 2.5})
    with pytest.raises(ValueError, match=r"a gain is given for axis \['z'\]"):
        FrequencyILC(ref, DT, AXES, ILCConfig(axis_gains={"z": 0.3}))


def test_model_is_saved_and_restored(ref, tmp_path):
    ilc = FrequencyILC(ref, DT, AXES, ILCConfig(gain=0.7), model=lag_frf)
    ilc.save(tmp_path)  # before any trial: the model must survive a resume
    resumed = FrequencyILC.load(tmp_path)
    u_a = ilc.initial_input()
    u_b = resumed.initial_input()
    for _ in range(3):
        u_a = ilc.update(trial(ref, u_a, output(u_a)))
        u_b = resumed.update(trial(ref, u_b, output(u_b)))
        assert np.array_equal(u_a, u_b)
    np.testing.assert_array_equal(resumed.state.pinv, ilc.state.pinv)


def test_p_type_converges_where_eq5_holds_and_refuses_where_it_cannot(ref):
    final = {}
    for law in ("p-type", "inverse"):
        ilc = FrequencyILC(ref, DT, AXES, ILCConfig(law=law, gain=0.5, cutoff_hz=3000.0))
        u = ilc.initial_input()
        for _ in range(40):
            u = ilc.update(trial(ref, u, output(u)))
        final[law] = ilc.rms_history[-1]
        assert np.all(final[law] < ilc.rms_history[0] / 5)
    # both reach the floor set by the harmonics above the cutoff, which neither learns
    np.testing.assert_allclose(final["p-type"], final["inverse"], rtol=0.01)

    # without an advance, 30 samples of delay turn the 7 kHz harmonic past 90 degrees
    # (67 of lag, 76 of delay): no gain satisfies eq. 5 there and the first call says so
    def slow(f: np.ndarray) -> np.ndarray:
        return lag_frf(f) * np.exp(-2j * np.pi * np.asarray(f)[:, None] * 26 * DT)

    ilc = FrequencyILC(ref, DT, AXES, ILCConfig(law="p-type", advance_s=0.0))
    u = ilc.initial_input()
    with pytest.raises(ConvergenceError, match=r"no gain satisfies it there: set cutoff_hz"):
        ilc.update(trial(ref, u, output(u, slow)))
    # the advance measured from trial 1 (30 samples) fixes it
    ilc = FrequencyILC(ref, DT, AXES, ILCConfig(law="p-type"))
    ilc.update(trial(ref, u, output(u, slow)))
    assert ilc.iteration == 1


def test_monitor_falls_back_to_the_best_input_and_lowers_the_gain(ref, tmp_path):
    """A machine whose response turns over after trial 3 (e.g. a mode that drifts): the
    error grows twice in a row, so the learner goes back to its best input and halves
    the gain where the error grew."""
    trials = {"n": 0}

    def drifting(f: np.ndarray) -> np.ndarray:
        p = lag_frf(f)
        return p if trials["n"] < 3 else p * np.exp(-1.4j)  # 80 degrees of extra lag

    ilc = FrequencyILC(ref, DT, AXES, ILCConfig(gain=0.9))
    u = ilc.initial_input()
    inputs = []
    for _ in range(8):
        inputs.append(u)
        y = output(u, drifting)
        u = ilc.update(trial(ref, u, y))
        trials["n"] += 1
        if ilc.events:
            break
    assert ilc.events, ilc.rms_history
    assert "grew twice in a row" in ilc.events[0] and "gain halved" in ilc.events[0]
    rms = ilc.rms_history
    a = 0 if "axis x" in ilc.events[0] else 1
    best = int(np.argmin(rms[:, a]))
    np.testing.assert_array_equal(u[:, a], inputs[best][:, a])
    assert ilc.harmonic_gains[ilc.state.mask[:, a], a].min() == pytest.approx(0.45)
    ilc.save(tmp_path)
    back = FrequencyILC.load(tmp_path)
    assert back.events == ilc.events
    np.testing.assert_array_equal(back.harmonic_gains, ilc.harmonic_gains)


def test_monitor_stays_quiet_on_a_converging_noisy_loop(ref):
    rng = np.random.default_rng(4)
    ilc = FrequencyILC(ref, DT, AXES)
    u = ilc.initial_input()
    for _ in range(30):
        u = ilc.update(trial(ref, u, output(u) + 1e-3 * rng.standard_normal(u.shape)))
    assert ilc.events == []
