from __future__ import annotations

import json

import imageio.v3 as iio
import numpy as np
import pytest
import tifffile

from microfab.measure.shadowgraph import (
    SIDECAR_NAME,
    Camera,
    render,
    render_sequence,
    write_frames,
)
from microfab.process.inkjet.silhouette import Silhouette

NOZ_R = 60e-6
SHARP = Camera(
    pixel_size_m=2e-6, width_px=64, height_px=96, blur_px=0.0, noise_std=0.0, nozzle_rows=10
)


def _cylinder(z0: float, z1: float, r: float) -> tuple[np.ndarray, np.ndarray]:
    z = np.linspace(z0, z1, 11)
    return z, np.full_like(z, r)


def _darkness(img: np.ndarray, cam: Camera) -> np.ndarray:
    """Coverage recovered from a noise-free, unblurred image."""
    return (cam.background - img) / (cam.background - cam.shadow)


# ------------------------------------------------------------------ validation


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"bit_depth": 12}, "bit_depth"),
        ({"shadow": 0.9}, "shadow"),
        ({"nozzle_rows": 200, "height_px": 100}, "nozzle_rows"),
        ({"pixel_size_m": -1.0}, "pixel_size_m"),
        ({"blur_px": -0.5}, "blur_px"),
        ({"vignette": 1.0}, "vignette"),
        ({"width_px": 1}, "width_px"),
    ],
)
def test_camera_validation(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Camera(**kwargs)


# ------------------------------------------------------------------ rendering


def test_coverage_is_exact_across_rows_and_along_the_axis() -> None:
    cam = SHARP
    r = 5.25 * cam.pixel_size_m  # a chord of 10.5 px, edges inside pixels
    z0, z1 = 20e-6, 60.5e-6  # 10 px and 20.25 px below the exit plane
    s = Silhouette(time_s=0.0, bodies=(_cylinder(z0, z1, r),), nozzle_radius_m=NOZ_R)
    cover = _darkness(render(s, cam), cam)
    rows = cover[cam.nozzle_rows :]
    # Each fully covered row holds a chord of exactly 2 r / px.
    assert rows[15].sum() == pytest.approx(10.5, abs=1e-9)
    # Total dark area = 2 r (z1 - z0) / px^2 (anti-aliased ends, supersample 4).
    assert rows.sum() == pytest.approx(10.5 * 20.25, abs=1e-9)
    # Symmetric about the centre line, nothing outside the body.
    np.testing.assert_allclose(rows, rows[:, ::-1], atol=1e-12)
    assert rows[:10].max() == 0.0 and rows[31:].max() == 0.0
    # The nozzle block: rows above the exit plane are dark over 2 x 3 nozzle radii.
    assert cover[: cam.nozzle_rows].sum(axis=1) == pytest.approx(
        np.full(cam.nozzle_rows, min(6 * NOZ_R / cam.pixel_size_m, cam.width_px))
    )


def test_render_range_noise_and_reproducibility() -> None:
    cam = Camera(width_px=48, height_px=80, noise_std=0.05, blur_px=1.0)
    s = Silhouette(time_s=0.0, bodies=(_cylinder(0.0, 80e-6, 20e-6),), nozzle_radius_m=NOZ_R)
    a = render(s, cam)
    assert a.shape == (80, 48)
    assert a.min() >= 0.0 and a.max() <= 1.0
    np.testing.assert_array_equal(a, render(s, cam))  # rng=None: seeded, reproducible
    b = render(s, cam, rng=np.random.default_rng(5))
    assert np.std(a - b) == pytest.approx(0.05 * np.sqrt(2), rel=0.1)
    seq1 = render_sequence([s, s], cam, seed=3)
    seq2 = render_sequence([s, s], cam, seed=3)
    np.testing.assert_array_equal(seq1, seq2)
    assert not np.array_equal(seq1[0], seq1[1])  # independent noise per frame
    assert render_sequence([], cam).shape == (0, 80, 48)


def test_vignette_darkens_the_corners() -> None:
    cam = Camera(width_px=40, height_px=60, noise_std=0.0, blur_px=0.0, vignette=0.2)
    img = render(Silhouette(time_s=0.0, bodies=(), nozzle_radius_m=5e-6), cam)
    assert img[-1, 0] < img[40, 20] < cam.background + 1e-12
    assert img[-1, 0] == pytest.approx(cam.background * 0.8, rel=0.05)


# ------------------------------------------------------------------ files and figure


@pytest.mark.parametrize(("fmt", "bits"), [("png", 8), ("png", 16), ("tiff", 16), ("tiff", 8)])
def test_write_frames(tmp_path, fmt: str, bits: int) -> None:
    cam = Camera(width_px=24, height_px=32, bit_depth=bits)
    frames = np.linspace(0.0, 1.0, 3 * 32 * 24).reshape(3, 32, 24)
    paths = write_frames(frames, tmp_path / "run", camera=cam, frame_interval_s=5e-6, fmt=fmt)
    ext = "png" if fmt == "png" else "tif"
    assert [p.name for p in paths] == [f"frame_{i:04d}.{ext}" for i in range(3)]
    data = tifffile.imread(paths[1]) if fmt == "tiff" else iio.imread(paths[1])
    assert data.dtype == (np.uint8 if bits == 8 else np.uint16)
    full = (1 << bits) - 1
    np.testing.assert_array_equal(data, np.round(frames[1] * full))
    meta = json.loads((tmp_path / "run" / SIDECAR_NAME).read_text())
    assert meta["pixel_size_m"] == cam.pixel_size_m
    assert meta["frame_interval_s"] == 5e-6
    assert meta["nozzle_row"] == cam.nozzle_rows - 1
    assert meta["bit_depth"] == bits
    # Atomic writes leave no temporary files behind.
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == sorted(
        [p.name for p in paths] + [SIDECAR_NAME]
    )


def test_write_frames_rejects_bad_arguments(tmp_path) -> None:
    cam = Camera(width_px=8, height_px=8, nozzle_rows=2)
    frames = np.zeros((1, 8, 8))
    with pytest.raises(ValueError, match="frame_interval_s"):
        write_frames(frames, tmp_path, camera=cam, frame_interval_s=0.0)
    with pytest.raises(ValueError, match="fmt"):
        write_frames(frames, tmp_path, camera=cam, frame_interval_s=1e-6, fmt="jpg")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="prefix"):
        write_frames(frames, tmp_path, camera=cam, frame_interval_s=1e-6, prefix="../x")
