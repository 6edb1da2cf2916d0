"""Transfer function fit (seed 003 part 2 §1) on the seed's model sampled at 10 us.

Issue 16 §6 acceptance: coefficients 1.242e11; 9517, 5.773e7, 1.272e11 within 1e-4
relative without noise and 2 % with 0.3 bit rms noise; derived real pole 550.5 Hz,
complex pair 965.2 Hz with damping 0.4995, -3 dB bandwidth 710.6 Hz, each within 1 %.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from microfab.identify import (
    FRF,
    Chirp,
    ChirpDesign,
    LowCoherenceError,
    TFModel,
    UnstableFitError,
    estimate_frf,
    fit_tf,
)

SEED_NUM = (1.242e11,)  # seed 003 part 2 §1
SEED_DEN = (1.0, 9517.0, 5.773e7, 1.272e11)  # seed 003 part 2 §1
SEED_COEFS = np.array([1.242e11, 9517.0, 5.773e7, 1.272e11])  # b0; a2, a1, a0
REAL_POLE_HZ = 550.5  # issue 16 §6, derived from the seed's model
MODE_HZ, MODE_ZETA = 965.2, 0.4995  # issue 16 §6
BANDWIDTH_HZ = 710.6  # issue 16 §6 (the half-power point computes to 710.19 Hz)


def coefficient_errors(model: TFModel) -> np.ndarray:
    """Relative errors of (b0, a2, a1, a0) against the seed's."""
    got = np.array([model.num[-1], *model.den[1:]])
    return got / SEED_COEFS - 1.0


def check_derived(model: TFModel) -> None:
    (real_hz,) = model.real_poles_hz
    ((mode_hz, zeta),) = model.complex_modes
    assert real_hz == pytest.approx(REAL_POLE_HZ, rel=0.01)
    assert mode_hz == pytest.approx(MODE_HZ, rel=0.01)
    assert zeta == pytest.approx(MODE_ZETA, rel=0.01)
    assert model.bandwidth_hz() == pytest.approx(BANDWIDTH_HZ, rel=0.01)


def test_zoh_fit_recovers_the_seeds_coefficients_without_noise(chirp: Chirp, y_clean):
    fit = fit_tf(estimate_frf(chirp, y_clean), n_poles=3, n_zeros=0)
    assert fit.sampling == "zoh" and fit.dt == 1e-5  # the default when dt is known
    assert (fit.model.n_poles, fit.model.n_zeros) == (3, 0)
    err = coefficient_errors(fit.model)
    assert np.max(np.abs(err)) < 1e-4  # acceptance; measured below 1e-11
    check_derived(fit.model)
    assert fit.residual_rms < 1e-9 and fit.max_relative_error < 1e-9
    assert fit.model.is_stable


def test_zoh_fit_with_noise_is_within_two_percent(chirp: Chirp, y_noisy):
    fit = fit_tf(estimate_frf(chirp, y_noisy))
    err = coefficient_errors(fit.model)
    assert np.max(np.abs(err)) < 0.02  # acceptance; measured 1.2e-4 at most (a2, noise seed 16)
    check_derived(fit.model)
    # the noise leaves a weighted residual: 0.3 bit against |Y| of a few bit at 2 kHz
    assert 1e-4 < fit.residual_rms < 0.01


def test_h1_estimate_fits_within_two_percent(chirp: Chirp, y_noisy):
    fit = fit_tf(estimate_frf(chirp, y_noisy, method="h1"))
    # acceptance 2 %; measured 9.4e-4 at most (a0: the Hann window smooths over 3 bins)
    assert np.max(np.abs(coefficient_errors(fit.model))) < 0.02
    check_derived(fit.model)


@pytest.mark.parametrize("y_name", ["y_clean", "y_noisy"])
def test_sampling_modes_half_sample_delay_and_plain_continuous(chirp: Chirp, y_name, request):
    frf = estimate_frf(chirp, request.getfixturevalue(y_name))
    delay = np.abs(coefficient_errors(fit_tf(frf, sampling="delay").model))
    plain_fit = fit_tf(frf, sampling="none")
    plain = np.abs(coefficient_errors(plain_fit.model))
    # issue 16 §2: a ZOH-aware fit misses by 0.03 %, a plain continuous one by 3-6 %.
    # Measured (both records): delay 2.5e-4 at most (b0); none: b0 -4.5 %, a2 -5.4 %,
    # a1 -3.5 %, a0 -6.3 %.
    assert np.max(delay) < 3e-4
    assert 0.03 < np.min(plain) and np.max(plain) < 0.07
    assert plain_fit.sampling == "none" and plain_fit.dt == 1e-5
    # the plain fit's real pole is 7 % low: the derived numbers miss too
    assert abs(plain_fit.model.real_poles_hz[0] / REAL_POLE_HZ - 1) > 0.05


def test_any_orders_a_mirror_mode_on_top(simulate_zoh):
    # the seed's model times an assumed mirror mode at 3 kHz, damping 0.02 (issue 16 §1)
    wm, zm = 2 * np.pi * 3000.0, 0.02
    num = np.polymul(SEED_NUM, [wm**2])
    den = np.polymul(SEED_DEN, [1.0, 2 * zm * wm, wm**2])
    c = ChirpDesign(f1_hz=4000.0).signal()
    frf = estimate_frf(c, simulate_zoh(num, den, c.input))
    fit = fit_tf(frf, n_poles=5, n_zeros=0)
    np.testing.assert_allclose(fit.model.den, den / den[0], rtol=1e-6)
    np.testing.assert_allclose(fit.model.num, num / den[0], rtol=1e-6)
    modes = fit.model.complex_modes
    assert modes[1].frequency_hz == pytest.approx(3000.0, rel=1e-6)
    assert modes[1].damping == pytest.approx(0.02, rel=1e-5)


