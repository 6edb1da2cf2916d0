from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from microfab.trajectory.waveform import (
    MAX_AMPLITUDE_V,
    SEED003_VOLTAGES_V,
    Waveform,
    seed003_waveform,
)

US = 1e-6


def test_seed003_waveform_matches_table_1() -> None:
    w = seed003_waveform()
    assert w.kind == "bipolar"
    assert w.amplitude_v == 50.0
    assert w.rise_s == pytest.approx(3 * US, abs=1e-15)
    assert w.fall_s == pytest.approx(3 * US, abs=1e-15)
    assert w.dwell_s == pytest.approx(30 * US, abs=1e-15)
    assert w.echo_s == pytest.approx(30 * US, abs=1e-15)
    assert w.frequency_hz == 50.0
    assert SEED003_VOLTAGES_V == (40.0, 45.0, 50.0, 55.0, 60.0, 65.0, 70.0)
    assert seed003_waveform(65.0).amplitude_v == 65.0


@pytest.mark.parametrize(
    ("kind", "times_us", "volts"),
    [
        ("unipolar", [0, 2, 7, 11], [0, 10, 10, 0]),
        ("bipolar", [0, 2, 7, 11, 13, 15], [0, 10, 10, -10, -10, 0]),
        ("tripolar", [0, 2, 7, 11, 13, 15, 17, 21], [0, 10, 10, -10, -10, 5, 5, 0]),
    ],
)
def test_breakpoints(kind: str, times_us: list[float], volts: list[float]) -> None:
    w = Waveform(
        kind=kind,
        amplitude_v=10.0,
        rise_s=2 * US,
        fall_s=4 * US,
        dwell_s=5 * US,
        echo_s=2 * US,
        final_s=2 * US,
        final_ratio=0.5,
        frequency_hz=1e3,
    )
    t, v = w.breakpoints()
    np.testing.assert_allclose(t / US, times_us, atol=1e-9)
    np.testing.assert_allclose(v, volts, atol=1e-12)
    assert w.duration_s == pytest.approx(times_us[-1] * US, rel=1e-12)


def test_plateau_values_and_ramps_of_seed_waveform() -> None:
    w = seed003_waveform(40.0)
    # rise 0-3 µs, dwell 3-33, fall 33-36, echo 36-66, rise 66-69
    np.testing.assert_allclose(w.voltage(np.array([5, 18, 32.9]) * US), 40.0, atol=1e-9)
    np.testing.assert_allclose(w.voltage(np.array([36.1, 50, 65.9]) * US), -40.0, atol=1e-9)
    np.testing.assert_allclose(w.voltage(np.array([69.1, 500, 19_999]) * US), 0.0, atol=0)
    assert float(w.voltage(1.5 * US)) == pytest.approx(20.0, rel=1e-12)  # mid-rise
    assert float(w.voltage(34.5 * US)) == pytest.approx(0.0, abs=1e-9)  # middle of +V -> -V
    assert float(w.voltage(67.5 * US)) == pytest.approx(-20.0, rel=1e-9)
    assert w.duration_s == pytest.approx(69 * US, rel=1e-12)


