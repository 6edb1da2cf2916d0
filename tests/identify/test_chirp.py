"""Chirp design (seed 003 part 2 §1): defaults, the sweep, periodicity, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from microfab.identify import Chirp, ChirpDesign


def test_defaults_are_the_seeds_experiment():
    d = ChirpDesign()
    # seed 003 part 2 §1: 10 Hz -> 2 kHz, 100 bit, 1 s; §2: T = 10 us
    assert (d.f0_hz, d.f1_hz, d.amplitude, d.period_s, d.dt) == (10.0, 2000.0, 100.0, 1.0, 1e-5)
    assert (d.n_periods, d.n_dropped, d.sweep) == (4, 1, "linear")  # assumed
    assert d.samples_per_period == 100_000
    assert d.n_samples == 400_000
    assert d.duration_s == pytest.approx(4.0)
    assert d.bin_hz == pytest.approx(1.0)
    assert d.nyquist_hz == pytest.approx(50_000.0)
    assert d.band_hz == (10.0, 2000.0)


def test_signal_repeats_each_period_and_has_the_amplitude(chirp: Chirp):
    d = chirp.design
    u = chirp.input.reshape(d.n_periods, d.samples_per_period)
    np.testing.assert_array_equal(u, np.broadcast_to(u[0], u.shape))
    assert np.max(np.abs(chirp.input)) <= d.amplitude
    assert np.max(np.abs(chirp.input)) > 0.999 * d.amplitude
    assert chirp.time[1] == pytest.approx(d.dt)
    assert chirp.kept == slice(100_000, None)
    assert not chirp.input.flags.writeable


def _local_frequency(u: np.ndarray, dt: float, t_mid: float, half_s: float) -> float:
    """Mean frequency of ``u`` over ``t_mid +- half_s`` from its analytic signal's phase."""
    phase = np.unwrap(np.angle(scipy.signal.hilbert(u)))
    i0, i1 = round((t_mid - half_s) / dt), round((t_mid + half_s) / dt)
    return (phase[i1] - phase[i0]) / (2 * np.pi * (i1 - i0) * dt)


@pytest.mark.parametrize(
    "sweep, expected_hz",
    [("linear", 1005.0), ("log", np.sqrt(10.0 * 2000.0))],  # f(P/2) of each law
)
def test_instantaneous_frequency_follows_the_law(sweep: str, expected_hz: float):
    d = ChirpDesign(sweep=sweep, n_periods=1, n_dropped=0)
    u = d.one_period()
    assert d.frequency_hz(np.array([0.5]))[0] == pytest.approx(expected_hz)
    assert _local_frequency(u, d.dt, 0.5, 0.005) == pytest.approx(expected_hz, rel=1e-3)
    assert d.frequency_hz(np.array([0.0, 1.0]))[0] == pytest.approx(10.0)  # wraps


@pytest.mark.parametrize("sweep, share", [("linear", 0.99), ("log", 0.97)])
def test_the_energy_lies_in_the_band(sweep: str, share: float):
    d = ChirpDesign(sweep=sweep)
    spec = np.abs(np.fft.rfft(d.one_period())) ** 2
    f = np.fft.rfftfreq(d.samples_per_period, d.dt)
    inside = spec[(f >= d.f0_hz) & (f <= d.f1_hz)].sum() / spec.sum()
    assert inside > share  # measured 0.9956 (linear), 0.981 (log)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"f1_hz": 60_000.0}, r"f1_hz must lie below the Nyquist frequency .*50000 Hz"),
        ({"f1_hz": 5.0}, r"f1_hz must exceed f0_hz = 10 Hz"),
        ({"f0_hz": 0.5}, r"f0_hz must be at least one FFT bin, 1 / period_s = 1 Hz"),
        (
            {"period_s": 1.000004},
            r"period_s must be a whole number .*got 1.000004 s \(100000.4 samples\): use 1 s",
        ),
        ({"n_dropped": 4}, r"n_dropped must be below n_periods = 4"),
        ({"n_periods": 0}, r"n_periods must be an integer >= 1"),
        ({"amplitude": -1.0}, r"amplitude must be positive and finite, got -1.0 bit"),
        ({"dt": float("nan")}, r"dt must be positive and finite, got nan s"),
        ({"sweep": "square"}, r"sweep must be one of linear, log, got 'square'"),
    ],
)
def test_bad_designs_are_refused(kwargs: dict, match: str):
    with pytest.raises(ValueError, match=match):
        ChirpDesign(**kwargs)


def test_chirp_refuses_samples_that_do_not_fit_the_design():
    d = ChirpDesign(period_s=0.01, n_periods=2, n_dropped=1, f0_hz=100.0)
    with pytest.raises(ValueError, match=r"input must have shape \(2000,\)"):
        Chirp(design=d, input=np.zeros(1999))
    u = d.signal().input.copy()
    u[7] = np.nan
    with pytest.raises(ValueError, match="NaN/inf at sample 7"):
        Chirp(design=d, input=u)
