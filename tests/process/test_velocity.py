from __future__ import annotations

import numpy as np
import pytest

from microfab.process.velocity import (
    SEED000_BEAM_VELOCITY,
    BeamVelocity,
    BeamVelocityParams,
    beam_velocity,
    target_speed_mm_s,
)

FS = 1e6  # 1 MHz sampling
DT = 1.0 / FS


def _circle(radius_v: float, features_per_s: float) -> np.ndarray:
    n = round(FS / features_per_s)
    t = np.arange(n) * DT
    w = 2 * np.pi * features_per_s
    return np.column_stack([radius_v * np.cos(w * t), radius_v * np.sin(w * t)])


def _square(half_side_v: float, features_per_s: float) -> np.ndarray:
    """Square traced once per period at constant speed: trapezoidal x(t), y(t)."""
    n = round(FS / features_per_s)
    s = np.arange(n) / n * 4.0  # edge coordinate in [0, 4)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]], dtype=float)
    x = np.interp(s, np.arange(5), corners[:, 0])
    y = np.interp(s, np.arange(5), corners[:, 1])
    return half_side_v * np.column_stack([x, y])


def test_seed_defaults() -> None:
    p = SEED000_BEAM_VELOCITY
    assert p.cutoff_hz == 20e3
    assert p.order == 4
    assert p.scale_mm_per_v == (0.3, 0.3)


def test_target_speed_matches_seed() -> None:
    assert [target_speed_mm_s(0.6, r) for r in (100, 200, 400)] == pytest.approx(
        [240.0, 480.0, 960.0]
    )


@pytest.mark.parametrize(("side", "rate"), [(0.0, 100.0), (0.6, -1.0), (np.nan, 100.0)])
def test_target_speed_validation(side: float, rate: float) -> None:
    with pytest.raises(ValueError, match="must be positive"):
        target_speed_mm_s(side, rate)


def test_circle_constant_speed_periodic() -> None:
    rate = 400.0
    pos = _circle(1.0, rate)
    bv = beam_velocity(pos, DT, periodic=True)
    assert isinstance(bv, BeamVelocity)
    assert bv.speed_mm_s.shape == (pos.shape[0],)
    assert bv.velocity_mm_s.shape == pos.shape
    expected = 1.0 * 2 * np.pi * rate * 0.3  # r·ω·scale ≈ 754 mm/s
    np.testing.assert_allclose(bv.speed_mm_s, expected, rtol=5e-3)
    assert bv.max_rel_error(expected) < 5e-3
    assert bv.mean == pytest.approx(expected, rel=1e-3)
    assert bv.std < 1e-3 * expected
    assert bv.min <= bv.mean <= bv.max


def test_circle_non_periodic_interior_matches_periodic() -> None:
    pos = _circle(1.0, 400.0)
    periodic = beam_velocity(pos, DT, periodic=True)
    plain = beam_velocity(pos, DT)
    interior = slice(500, -500)
    np.testing.assert_allclose(plain.speed_mm_s[interior], periodic.speed_mm_s[interior], rtol=1e-3)


def test_noise_is_filtered() -> None:
    rng = np.random.default_rng(0)
    pos = _circle(1.0, 400.0) + 1e-3 * rng.standard_normal((2500, 2))  # 1 mV encoder noise
    expected = 2 * np.pi * 400.0 * 0.3
    bv = beam_velocity(pos, DT, periodic=True)
    # Filtered noise: ~0.6 % std expected from the 20 kHz bandwidth.
    assert bv.std < 0.01 * expected
    assert bv.max_rel_error(expected) < 0.03
    # Without the filter the differentiated noise would dominate (~700 V/s ≈ 210 mm/s).
    raw = np.hypot(*np.gradient(pos, DT, axis=0).T) * 0.3
    assert np.std(raw) > 10 * bv.std


def test_square_mean_close_to_target() -> None:
    rate = 400.0
    pos = _square(1.0, rate)  # ±1 V, 0.6 mm square at 0.3 mm/V
    bv = beam_velocity(pos, DT, periodic=True)
    target = target_speed_mm_s(0.6, rate)
    assert target == pytest.approx(960.0)
    assert bv.mean == pytest.approx(target, rel=0.02)
    # The filtered corners slow the beam down: a clear dip below target.
    assert bv.min < 0.9 * target
    # Along the middle of an edge the speed is the target.
    mid_edge = pos.shape[0] // 8
    assert bv.speed_mm_s[mid_edge] == pytest.approx(target, rel=1e-3)


def test_per_axis_scale_and_single_axis() -> None:
    pos = _circle(1.0, 400.0)
    params = BeamVelocityParams(scale_mm_per_v=(0.3, 0.6))
    bv = beam_velocity(pos, DT, params, periodic=True)
    w = 2 * np.pi * 400.0
    assert np.max(np.abs(bv.velocity_mm_s[:, 1])) == pytest.approx(0.6 * w, rel=5e-3)
    one = beam_velocity(pos[:, 0], DT, BeamVelocityParams(scale_mm_per_v=(0.3,)), periodic=True)
    assert one.velocity_mm_s.shape == (pos.shape[0], 1)
    np.testing.assert_allclose(one.speed_mm_s, np.abs(bv.velocity_mm_s[:, 0]), atol=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"cutoff_hz": 0.0}, "cutoff_hz"),
        ({"order": 0}, "order"),
        ({"order": 2.5}, "order"),
        ({"scale_mm_per_v": ()}, "scale_mm_per_v"),
        ({"scale_mm_per_v": (0.3, -0.3)}, r"scale_mm_per_v\[1\]"),
    ],
)
def test_params_validation(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        BeamVelocityParams(**kwargs)  # type: ignore[arg-type]


def test_beam_velocity_validation() -> None:
    pos = _circle(1.0, 400.0)
    with pytest.raises(ValueError, match="dt"):
        beam_velocity(pos, 0.0)
    with pytest.raises(ValueError, match="Nyquist"):
        beam_velocity(pos, 1e-4)  # Nyquist 5 kHz < 20 kHz
    with pytest.raises(ValueError, match="axes"):
        beam_velocity(np.zeros((100, 3)), DT)
    with pytest.raises(ValueError, match="samples"):
        beam_velocity(pos[:10], DT)
    with pytest.raises(ValueError, match="target_mm_s"):
        beam_velocity(pos, DT).max_rel_error(0.0)