@pytest.mark.parametrize("kind", ["unipolar", "bipolar", "tripolar"])
def test_area_matches_closed_form(kind: str) -> None:
    v, r = 37.0, 0.4
    rise, fall, dwell, echo, final = 2 * US, 5 * US, 11 * US, 7 * US, 13 * US
    w = Waveform(
        kind=kind,
        amplitude_v=v,
        rise_s=rise,
        fall_s=fall,
        dwell_s=dwell,
        echo_s=echo,
        final_s=final,
        final_ratio=r,
        frequency_hz=100.0,
    )
    expected = {
        # positive trapezoid: plateau + two half ramps
        "unipolar": v * (dwell + rise / 2 + fall / 2),
        # the +V -> -V ramp has zero area; the echo trapezoid closes with a rise
        "bipolar": v * (rise / 2 + dwell) - v * (echo + rise / 2),
        # -V -> +rV over a rise has area (r - 1) V rise / 2
        "tripolar": v * (rise / 2 + dwell)
        - v * echo
        + (r - 1) * v * rise / 2
        + r * v * final
        + r * v * fall / 2,
    }[kind]
    t, volts = w.breakpoints()
    assert np.trapezoid(volts, t) == pytest.approx(expected, rel=1e-12)
    # the callable integrates to the same value (independent adaptive quadrature)
    area, _ = quad(w.voltage, 0.0, w.duration_s, points=list(t[1:-1]), epsabs=1e-15)
    assert area == pytest.approx(expected, rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("kind", ["unipolar", "bipolar", "tripolar"])
def test_slope_integrates_back_to_voltage(kind: str) -> None:
    w = Waveform(kind=kind, amplitude_v=55.0, frequency_hz=1e3)
    dt = 10e-9
    t = np.arange(0.0, 1.2 * w.duration_s, dt)
    # the slope is piecewise constant with corners on this grid: a midpoint sum is exact
    v_int = np.concatenate(([0.0], np.cumsum(w.slope(t[:-1] + dt / 2) * dt)))
    np.testing.assert_allclose(v_int, w.voltage(t), atol=1e-9 * w.amplitude_v)


def test_slope_values() -> None:
    w = seed003_waveform(30.0)
    s = w.slope(np.array([0.0, 1.0, 3.0, 20.0, 33.0, 34.0, 40.0, 67.0, 69.0, 100.0]) * US)
    expected = np.array([10, 10, 0, 0, -20, -20, 0, 10, 0, 0]) * 1e6
    np.testing.assert_allclose(s, expected, rtol=1e-9, atol=1e-3)


def test_periodicity() -> None:
    w = seed003_waveform()
    t = np.linspace(0.0, w.period_s, 5001)
    for shift in (1, 2, -1, 7):
        np.testing.assert_allclose(w.voltage(t + shift * w.period_s), w.voltage(t), atol=1e-9)
        np.testing.assert_allclose(w.slope(t + shift * w.period_s + 1e-9), w.slope(t + 1e-9))
    assert float(w.voltage(w.period_s + 20 * US)) == pytest.approx(50.0, rel=1e-12)


def test_voltage_shape_and_scalar() -> None:
    w = seed003_waveform()
    assert np.asarray(w.voltage(10 * US)).shape == ()
    assert w.voltage(np.zeros((3, 4))).shape == (3, 4)
    assert w.slope(np.zeros((2, 5))).shape == (2, 5)


def test_sample_grid_spacing_is_exact() -> None:
    w = seed003_waveform()
    t, v = w.sample(20e6)
    assert t.size == 69 * 20 + 1
    np.testing.assert_array_equal(t, np.arange(t.size) / 20e6)
    assert v[0] == 0.0 and v[-1] == pytest.approx(0.0, abs=1e-9)
    assert v.max() == pytest.approx(50.0) and v.min() == pytest.approx(-50.0)
    t2, _ = w.sample(1e6, 100 * US)
    assert t2.size == 101
    assert t2[-1] == pytest.approx(100 * US, rel=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"amplitude_v": 0.0}, "amplitude_v"),
        ({"amplitude_v": -5.0}, "amplitude_v"),
        ({"amplitude_v": MAX_AMPLITUDE_V + 1}, "driver range"),
        ({"amplitude_v": float("nan")}, "amplitude_v"),
        ({"rise_s": 0.0}, "rise_s"),
        ({"fall_s": -1e-6}, "fall_s"),
        ({"dwell_s": 0.0}, "dwell_s"),
        ({"echo_s": float("inf")}, "echo_s"),
        ({"final_s": 0.0}, "final_s"),
        ({"final_ratio": 0.0}, "final_ratio"),
        ({"final_ratio": 1.5}, "final_ratio"),
        ({"frequency_hz": 0.0}, "frequency_hz"),
        ({"frequency_hz": 20e3}, "period"),
        ({"kind": "square"}, "kind"),
    ],
)
def test_validation(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"kind": "bipolar", "amplitude_v": 50.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        Waveform(**args)  # type: ignore[arg-type]


def test_validation_message_names_value_and_unit() -> None:
    with pytest.raises(ValueError, match=r"dwell_s .* -3e-06 s"):
        Waveform(kind="unipolar", amplitude_v=10.0, dwell_s=-3e-6)


def test_sample_validation() -> None:
    w = seed003_waveform()
    with pytest.raises(ValueError, match="sample_rate_hz"):
        w.sample(0.0)
    with pytest.raises(ValueError, match="duration_s"):
        w.sample(1e6, -1.0)


def test_unipolar_ignores_echo_and_frequency_bound() -> None:
    # a unipolar train fits a period that would be too short for the bipolar one
    w = Waveform(kind="unipolar", amplitude_v=10.0, echo_s=1.0, frequency_hz=1 / 40e-6)
    assert w.duration_s == pytest.approx(36 * US)
    with pytest.raises(ValueError, match="period"):
        Waveform(kind="bipolar", amplitude_v=10.0, frequency_hz=1 / 40e-6)
