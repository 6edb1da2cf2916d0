from __future__ import annotations

import numpy as np
import pytest

from microfab.measure.metrics import (
    ErrorSpectrum,
    ErrorStats,
    error_psd,
    error_stats,
    learning_transient,
    peak_to_peak,
    rms,
)

FS = 100e3
DT = 1.0 / FS


def _sine(amp: float, freq: float, n: int, phase: float = 0.3) -> np.ndarray:
    t = np.arange(n) * DT
    return amp * np.sin(2 * np.pi * freq * t + phase)


def test_rms_of_sine_is_amplitude_over_sqrt2() -> None:
    x = _sine(2.5, 1e3, 1000)  # exactly 10 periods
    assert rms(x) == pytest.approx(2.5 / np.sqrt(2), rel=1e-12)


def test_rms_and_pp_per_axis() -> None:
    rng = np.random.default_rng(0)
    x = np.column_stack([_sine(1.0, 1e3, 1000), 3.0 * rng.standard_normal(1000)])
    r = rms(x)
    assert r.shape == (2,)
    assert r[0] == pytest.approx(1 / np.sqrt(2), rel=1e-12)
    assert r[1] == pytest.approx(3.0, rel=0.1)
    pp = peak_to_peak(x)
    assert pp[0] == pytest.approx(2.0, rel=1e-3)
    assert pp[1] == pytest.approx(x[:, 1].max() - x[:, 1].min())


def test_rms_empty_raises() -> None:
    with pytest.raises(ValueError, match="empty"):
        rms(np.array([]))
    with pytest.raises(ValueError, match="empty"):
        peak_to_peak(np.array([]))


def test_error_stats_shapes_and_values() -> None:
    e = np.column_stack([_sine(1e-3, 400, 1000), _sine(2e-3, 400, 1000)])
    stats = error_stats(e)
    assert isinstance(stats, ErrorStats)
    np.testing.assert_allclose(stats.rms, [1e-3 / np.sqrt(2), 2e-3 / np.sqrt(2)], rtol=1e-6)
    np.testing.assert_allclose(stats.pp, [2e-3, 4e-3], rtol=1e-3)
    one = error_stats(_sine(1.0, 1e3, 1000))
    assert one.rms.shape == (1,)


def test_error_stats_rejects_nan() -> None:
    with pytest.raises(ValueError, match="finite"):
        error_stats(np.array([0.0, np.nan, 1.0]))


def test_periodogram_third_harmonic() -> None:
    period = 2.5e-3  # 400 features/s
    n = round(4 * period / DT)  # 4 periods, 1000 samples
    amp = 0.7
    rng = np.random.default_rng(1)
    e = _sine(amp, 3 / period, n) + 1e-4 * rng.standard_normal(n)
    spec = error_psd(e, DT, period_s=period)
    assert isinstance(spec, ErrorSpectrum)
    assert spec.psd.shape == (len(spec.freq_hz), 1)
    assert spec.harmonic_freq_hz[0] == pytest.approx(400.0)
    np.testing.assert_allclose(spec.harmonic_freq_hz, spec.harmonic_number * 400.0)
    assert spec.harmonic_freq_hz[-1] <= FS / 2
    assert spec.harmonic_psd.shape == (len(spec.harmonic_freq_hz), 1)
    assert spec.harmonic_number[np.argmax(spec.harmonic_psd[:, 0])] == 3
    df = spec.freq_hz[1] - spec.freq_hz[0]
    assert np.sum(spec.psd[:, 0]) * df == pytest.approx(amp**2 / 2, rel=1e-3)
    # The harmonic bin holds (almost) all the power: no leakage with a boxcar.
    assert spec.harmonic_psd[2, 0] * df == pytest.approx(amp**2 / 2, rel=1e-3)


def test_welch_without_period() -> None:
    n = 20000
    amp = 1.3
    e = np.column_stack([_sine(amp, 1e3, n), _sine(amp / 2, 5e3, n)])
    spec = error_psd(e, DT)
    assert spec.psd.shape == (4096 // 2 + 1, 2)
    assert spec.harmonic_freq_hz.size == 0
    assert spec.harmonic_psd.shape == (0, 2)
    df = spec.freq_hz[1] - spec.freq_hz[0]
    np.testing.assert_allclose(np.sum(spec.psd, axis=0) * df, [amp**2 / 2, amp**2 / 8], rtol=0.02)
    assert spec.freq_hz[np.argmax(spec.psd[:, 0])] == pytest.approx(1e3, abs=df)


@pytest.mark.parametrize(
    ("dt", "period", "match"),
    [(0.0, None, "dt"), (-1e-5, 1e-3, "dt"), (DT, -1.0, "period_s"), (DT, 3e-3, "integer")],
)
def test_error_psd_validation(dt: float, period: float | None, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        error_psd(np.zeros(1000), dt, period_s=period)


def test_learning_transient_geometric_decay() -> None:
    rng = np.random.default_rng(2)
    k = np.arange(30)
    base = np.column_stack([100 * 0.5**k + 1.0, 120 * 0.75**k + 1.2])
    hist = base * (1 + 0.01 * rng.standard_normal(base.shape))
    lt = learning_transient(hist)
    np.testing.assert_array_equal(lt.iterations, np.arange(1, 31))
    np.testing.assert_allclose(lt.final, hist[-1])
    np.testing.assert_allclose(lt.reduction, hist[0] / hist[-1])
    assert lt.reduction[0] > 80
    assert lt.is_monotonic(noise_tol=0.1)
    # Axis 0 settles within 20 % of its minimum by iteration 12, axis 1 does not.
    assert lt.converged_within(12, rel_tol=0.2, axis=0)
    assert not lt.converged_within(12, rel_tol=0.2, axis=1)
    assert not lt.converged_within(12, rel_tol=0.2)
    assert lt.converged_within(26, rel_tol=0.2)
    it = lt.convergence_iteration(rel_tol=0.2)
    assert 9 <= it[0] <= 12
    assert 20 <= it[1] <= 26
    assert lt.converged_within(int(it[1]), rel_tol=0.2, axis=1)
    assert not lt.converged_within(int(it[1]) - 1, rel_tol=0.2, axis=1)


def test_learning_transient_non_monotonic_and_1d() -> None:
    lt = learning_transient([10.0, 5.0, 8.0, 1.0])
    assert lt.rms.shape == (4, 1)
    assert lt.reduction[0] == pytest.approx(10.0)
    assert not lt.is_monotonic(noise_tol=0.1)
    assert lt.is_monotonic(noise_tol=0.6)
    assert lt.convergence_iteration()[0] == 4


def test_learning_transient_validation() -> None:
    with pytest.raises(ValueError, match=">= 0"):
        learning_transient([1.0, -0.5])
    lt = learning_transient([3.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="k must"):
        lt.converged_within(0)
    with pytest.raises(ValueError, match="k must"):
        lt.converged_within(4)
    with pytest.raises(ValueError, match="rel_tol"):
        lt.converged_within(1, rel_tol=-0.1)
    with pytest.raises(ValueError, match="noise_tol"):
        lt.is_monotonic(noise_tol=-1.0)