def test_zeros_and_poles_continuous_data():
    # a lead network times a second-order lag: 1 zero, 3 poles, no sampling
    true = TFModel(num=[2e3 * 50.0, 2e3 * 50.0 * 200.0], den=np.polymul([1, 2000], [1, 60, 4e4]))
    f = np.geomspace(1.0, 2000.0, 300)
    frf = FRF(
        freq_hz=f, response=true.frequency_response(f), coherence=np.full(f.size, np.nan),
        method="table", dt=None, excited_hz=(1.0, 2000.0),
    )  # fmt: skip
    fit = fit_tf(frf, n_poles=3, n_zeros=1)
    assert fit.sampling == "none" and fit.dt is None
    np.testing.assert_allclose(fit.model.den, true.den, rtol=1e-8)
    np.testing.assert_allclose(fit.model.num, true.num, rtol=1e-8)


def test_unstable_fit_is_refused():
    # an FRF computed from a model with a right-half-plane pair (300 Hz, damping -0.2)
    w = 2 * np.pi * 300.0
    bad = TFModel(num=[w**2], den=[1.0, -2 * 0.2 * w, w**2])
    f = np.arange(1.0, 2001.0)
    frf = FRF(
        freq_hz=f, response=bad.frequency_response(f), coherence=np.ones(f.size),
        method="table", dt=None, excited_hz=(1.0, 2000.0),
    )  # fmt: skip
    with pytest.raises(UnstableFitError, match=r"unstable: pole\(s\) 377\S*, 377\S* rad/s") as e:
        fit_tf(frf, n_poles=2)
    assert np.all(e.value.poles.real > 0)
    assert "best stable fit found leaves" in str(e.value)


def test_fit_refusals(chirp: Chirp, y_clean):
    frf = estimate_frf(chirp, y_clean)
    with pytest.raises(ValueError, match=r"n_zeros must not exceed n_poles = 2"):
        fit_tf(frf, n_poles=2, n_zeros=3)
    with pytest.raises(ValueError, match=r"n_poles must be an integer >= 1"):
        fit_tf(frf, n_poles=0)
    with pytest.raises(ValueError, match=r"sampling must be one of zoh, delay, none"):
        fit_tf(frf, sampling="tustin")  # type: ignore[arg-type]
    nodt = FRF(
        freq_hz=frf.freq_hz, response=frf.response, coherence=frf.coherence,
        method="table", dt=None, excited_hz=frf.excited_hz,
    )  # fmt: skip
    with pytest.raises(ValueError, match=r"sampling='zoh' needs the sample time dt"):
        fit_tf(nodt, sampling="zoh")
    assert fit_tf(nodt, dt=1e-5).sampling == "zoh"  # given dt: ZOH by default
    with pytest.raises(ValueError, match=r"above the Nyquist frequency 500 Hz of dt = 0.001 s"):
        fit_tf(frf, dt=1e-3)
    with pytest.raises(ValueError, match=r"band 5-2000 Hz lies outside the excited band"):
        fit_tf(frf, band_hz=(5.0, 2000.0))
    with pytest.raises(ValueError, match=r"holds 2 frequencies .* too few for 4 coefficients"):
        fit_tf(frf, band_hz=(100.0, 101.0))
    low = FRF(
        freq_hz=frf.freq_hz, response=frf.response,
        coherence=np.where((frf.freq_hz > 900) & (frf.freq_hz < 950), 0.5, 1.0),
        method="h1", dt=1e-5, excited_hz=frf.excited_hz,
    )  # fmt: skip
    with pytest.raises(LowCoherenceError, match=r"below 0\.8 from 901 to 949 Hz"):
        fit_tf(low)
    fit = fit_tf(low, band_hz=(10.0, 850.0))  # a band clear of it fits
    assert np.max(np.abs(coefficient_errors(fit.model))) < 1e-4


def test_result_to_json_and_back_and_plot(chirp: Chirp, y_noisy, tmp_path):
    fit = fit_tf(estimate_frf(chirp, y_noisy))
    text = json.dumps(fit.to_dict())
    d = json.loads(text)
    assert d["fit"]["sampling"] == "zoh" and d["fit"]["band_hz"] == [10.0, 2000.0]
    assert d["fit"]["n_poles"] == 3 and d["fit"]["n_averages"] == 3
    assert d["derived"]["real_poles_hz"][0] == pytest.approx(REAL_POLE_HZ, rel=0.01)
    back = TFModel.from_dict(d)
    np.testing.assert_array_equal(back.den, fit.model.den)
    np.testing.assert_array_equal(back.num, fit.model.num)
    assert back.unit == "bit/bit"
    fig = fit.plot(title="seed 003 part 2 Fig. 4")
    assert len(fig.axes) == 3
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["measured (periodic)", "fit (zoh)", "fit, continuous"]
    rel = fit.relative_error()
    assert np.max(np.abs(rel)) == pytest.approx(fit.max_relative_error)
    assert list(tmp_path.iterdir()) == []
