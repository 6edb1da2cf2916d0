"""FRF estimates of a chirp experiment: per-period FFT ratio, H1, coherence, refusals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from microfab.identify import (
    FRF,
    Chirp,
    ChirpDesign,
    LowCoherenceError,
    estimate_frf,
    frf_h1,
    frf_periodic,
)
from microfab.io.frf import read_frf, write_frf

SEED_NUM = (1.242e11,)  # seed 003 part 2 §1
SEED_DEN = (1.0, 9517.0, 5.773e7, 1.272e11)  # seed 003 part 2 §1


def test_periodic_frf_is_the_exact_sampled_response(chirp: Chirp, y_clean, exact_zoh):
    frf = estimate_frf(chirp, y_clean)
    assert frf.method == "periodic" and frf.n_averages == 3 and frf.dt == 1e-5
    np.testing.assert_allclose(frf.freq_hz, np.arange(10.0, 2001.0))  # 1 Hz bins, f0..f1
    assert frf.excited_hz == (10.0, 2000.0)
    assert frf.unit == "bit/bit"
    pick = np.arange(0, frf.freq_hz.size, 97)  # python-control is slow point by point
    exact = exact_zoh(SEED_NUM, SEED_DEN, frf.freq_hz[pick])
    np.testing.assert_allclose(frf.response[pick], exact, rtol=1e-9)
    np.testing.assert_allclose(frf.coherence, 1.0, atol=1e-9)
    assert not frf.response.flags.writeable


def test_h1_with_rectangular_whole_periods_is_the_periodic_estimate(chirp: Chirp, y_noisy):
    per = estimate_frf(chirp, y_noisy)
    n = chirp.design.samples_per_period
    h1 = frf_h1(
        chirp.input, y_noisy, dt=1e-5, nperseg=n, noverlap=0, window="boxcar",
        n_dropped_samples=n, excited_hz=(10.0, 2000.0),
    )  # fmt: skip
    # the input repeats exactly, so mean(Y_p / U_p) = sum(Y_p U_p*) / sum(|U_p|^2)
    np.testing.assert_allclose(h1.response, per.response, rtol=1e-9)
    np.testing.assert_allclose(h1.coherence, per.coherence, rtol=1e-9)
    assert h1.n_averages == 3


def test_the_two_methods_agree_in_band(chirp: Chirp, y_clean, y_noisy):
    for y, tol in ((y_clean, 5e-3), (y_noisy, 5e-3)):
        per = estimate_frf(chirp, y)
        h1 = estimate_frf(chirp, y, method="h1")  # Hann, one-period segments, 50 % overlap
        assert h1.n_averages == 5
        np.testing.assert_array_equal(h1.freq_hz, per.freq_hz)
        rel = np.abs(h1.response / per.response - 1.0)
        # no noise: the window's smoothing over 3 bins, measured 0.12 % at most;
        # 0.3 bit noise: median 0.10 %, at most 2.6 % (at 2 kHz, where |H| is 0.08)
        assert (np.max(rel) if y is y_clean else np.median(rel)) < tol
        assert np.min(h1.coherence) > 0.99


def test_record_without_design_finds_the_excited_band(chirp: Chirp, y_clean):
    frf = frf_periodic(chirp.input, y_clean, dt=1e-5, samples_per_period=100_000, n_dropped=1)
    lo, hi = frf.excited_hz
    # a linear chirp's spectrum spreads over sqrt((f1 - f0) / P) = 45 Hz at its ends
    assert 0 < lo <= 10.0 and 2000.0 <= hi <= 2150.0
    assert frf.freq_hz[0] == lo and frf.freq_hz[-1] == hi


def test_single_period_leaves_coherence_unknown(chirp: Chirp, y_clean):
    n = chirp.design.samples_per_period
    frf = frf_periodic(
        chirp.input[:2 * n], y_clean[:2 * n], dt=1e-5, samples_per_period=n,
        excited_hz=(10.0, 2000.0),
    )  # fmt: skip
    assert frf.n_averages == 1
    assert np.all(np.isnan(frf.coherence))
    frf.band(10.0, 2000.0)  # unknown coherence is not refused
    assert frf.low_coherence_ranges() == []


def test_low_coherence_range_is_named(chirp: Chirp, y_clean):
    # strong noise between 1.5 and 1.7 kHz only (4th-order Butterworth band-pass)
    sos = scipy.signal.butter(4, [1500.0, 1700.0], btype="bandpass", fs=1e5, output="sos")
    rng = np.random.default_rng(7)
    y = y_clean + scipy.signal.sosfilt(sos, 50.0 * rng.standard_normal(y_clean.size))
    frf = estimate_frf(chirp, y)
    with pytest.raises(
        LowCoherenceError, match=r"coherence below 0\.8 from 1\d{3} to 1\d{3} Hz"
    ) as e:
        frf.band(10.0, 2000.0)
    (r,) = e.value.ranges
    assert 1400.0 < r.start_hz < 1560.0 and 1640.0 < r.stop_hz < 1800.0
    assert r.start_hz <= r.lowest_hz <= r.stop_hz and r.lowest < 0.8
    assert r.n_low <= r.n_frequencies == round(r.stop_hz - r.start_hz) + 1
    ok = frf.band(10.0, 1300.0)  # below the noisy range
    assert ok.freq_hz[-1] == 1300.0 and ok.freq_hz[0] == 10.0
    frf.band(10.0, 2000.0, min_coherence=0.0)  # 0 checks nothing


def test_band_refusals(chirp: Chirp, y_clean):
    frf = estimate_frf(chirp, y_clean)
    with pytest.raises(ValueError, match=r"band 5-2000 Hz lies outside the excited band 10-2000"):
        frf.band(5.0, 2000.0)
    with pytest.raises(ValueError, match=r"band 10-2500 Hz lies outside the excited band"):
        frf.band(10.0, 2500.0)
    wide = frf_periodic(chirp.input, y_clean, dt=1e-5, samples_per_period=100_000)
    with pytest.raises(ValueError, match=r"above the Nyquist frequency 50000 Hz"):
        wide.band(10.0, 60_000.0)
    with pytest.raises(ValueError, match=r"low_hz < high_hz"):
        frf.band(500.0, 100.0)
    with pytest.raises(ValueError, match=r"holds no frequency"):
        frf.band(100.2, 100.8)


def test_record_refusals(chirp: Chirp, y_clean):
    n = chirp.design.samples_per_period
    with pytest.raises(ValueError, match=r"shorter than one period of 100000 samples \(1 s\)"):
        estimate_frf(chirp, y_clean[: n // 2])
    with pytest.raises(ValueError, match=r"1 whole periods of 100000 samples .* at least 200000"):
        estimate_frf(chirp, y_clean[: n + 10])
    with pytest.raises(ValueError, match=r"shorter than one period \(segment\) of 100000"):
        estimate_frf(chirp, y_clean[: n + 10], method="h1")
    bad = y_clean.copy()
    bad[123_456] = np.nan
    with pytest.raises(ValueError, match=r"output record.*nan.*sample 123456"):
        estimate_frf(chirp, bad)
    with pytest.raises(ValueError, match=r"same length, got 400000 and 399999"):
        frf_periodic(chirp.input, y_clean[:-1], dt=1e-5, samples_per_period=n)
    with pytest.raises(ValueError, match=r"excited_hz upper edge 60000 Hz lies above the Nyquist"):
        frf_periodic(chirp.input, y_clean, dt=1e-5, samples_per_period=n, excited_hz=(10, 6e4))
    with pytest.raises(ValueError, match=r"excites no frequency"):
        frf_periodic(np.ones(2 * n), y_clean[: 2 * n], dt=1e-5, samples_per_period=n)
    with pytest.raises(ValueError, match=r"method must be 'periodic' or 'h1'"):
        estimate_frf(chirp, y_clean, method="h2")  # type: ignore[arg-type]


def test_log_chirp_gives_the_same_response(y_clean, exact_zoh, simulate_zoh):
    c = ChirpDesign(sweep="log").signal()
    frf = estimate_frf(c, simulate_zoh(SEED_NUM, SEED_DEN, c.input))
    pick = np.array([0, 90, 490, 990, 1990])  # 10, 100, 500, 1000, 2000 Hz
    np.testing.assert_allclose(
        frf.response[pick], exact_zoh(SEED_NUM, SEED_DEN, frf.freq_hz[pick]), rtol=1e-9
    )


def test_frf_file_round_trip_and_plot(tmp_path, chirp: Chirp, y_noisy):
    frf = estimate_frf(chirp, y_noisy)
    write_frf(tmp_path / "frf.csv", frf.freq_hz, frf.response[:, None], ["x"])
    back = FRF.from_table(read_frf(tmp_path / "frf.csv"), dt=1e-5)
    np.testing.assert_allclose(back.response, frf.response, rtol=1e-12)
    assert back.method == "table" and np.all(np.isnan(back.coherence))
    with pytest.raises(ValueError, match=r"no axis 'y' \(it holds x\)"):
        FRF.from_table(read_frf(tmp_path / "frf.csv"), "y")
    fig = frf.plot(title="seed 003 part 2 Fig. 4")
    assert len(fig.axes) == 3
    assert fig.axes[0].get_ylabel() == "magnitude, dB"
    assert list(tmp_path.iterdir()) == [tmp_path / "frf.csv"]  # the plot wrote nothing


def test_frf_container_refusals():
    f = np.array([1.0, 2.0, 3.0])
    ok = {"coherence": np.ones(3), "method": "h1", "dt": 1e-3, "excited_hz": (1.0, 3.0)}
    with pytest.raises(ValueError, match="strictly increasing"):
        FRF(freq_hz=f[::-1], response=np.ones(3), **ok)
    with pytest.raises(ValueError, match=r"NaN/inf at 2 Hz"):
        FRF(freq_hz=f, response=np.array([1, np.nan, 1]), **ok)
    with pytest.raises(ValueError, match=r"coherence must lie in \[0, 1\]"):
        FRF(freq_hz=f, response=np.ones(3), **{**ok, "coherence": np.array([1, 1.5, 1])})
    with pytest.raises(ValueError, match="method must be one of"):
        FRF(freq_hz=f, response=np.ones(3), **{**ok, "method": "h3"})
