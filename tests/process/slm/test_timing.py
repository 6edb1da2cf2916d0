"""Tests of the RTC vector timing (jumps, marks, delays, sky-writing) in 10 µs ticks."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.geometry.hatch import hatch
from microfab.geometry.layer import Layer
from microfab.geometry.shapes import rectangle
from microfab.process.slm.timing import (
    CATEGORIES,
    RTCDelays,
    RTCSettings,
    ScanSpeeds,
    SkyWriting,
    VectorPath,
    rtc_timeline,
    ticks,
)

BIT = 1.5e-6  # m per bit (assumed, as the twin)


def program() -> VectorPath:
    """Jump 1 mm +x, mark 0.3 mm +y, corner (90°), mark 0.3 mm +x, jump back home."""
    pts = np.array([[0, 0], [1e-3, 0], [1e-3, 0.3e-3], [1.3e-3, 0.3e-3], [0, 0]])
    return VectorPath(pts, np.array([False, True, True, False]))


def expected_jump_back_ticks() -> int:
    # |(1.3, 0.3) mm| / (5 m/s * 10 µs) = 1.334 mm / 50 µm = 26.7 -> 27 ticks
    return int(np.ceil(np.hypot(1.3e-3, 0.3e-3) / 50e-6))


def test_ticks_accepts_multiples_and_names_the_nearest_otherwise():
    assert ticks("jump delay", 750e-6) == 75
    assert ticks("jump delay", 0.0) == 0
    with pytest.raises(ValueError, match=r"nearest is 750 µs \(75 ticks\) or 760 µs"):
        ticks("jump delay", 753e-6)
    with pytest.raises(ValueError, match=r"nearest is 260 µs \(26 ticks\) or 250 µs"):
        RTCDelays(jump_s=257e-6)
    with pytest.raises(ValueError, match="must be non-negative"):
        RTCDelays(mark_s=-10e-6)


def test_plain_rtc_timing_tick_by_tick():
    d = RTCDelays(
        jump_s=750e-6, mark_s=500e-6, polygon_s=50e-6, laser_on_s=100e-6, laser_off_s=450e-6
    )
    tl = rtc_timeline(program(), RTCSettings(delays=d))
    back = expected_jump_back_ticks()
    # jump 1 mm at 5 m/s = 20 ticks, +75; marks 0.3 mm at 0.6 m/s = 50 ticks each, a
    # polygon delay of 5 between them and a mark delay of 50 after; jump back, +75
    np.testing.assert_array_equal(tl.n, [20, 50, 50, back])
    np.testing.assert_array_equal(tl.hold, [75, 5, 50, 75])
    assert tl.total_ticks == 20 + 75 + 50 + 5 + 50 + 50 + back + 75
    br = tl.breakdown_s()
    assert tuple(br) == CATEGORIES
    assert br["mark"] == pytest.approx(100e-5) and br["polygon_delay"] == pytest.approx(5e-5)
    assert br["jump_delay"] == pytest.approx(150e-5) and br["mark_delay"] == pytest.approx(50e-5)
    assert sum(br.values()) == pytest.approx(tl.total_s)
    # one polyline: laser on 10 ticks after its first step, off 45 after its last
    np.testing.assert_array_equal(tl.laser_on_tick, [95 + 10])
    np.testing.assert_array_equal(tl.laser_off_tick, [95 + 50 + 5 + 50 + 45])
    np.testing.assert_allclose(tl.laser_on_target, [[1e-3 / BIT, 0.0]])
    np.testing.assert_allclose(tl.laser_off_target, [[1.3e-3 / BIT, 0.3e-3 / BIT]])


def test_variable_polygon_delay_scales_with_the_turn():
    d = RTCDelays(polygon_s=50e-6, variable_polygon=True)
    tl = rtc_timeline(program(), RTCSettings(delays=d))
    assert tl.hold[1] == 3  # 90° of 180°: ceil(5 * 0.5)
    straight = VectorPath(np.array([[0, 0], [1e-3, 0], [2e-3, 0]]), np.array([True, True]))
    assert rtc_timeline(straight, RTCSettings(delays=d)).hold[0] == 0


def test_the_command_steps_at_most_one_speed_per_tick_and_reaches_every_vertex():
    tl = rtc_timeline(program())
    cmd = tl.command()
    assert cmd.shape == (tl.total_ticks, 2)
    step = np.hypot(*np.diff(np.vstack([[0.0, 0.0], cmd]), axis=0).T)
    assert step.max() <= 5.0 * 1e-5 / BIT * (1 + 1e-12)  # the jump speed in bit per tick
    ends = tl.start + tl.n - 1  # last motion tick of each segment
    np.testing.assert_allclose(cmd[ends], tl.p1, atol=1e-9)
    np.testing.assert_allclose(cmd[-1], [0.0, 0.0], atol=1e-9)


@pytest.mark.parametrize(("n_prev", "n_post"), [(3, 2), (0, 4)])
def test_sky_writing_mode_1_adds_2_nprev_plus_2_npost_per_mark(n_prev, n_post):
    plain = rtc_timeline(program())
    s = RTCSettings(sky_writing=SkyWriting(mode=1, n_prev=n_prev, n_post=n_post))
    tl = rtc_timeline(program(), s)
    br, br0 = tl.breakdown_s(), plain.breakdown_s()
    assert br["sky_writing"] == pytest.approx(2 * (2 * n_prev + 2 * n_post) * 1e-5)
    assert br["mark_delay"] == 0.0 and br["polygon_delay"] == 0.0  # replaced
    for cat in ("mark", "jump", "jump_delay"):
        assert br[cat] == pytest.approx(br0[cat])
    assert tl.laser_on_tick.size == 2  # each mark its own laser run
    np.testing.assert_allclose(tl.command()[-1], 0.0, atol=1e-9)


@pytest.mark.parametrize("mode", [2, 3])
def test_sky_writing_modes_2_and_3_add_at_least_nprev_plus_npost(mode):
    # limit 100°: the 90° corner stays a polygon corner in mode 3
    sky = SkyWriting(mode=mode, n_prev=3, n_post=2, limit_angle_deg=100.0)
    tl = rtc_timeline(program(), RTCSettings(sky_writing=sky))
    br = tl.breakdown_s()
    per_polyline = (3 + 2) * 1e-5
    if mode == 2:  # every mark sky-written, plus the sky jump across the corner
        assert br["sky_writing"] >= 2 * per_polyline
        assert br["polygon_delay"] == 0.0 and tl.laser_on_tick.size == 2
    else:  # one polyline: run-in before, run-out after, the corner keeps its delay
        assert br["sky_writing"] == pytest.approx(per_polyline)
        assert br["polygon_delay"] == pytest.approx(5e-5) and tl.laser_on_tick.size == 1
    assert br["mark_delay"] == 0.0
    # the jump goes to the run-in start: 3 ticks of mark speed before the mark, along it
    first_mark = int(np.flatnonzero(tl.kind == 0)[0])
    np.testing.assert_allclose(tl.p0[first_mark - 1], [1e-3 / BIT, -3 * 0.6e-5 / BIT], atol=1e-9)
    sharp = SkyWriting(mode=3, n_prev=3, n_post=2, limit_angle_deg=80.0)
    tl3 = rtc_timeline(program(), RTCSettings(sky_writing=sharp))
    assert tl3.laser_on_tick.size == 2 and tl3.breakdown_s()["polygon_delay"] == 0.0


def test_a_hatch_becomes_a_vector_path_with_its_jumps():
    sv = hatch(Layer((rectangle(2e-3, 1e-3),)), spacing=1e-4)
    path = VectorPath.from_scan_vectors(sv, start=(-5e-3, 0.0))
    assert path.n_marks == len(sv) and path.n_jumps == len(sv)  # start jump + between marks
    assert path.summary()["mark_length_m"] == pytest.approx(sv.total_mark_length)
    tl = rtc_timeline(path)
    assert tl.laser_on_tick.size == len(sv)  # every hatch mark its own laser run


def test_speeds_and_settings_are_checked():
    with pytest.raises(ValueError, match="mark speed mark_m_s must be positive"):
        ScanSpeeds(mark_m_s=0.0)
    with pytest.raises(ValueError, match="sky-writing mode must be 0, 1, 2 or 3"):
        SkyWriting(mode=4)
    with pytest.raises(ValueError, match="is_mark needs one flag per vector"):
        VectorPath(np.zeros((3, 2)), np.array([True]))
