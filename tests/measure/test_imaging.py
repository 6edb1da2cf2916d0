"""Analyser tests on synthetic sequences with known ground truth.

The jet is built analytically: a head sphere of radius 40 µm whose tip moves at 4 m/s,
joined to the nozzle (radius 60 µm, a 30 µm cone down to the ligament) by a rounded
ligament of radius 10 µm. In frame ``KB`` the ligament gets a gap at a chosen fraction of
the jet length (front / middle / exit); the gap widens afterwards, and from ``KB + 3`` on
the ligament between the nozzle stub and the head has turned into ``n_sat`` satellite
spheres of radius 12 µm while the head is a lone sphere.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import tifffile

from microfab.measure.imaging import (
    DropletAnalysis,
    analyze,
    analyze_folder,
    load_frames,
    natural_key,
)
from microfab.measure.shadowgraph import (
    Camera,
    render_sequence,
    write_frames,
)
from microfab.process.inkjet.silhouette import Silhouette

PX = 2e-6
NOZ_R = 60e-6
HEAD_R = 40e-6
LIG_R = 10e-6
SAT_R = 12e-6
CONE = 30e-6
SPEED = 4.0
DT = 10e-6
N_FRAMES = 15
TIP0 = 120e-6
KB = 6
HEAD_VOLUME = 4.0 / 3.0 * math.pi * HEAD_R**3
CAM = Camera(pixel_size_m=PX, width_px=120, height_px=400, blur_px=1.2, noise_std=0.03)
Z = np.arange(0.0, 800e-6, 0.25e-6)

CASES = {  # name: (gap position / jet length at breakup, satellites at the end)
    "front": (0.76, 2),
    "exit": (0.10, 0),
    "middle": (0.50, 1),
}


def _sphere(zc: float, radius: float) -> np.ndarray:
    return np.sqrt(np.clip(radius**2 - (Z - zc) ** 2, 0.0, None))


def _capsule(za: float, zb: float, a: float) -> np.ndarray:
    """Rod of radius ``a`` with hemispherical ends, from ``za`` to ``zb``."""
    if zb - za <= 2 * a:
        return _sphere((za + zb) / 2, (zb - za) / 2)
    zc = np.clip(Z, za + a, zb - a)
    return np.sqrt(np.clip(a**2 - (Z - zc) ** 2, 0.0, None))


def _cone() -> np.ndarray:
    return np.where(Z <= CONE, NOZ_R + (LIG_R - NOZ_R) * Z / CONE, 0.0)


def _body(r: np.ndarray, z0: float, z1: float) -> tuple[np.ndarray, np.ndarray]:
    sel = (Z >= z0 - 1e-12) & (Z <= z1 + 1e-12)
    return Z[sel], r[sel]


def _tip(k: int) -> float:
    return TIP0 + SPEED * DT * k


def _scenario(frac: float, n_sat: int, kb: int | None = KB) -> list[Silhouette]:
    gap = frac * _tip(kb) if kb is not None else math.inf
    out = []
    for k in range(N_FRAMES):
        tip = _tip(k)
        zc = tip - HEAD_R
        if kb is None or k < kb:
            r = np.maximum.reduce([_cone(), _capsule(-LIG_R, zc, LIG_R), _sphere(zc, HEAD_R)])
            bodies = [_body(r, 0.0, tip)]
        else:
            half = 5e-6 + 10e-6 * (k - kb)
            end = max(gap - half, 20e-6)
            bodies = [_body(np.maximum(_cone(), _capsule(-LIG_R, end, LIG_R)), 0.0, end)]
            if k < kb + 3:
                r = np.maximum(_capsule(gap + half, zc, LIG_R), _sphere(zc, HEAD_R))
                bodies.append(_body(r, gap + half, tip))
            else:
                tail = tip - 2 * HEAD_R
                for i in range(n_sat):
                    c = end + (tail - end) * (i + 1) / (n_sat + 1)
                    bodies.append(_body(_sphere(c, SAT_R), c - SAT_R, c + SAT_R))
                bodies.append(_body(_sphere(zc, HEAD_R), tail, tip))
        out.append(Silhouette(time_s=k * DT, bodies=tuple(bodies), nozzle_radius_m=NOZ_R))
    return out


@pytest.fixture(scope="module")
def rendered() -> dict[str, np.ndarray]:
    return {
        name: render_sequence(_scenario(frac, n_sat), CAM, seed=i)
        for i, (name, (frac, n_sat)) in enumerate(CASES.items())
    }


def _check(res: DropletAnalysis, case: str) -> None:
    _frac, n_sat = CASES[case]
    assert res.nozzle_row == CAM.nozzle_rows - 1
    assert res.breakup_frame == KB
    assert res.breakup_time_s == pytest.approx(KB * DT)
    assert res.breakup_window_s == pytest.approx(((KB - 1) * DT, KB * DT))
    assert res.breakup_mode == case
    assert res.breakup_z_m == pytest.approx(_frac * _tip(KB), abs=3 * PX)
    assert res.head_speed_m_s == pytest.approx(SPEED, rel=0.05)
    assert abs(res.head_speed_m_s / SPEED - 1) < 0.005  # measured: ~0.03 %
    assert res.drop_volume_m3 == pytest.approx(HEAD_VOLUME, rel=0.10)
    assert abs(res.drop_volume_m3 / HEAD_VOLUME - 1) < 0.03  # measured: ~1 %
    assert res.satellites == n_sat
    np.testing.assert_allclose(res.head_z_m, [_tip(k) for k in range(N_FRAMES)], atol=PX)
    assert res.attached.all()  # a stub stays on the nozzle in every case
    assert list(res.n_bodies[:KB]) == [0] * KB
    assert res.n_bodies[-1] == n_sat + 1


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize(("fmt", "bits"), [("png", 8), ("tiff", 16)])
def test_breakup_cases_from_files(
    rendered: dict[str, np.ndarray], tmp_path: Path, case: str, fmt: str, bits: int
) -> None:
    cam = dataclasses.replace(CAM, bit_depth=bits)
    write_frames(rendered[case], tmp_path, camera=cam, frame_interval_s=DT, fmt=fmt)
    res = analyze_folder(tmp_path)  # calibration and nozzle row from frames.json
    _check(res, case)
    assert res.frame_names[0] == f"frame_0000.{'png' if fmt == 'png' else 'tif'}"
    d = res.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["breakup_time_s"] == pytest.approx(KB * DT)
    assert d["breakup_mode"] == case
    assert d["satellites_count"] == CASES[case][1]
    assert len(d["frames"]["head_z_m"]) == N_FRAMES


def test_ligament_length_and_nozzle_detection(rendered: dict[str, np.ndarray]) -> None:
    # In memory, nozzle row detected (the jet already hangs from the nozzle in frame 0).
    res = analyze(rendered["exit"], pixel_size_m=PX, frame_interval_s=DT, t0_s=1e-6)
    np.testing.assert_allclose(res.times_s, 1e-6 + DT * np.arange(N_FRAMES))
    assert res.nozzle_row == CAM.nozzle_rows - 1
    # Exit pinch: the detached body runs from just behind the gap to the head tip.
    gap = CASES["exit"][0] * _tip(KB)
    assert res.ligament_length_m == pytest.approx(_tip(KB) - gap - 5e-6, abs=3 * PX)
    # Before breakup the ligament spans nozzle exit to head tip.
    assert res.ligament_lengths_m[KB - 1] == pytest.approx(_tip(KB - 1), abs=PX)


def test_uneven_background_and_bright_drop_centre() -> None:
    cam = dataclasses.replace(CAM, vignette=0.3)
    frames = render_sequence(_scenario(*CASES["middle"]), cam, seed=7)
    for k in range(N_FRAMES):  # lens spot: bright centre of the head drop
        row = int(cam.row_of_z(_tip(k) - HEAD_R))
        frames[k, row - 4 : row + 4, 56:64] = 0.8
    res = analyze(frames, pixel_size_m=PX, frame_interval_s=DT)
    _check(res, "middle")


def test_rgb_and_stack_inputs(rendered: dict[str, np.ndarray], tmp_path: Path) -> None:
    frames = rendered["front"]
    rgb = np.round(np.repeat(frames[..., None], 3, axis=-1) * 255).astype(np.uint8)
    for k, img in enumerate(rgb):
        iio.imwrite(tmp_path / f"shot{k}.png", img)
    loaded, names = load_frames(tmp_path)
    assert loaded.shape == frames.shape
    assert names[:3] == ["shot0.png", "shot1.png", "shot2.png"]
    assert names[-1] == "shot14.png"
    np.testing.assert_allclose(loaded, frames, atol=1 / 255)
    with pytest.raises(ValueError, match="pixel size is required"):
        analyze_folder(tmp_path, frame_interval_s=DT)
    res = analyze_folder(tmp_path, pixel_size_m=PX, frame_interval_s=DT)
    _check(res, "front")
    # A multi-page TIFF stack is split into frames; in-memory RGB frames work too.
    stack_dir = tmp_path / "stack"
    stack_dir.mkdir()
    tifffile.imwrite(
        stack_dir / "seq.tif", (frames[:4] * 65535).astype(np.uint16), photometric="minisblack"
    )
    loaded, names = load_frames(stack_dir)
    assert loaded.shape == (4, *frames.shape[1:])
    assert names == [f"seq.tif[{i}]" for i in range(4)]
    res_rgb = analyze(rgb, pixel_size_m=PX, frame_interval_s=DT)
    assert res_rgb.breakup_frame == KB


def test_no_breakup_and_head_leaving_the_view(rendered: dict[str, np.ndarray]) -> None:
    frames = render_sequence(_scenario(0.5, 0, kb=None), CAM, seed=3)
    res = analyze(frames, pixel_size_m=PX, frame_interval_s=DT)
    assert res.breakup_frame is None and res.breakup_mode is None
    assert res.breakup_time_s is None and res.breakup_window_s == (None, None)
    assert res.satellites == 0 and res.drop_volume_m3 is None
    assert res.head_speed_m_s == pytest.approx(SPEED, rel=0.01)
    json.dumps(res.to_dict(), allow_nan=False)
    # Crop the front case so that the head leaves through the bottom edge (rows >= 300).
    cropped = rendered["front"][:, :300]
    res = analyze(cropped, pixel_size_m=PX, frame_interval_s=DT)
    z_edge = (300 - CAM.nozzle_rows) * PX
    in_view = np.array([_tip(k) < z_edge - PX for k in range(N_FRAMES)])
    assert np.isfinite(res.head_z_m[in_view]).all() and np.isnan(res.head_z_m[~in_view]).all()
    assert res.head_speed_m_s == pytest.approx(SPEED, rel=0.05)
    assert res.satellites == 2  # the head has left; both satellites still in view
    assert res.drop_volume_m3 == pytest.approx(HEAD_VOLUME, rel=0.10)  # last full view
    assert res.breakup_mode == "front"


# ------------------------------------------------------------------ loading and errors


def test_natural_sort(tmp_path: Path) -> None:
    for k in (10, 2, 1, 11, 3):
        iio.imwrite(tmp_path / f"frame_{k}.png", np.full((4, 5), k * 10, dtype=np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    (tmp_path / ".frame_0.png").write_bytes(b"partial")  # hidden: skipped
    frames, names = load_frames(tmp_path)
    assert names == ["frame_1.png", "frame_2.png", "frame_3.png", "frame_10.png", "frame_11.png"]
    np.testing.assert_allclose(frames[:, 0, 0], np.array([1, 2, 3, 10, 11]) * 10 / 255)
    assert sorted(["B2", "a10", "a9"], key=natural_key) == ["a9", "a10", "B2"]
    _, only = load_frames(tmp_path, pattern="frame_1*.png")
    assert only == ["frame_1.png", "frame_10.png", "frame_11.png"]


def test_load_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no image files"):
        load_frames(tmp_path)
    with pytest.raises(ValueError, match="not found"):
        load_frames(tmp_path / "missing")
    iio.imwrite(tmp_path / "a_1.png", np.zeros((10, 20), dtype=np.uint8))
    tifffile.imwrite(tmp_path / "a_2.tif", np.zeros((12, 20), dtype=np.uint16))
    with pytest.raises(ValueError, match=r"a_1\.png is 20 x 10 px.*a_2\.tif is 20 x 12 px"):
        load_frames(tmp_path)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.png").write_bytes(b"this is not a png")
    with pytest.raises(ValueError, match=r"cannot read image file .*x\.png"):
        load_frames(bad)


def test_calibration_errors(rendered: dict[str, np.ndarray], tmp_path: Path) -> None:
    frames = rendered["front"][:3]
    with pytest.raises(ValueError, match="pixel size is required"):
        analyze(frames, frame_interval_s=DT)
    with pytest.raises(ValueError, match="frame interval is required"):
        analyze(frames, pixel_size_m=PX)
    for bad in (0.0, -1e-6, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"frame_interval_s must be positive.* s$"):
            analyze(frames, pixel_size_m=PX, frame_interval_s=bad)
        with pytest.raises(ValueError, match=r"pixel_size_m must be positive.* m$"):
            analyze(frames, pixel_size_m=bad, frame_interval_s=DT)
    with pytest.raises(ValueError, match="nozzle_row"):
        analyze(frames, pixel_size_m=PX, frame_interval_s=DT, nozzle_row=400)
    no_nozzle = frames.copy()
    no_nozzle[:, : CAM.nozzle_rows + 40] = CAM.background  # nothing touches the top edge
    with pytest.raises(ValueError, match="cannot find the nozzle"):
        analyze(no_nozzle, pixel_size_m=PX, frame_interval_s=DT)
    with pytest.raises(ValueError, match="no dark silhouette"):
        analyze(np.full((2, 30, 30), 0.8), pixel_size_m=PX, frame_interval_s=DT)
    # Folder without sidecar: calibration must be passed.
    write_frames(frames, tmp_path, camera=CAM, frame_interval_s=DT)
    shutil.copy(tmp_path / "frames.json", tmp_path / "frames.bak")
    (tmp_path / "frames.json").unlink()
    with pytest.raises(ValueError, match="pixel size is required: give pixel_size_m"):
        analyze_folder(tmp_path, frame_interval_s=DT)
    with pytest.raises(ValueError, match="frame interval is required"):
        analyze_folder(tmp_path, pixel_size_m=PX)
    with pytest.raises(ValueError, match="frame_interval_s must be positive"):
        analyze_folder(tmp_path, pixel_size_m=PX, frame_interval_s=-DT)
    (tmp_path / "frames.json").write_text("{not json")
    with pytest.raises(ValueError, match="cannot read sidecar"):
        analyze_folder(tmp_path)


def test_noise_frames_are_no_jet(tmp_path: Path) -> None:
    # issue 13: frames of pure noise gave breakup_time_s 0.0 and 31 satellites
    noise = np.random.default_rng(0).random((6, 120, 80))
    with pytest.raises(ValueError, match="no jet found: in none of the 6 frames"):
        analyze(noise, pixel_size_m=PX, frame_interval_s=DT)


@pytest.mark.parametrize("key, value", [("t0_s", None), ("t0_s", [1.0]), ("pixel_size_m", "2e-6")])
def test_sidecar_values_must_be_numbers(
    rendered: dict[str, np.ndarray], tmp_path: Path, key: str, value: object
) -> None:
    write_frames(rendered["front"][:3], tmp_path, camera=CAM, frame_interval_s=DT)
    meta = json.loads((tmp_path / "frames.json").read_text())
    meta[key] = value  # t0_s: None was a TypeError from float()
    (tmp_path / "frames.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=rf"frames\.json: {key} = .* is not a number"):
        analyze_folder(tmp_path)


def test_damaged_tiff_is_refused_without_printing_tifffile_logs(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import logging

    monkeypatch.setattr(logging.getLogger(), "handlers", [])  # as on the command line
    tifffile.imwrite(tmp_path / "f.tif", np.zeros((3, 3), dtype=np.uint16))
    data = (tmp_path / "f.tif").read_bytes()
    (tmp_path / "f.tif").write_bytes(data[:8])  # tifffile logs "invalid offset", then raises
    with pytest.raises(ValueError, match=r"cannot (read|use) image file .*f\.tif"):
        load_frames(tmp_path)
    assert capfd.readouterr().err == ""
