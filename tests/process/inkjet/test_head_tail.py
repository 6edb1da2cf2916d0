"""Head-and-tail measures on simulated shapes and on the same shapes seen by the camera."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.measure.imaging import analyze
from microfab.measure.shadowgraph import Camera, render_sequence
from microfab.process.inkjet.head_tail import head_and_tail, thinning_rate
from microfab.process.inkjet.silhouette import Silhouette

R_NOZZLE = 60e-6


def _drop_on_a_tail(
    head_r: float, tail_r: float, tail_len: float, *, attached: bool = True, t: float = 0.0
) -> Silhouette:
    """A spherical head of radius head_r in front of a uniform tail (m)."""
    z0 = 0.0 if attached else 50e-6
    z = np.linspace(z0, z0 + tail_len + 2 * head_r, 1201)
    zc = z0 + tail_len + head_r
    sphere = np.sqrt(np.clip(head_r**2 - (z - zc) ** 2, 0.0, None))
    r = np.where(z < z0 + tail_len, tail_r, np.maximum(sphere, np.where(z < zc, tail_r, 0.0)))
    r[-1] = 0.0
    if attached:
        r[0] = R_NOZZLE
    else:
        r[0] = 0.0
    return Silhouette(time_s=t, bodies=((z, r),), nozzle_radius_m=R_NOZZLE)


def test_a_head_on_a_thin_tail_is_measured() -> None:
    ht = head_and_tail(_drop_on_a_tail(30e-6, 8e-6, 300e-6))
    assert ht is not None and ht.distinct_head and ht.attached
    assert ht.head_radius_m == pytest.approx(30e-6, rel=1e-3)
    assert ht.tail_length_m == pytest.approx(300e-6, rel=0.02)
    assert ht.tail_mean_radius_m == pytest.approx(8e-6, rel=0.05)
    assert ht.tail_min_radius_m == pytest.approx(8e-6, rel=1e-6)
    assert ht.tip_z_m == pytest.approx(360e-6, rel=1e-9)


def test_a_detached_ligament_keeps_its_tail() -> None:
    ht = head_and_tail(_drop_on_a_tail(25e-6, 5e-6, 200e-6, attached=False))
    assert ht is not None and not ht.attached and ht.distinct_head
    assert ht.tail_length_m == pytest.approx(200e-6, rel=0.02)
    assert ht.tail_min_radius_m == pytest.approx(5e-6, rel=1e-6)  # free tail tip left out


def test_a_plug_has_no_distinct_head() -> None:
    # a slug whose radius falls smoothly from the nozzle to its front: no neck
    z = np.linspace(0.0, 300e-6, 301)
    r = 40e-6 * np.sqrt(np.clip(1.0 - (z / 300e-6) ** 8, 0.0, None))
    r[0] = R_NOZZLE
    ht = head_and_tail(Silhouette(time_s=0.0, bodies=((z, r),), nozzle_radius_m=R_NOZZLE))
    assert ht is not None and not ht.distinct_head and ht.tail_length_m == 0.0
    assert ht.head_radius_m == pytest.approx(40e-6)  # the nozzle rim is not the head
    # the same slug necked at its root (to 10 µm over 5 µm): a neck, but no ligament
    r2 = r.copy()
    r2[1:6] = 10e-6
    ht = head_and_tail(Silhouette(time_s=0.0, bodies=((z, r2),), nozzle_radius_m=R_NOZZLE))
    assert ht is not None and not ht.distinct_head
    assert ht.tail_length_m == pytest.approx(5e-6) and ht.neck_radius_m == 10e-6


def test_nothing_out_of_the_nozzle_gives_none() -> None:
    assert head_and_tail(Silhouette(time_s=0.0, bodies=(), nozzle_radius_m=R_NOZZLE)) is None
    with pytest.raises(ValueError, match="neck_fraction"):
        head_and_tail(_drop_on_a_tail(30e-6, 8e-6, 100e-6), neck_fraction=1.0)


def test_thinning_rate_of_an_exponentially_thinning_ligament() -> None:
    rate = 2.0e4  # 1/s
    times = np.arange(0.0, 100e-6, 10e-6)
    sils = [_drop_on_a_tail(30e-6, 10e-6 * math.exp(-rate * t), 300e-6, t=t) for t in times]
    th = thinning_rate(sils, before_s=95e-6, window_s=50e-6)
    assert th is not None and th.frames == 5
    assert th.rate_per_s == pytest.approx(rate, rel=1e-6)
    assert th.speed_m_s > 0.0
    assert thinning_rate(sils, before_s=5e-6) is None  # one frame is not a slope
    with pytest.raises(ValueError, match="window_s"):
        thinning_rate(sils, before_s=95e-6, window_s=0.0)


def test_the_camera_sees_the_head_and_tail_the_solver_describes() -> None:
    # rendered at 2 µm/pixel and measured back: within about a pixel
    sils = [_drop_on_a_tail(30e-6, 8e-6 * (1.0 - 0.1 * k), 300e-6, t=k * 10e-6) for k in range(4)]
    # the 5th frame is broken behind the head (a gap), so that frame 3 is "before breakup"
    z, r = sils[-1].bodies[0]
    cut = (z > 290e-6) & (z < 300e-6)
    left = z <= 290e-6
    right = z >= 300e-6
    rl, rr = r[left].copy(), r[right].copy()
    rl[-1], rr[0] = 0.0, 0.0
    broken = Silhouette(time_s=40e-6, bodies=((z[left], rl), (z[right], rr)),
                        nozzle_radius_m=R_NOZZLE)  # fmt: skip
    assert cut.any()
    cam = Camera(pixel_size_m=2e-6, width_px=120, height_px=260)
    frames = render_sequence([*sils, broken], cam, seed=0)
    res = analyze(frames, pixel_size_m=2e-6, frame_interval_s=10e-6)
    assert res.breakup_frame == 4
    truth = head_and_tail(sils[3])
    assert truth is not None and res.head_tail is not None
    assert res.head_tail.head_radius_m == pytest.approx(truth.head_radius_m, abs=2e-6)
    assert res.head_tail.tail_length_m == pytest.approx(truth.tail_length_m, abs=6e-6)
    assert res.head_tail.tail_min_radius_m == pytest.approx(truth.tail_min_radius_m, abs=1.5e-6)
    assert res.to_dict()["head_tail"]["distinct_head"] is True
    assert res.thinning is not None and res.thinning.speed_m_s > 0.0


def test_the_neck_behind_the_head_is_found_before_a_thinner_one_at_the_nozzle() -> None:
    # a 47 µm head, a neck of 8 µm behind it, an 11 µm thread and a 3 µm neck at the exit
    # (the Eulerian 1 % NaAlg jet 10 µs before it pinches at the exit)
    z = np.linspace(0.0, 620e-6, 621)
    r = np.full(z.size, 11e-6)
    r[z < 30e-6] = 3e-6 + (z[z < 30e-6] / 30e-6) * 8e-6
    neck = (z > 450e-6) & (z < 500e-6)
    r[neck] = 8e-6
    head = z >= 500e-6
    sphere = np.sqrt(np.clip(47e-6**2 - (z - 573e-6) ** 2, 0.0, None))
    r[head] = np.where(z[head] < 573e-6, np.maximum(sphere[head], 8e-6), sphere[head])
    r[0], r[-1] = R_NOZZLE, 0.0
    ht = head_and_tail(Silhouette(time_s=0.0, bodies=((z, r),), nozzle_radius_m=R_NOZZLE))
    assert ht is not None and ht.distinct_head
    assert 450e-6 < ht.neck_z_m < 530e-6 and ht.neck_radius_m == pytest.approx(8e-6, rel=0.2)
    assert ht.tail_length_m == pytest.approx(ht.neck_z_m)
    assert ht.tail_min_radius_m == pytest.approx(3e-6, rel=0.2)  # the exit neck
