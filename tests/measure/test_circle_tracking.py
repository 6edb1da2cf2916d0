"""Seed 001 §4.2 metrics against hand numbers on synthetic traces of the pattern."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from microfab.measure.circle_tracking import (
    contour_error,
    pattern_metrics,
    period_rms,
    phase_of,
    tracking_metrics,
)
from microfab.report.circle_tracking import tracking_table
from microfab.trajectory.circle_pattern import (
    PatternConfig,
    PatternReference,
    pattern_reference,
)

DT = 1e-4
CFG = PatternConfig(period_s=0.05, periods=4, pause_s=0.02, move_s=0.03, ramp_s=0.02)


def _ref() -> PatternReference:
    return pattern_reference(CFG, DT)


def _metrics(ref: PatternReference, y: np.ndarray, laser: np.ndarray | None = None):
    on = np.zeros(ref.n_samples, bool) if laser is None else laser
    return pattern_metrics(ref, y, on)


def _radial(ref: PatternReference, delta: np.ndarray | float) -> np.ndarray:
    """Output = reference pushed out radially by ``delta`` (mm) over every circle run."""
    y = ref.position.copy()
    for i, c in enumerate(ref.centres):
        sl = ref.circle_slice(i)
        u = (ref.position[sl] - c) / ref.radius_mm
        y[sl] = c + (ref.radius_mm + np.broadcast_to(delta, (u.shape[0],))[:, None]) * u
    return y


def test_radial_offset_gives_its_contour_rms_and_half_power_per_axis() -> None:
    ref = _ref()
    d = 2e-4  # mm = 200 nm outside every circle
    m = _metrics(ref, _radial(ref, d))
    assert m.contour_rms_nm == pytest.approx(200.0, rel=1e-9)
    # e = −d (cos θ, sin θ) over whole periods: each axis carries half the power
    np.testing.assert_allclose(m.axial_rms_nm, 200.0 / math.sqrt(2.0), rtol=1e-9)
    np.testing.assert_allclose(m.period_rms_nm, 200.0, rtol=1e-9)
    assert m.period_rms_nm.shape == (4, 4)
    np.testing.assert_allclose(m.contour_vs_phase_nm, 200.0, rtol=1e-9)
    assert m.phase_rad.shape == (360 * 4,)
    assert m.phase_rad[0] == pytest.approx(math.pi / 360) and m.phase_rad[-1] < 8 * math.pi
    assert m.gate_period == (None,) * 4 and m.exposed_rms_nm == (None,) * 4


def test_translation_gives_the_axis_error_and_a_cosine_contour() -> None:
    ref = _ref()
    d = 1e-4  # mm: the stage lags 100 nm in x everywhere
    y = ref.position + np.array([d, 0.0])
    m = _metrics(ref, y)
    np.testing.assert_allclose(m.axial_rms_nm, [100.0, 0.0], atol=1e-9)
    # ‖r + d − c‖ − R = d cos θ + O(d²/2R): RMS d/√2 within d²/2R
    bound_nm = d**2 / (2 * ref.radius_mm) * 1e6
    assert abs(m.contour_rms_nm - 100.0 / math.sqrt(2.0)) <= bound_nm
    # Fig. 13b: phase 0 at the run start (angle 0 of the pattern), so d cos(phase); a bin
    # averages samples within half its width of its centre, and |d/dθ d cos θ| <= d
    width = 2 * math.pi / 360
    want = 100.0 * np.cos(m.phase_rad)
    np.testing.assert_allclose(m.contour_vs_phase_nm, want, atol=100.0 * width / 2 + bound_nm)
    assert np.max(np.abs(m.contour_vs_phase_nm - want)) > 0.1  # the bound is not idle
    # the moves between circles carry no error here, and are left out anyway
    y2 = y.copy()
    y2[: ref.starts[0]] += 1.0
    assert _metrics(ref, y2).axial_rms_nm[0] == pytest.approx(100.0)


def test_period_rms_follows_a_decaying_error_and_the_gate_period_is_counted() -> None:
    ref = _ref()
    n, k = ref.period_samples, ref.periods
    decay = 1e-3 * 10.0 ** -np.repeat(np.arange(k), n)  # 1000, 100, 10, 1 nm per period
    m = _metrics(ref, _radial(ref, decay))
    np.testing.assert_allclose(m.period_rms_nm, [[1000.0, 100.0, 10.0, 1.0]] * 4, rtol=1e-9)
    laser = np.zeros(ref.n_samples, bool)
    s0, s1, s3 = ref.starts[0], ref.starts[1], ref.starts[3]
    laser[s0 + 2 * n : s0 + 3 * n] = True  # circle 1: after 2 periods -> period 3
    laser[s1 + 3 * n - 40 : s1 + 4 * n - 40] = True  # circle 2: warm-up lead of 40 samples
    laser[s3 - 5 : s3 + 10] = True  # circle 4: advanced before its first period
    m = _metrics(ref, _radial(ref, decay), laser)
    assert m.gate_period == (3, 4, None, 1)
    assert m.gate_sample == (s0 + 2 * n, s1 + 3 * n - 40, None, s3 - 5)
    assert m.exposed_rms_nm[0] == pytest.approx(10.0, rel=1e-9)
    assert m.exposed_rms_nm[2] is None
    # circle 2's exposure: 40 samples of period 3 (10 nm), the rest of period 4 (1 nm)
    want = math.sqrt((40 * 10.0**2 + (n - 40) * 1.0**2) / n)
    assert m.exposed_rms_nm[1] == pytest.approx(want, rel=1e-9)


def test_summary_is_json_and_the_table_stands_beside_the_seed() -> None:
    ref = _ref()
    laser = np.zeros(ref.n_samples, bool)
    laser[ref.starts[0] + 3 * ref.period_samples :][: ref.period_samples] = True
    m = _metrics(ref, _radial(ref, 5e-4), laser)
    s = json.loads(json.dumps(m.summary(), allow_nan=False))
    assert s["contour_rms_nm"] == pytest.approx(500.0)
    assert s["gate_period"] == [4, None, None, None]
    assert s["gate_time_s"][0] == pytest.approx((ref.starts[0] + 3 * ref.period_samples) * DT)
    assert s["seed"]["axial_rms_nm"] == {"x": 485.8, "y": 885.8}
    text = tracking_table(m).to_text()
    assert "500.0 / 769.5" in text and "353.6 / 485.8" in text and "353.6 / 885.8" in text
    assert "4 / 3-4" in text and "— / 3-4" in text and "0.65" in text


def test_helpers_on_hand_cases() -> None:
    e = np.tile([3.0, 4.0], (12, 1))
    e[4:8] *= 2.0
    np.testing.assert_allclose(period_rms(e, 0, 4, 3), [5.0, 10.0, 5.0])
    np.testing.assert_allclose(period_rms(e[:, 0], 4, 4, 1), [6.0])
    c = np.array([1.0, -2.0])
    p = c + np.array([[0.5, 0.0], [0.0, 0.25], [-0.1, 0.0]])
    np.testing.assert_allclose(contour_error(p, c, 0.25), [0.25, 0.0, -0.15])
    t = np.linspace(0.0, 2.0, 801)[:-1]  # two turns, counter-clockwise from angle π/2
    ring = c + np.column_stack(
        [np.cos(2 * np.pi * t + np.pi / 2), np.sin(2 * np.pi * t + np.pi / 2)]
    )
    ph = phase_of(ring, c)
    assert ph[0] == 0.0 and ph[-1] == pytest.approx(4 * np.pi - 2 * np.pi / 400)
    assert np.all(np.diff(ph) > 0)
    assert phase_of(ring[::-1], c)[-1] < 0  # clockwise is negative


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"output": np.full((10, 2), np.nan)}, "output holds nan at sample 0"),
        ({"output": np.zeros((10, 3))}, r"output must be shaped \(10, 2\)"),
        ({"laser": np.zeros(10)}, "laser must be bool"),
        ({"starts": (0, 3)}, "overlaps the previous one"),
        ({"starts": (0, 7)}, "ends past the 10 samples"),
        ({"centres": np.zeros((1, 2))}, "one per start"),
        ({"period_samples": 1}, "period_samples must be an integer >= 2"),
        ({"bins_per_period": 9}, "must not exceed period_samples"),
        ({"radius": -1.0}, "radius must be positive"),
    ],
)
def test_bad_inputs_are_refused(change: dict, match: str) -> None:
    t = np.arange(10) / 4
    ring = np.column_stack([np.cos(2 * np.pi * t), np.sin(2 * np.pi * t)])
    kw = {
        "reference": ring,
        "output": ring,
        "laser": np.zeros(10, bool),
        "starts": (0, 4),
        "period_samples": 4,
        "periods": 1,
        "centres": np.zeros((2, 2)),
        "radius": 1.0,
        "bins_per_period": 4,
    } | change
    ref, out, laser = kw.pop("reference"), kw.pop("output"), kw.pop("laser")
    with pytest.raises(ValueError, match=match):
        tracking_metrics(ref, out, laser, **kw)


@pytest.mark.parametrize("bins", [None, 250, 125])
def test_every_phase_bin_holds_samples_when_the_bins_divide_the_period(bins: int | None) -> None:
    cfg = PatternConfig(
        n_circles=1, period_s=0.025, periods=2, pause_s=0.01, move_s=0.01, ramp_s=0.01
    )
    ref = pattern_reference(cfg, DT)  # 250 samples a period: samples on the bin edges
    m = tracking_metrics(
        ref.position,
        _radial(ref, 1e-4),
        np.zeros(ref.n_samples, bool),
        starts=ref.starts,
        period_samples=250,
        periods=2,
        centres=ref.centres,
        radius=ref.radius_mm,
        bins_per_period=bins,
    )
    assert m.phase_rad.size == 2 * (bins or 250)
    np.testing.assert_allclose(m.contour_vs_phase_nm, 100.0, rtol=1e-9)
