"""Synthetic shadowgraph (strobed back-lit) frames of a forming inkjet droplet.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.) images the
droplet formation of alginate solutions from a MicroFab 120 µm dispenser with a JetXpert
strobed camera: the liquid appears as a dark silhouette on a bright background (seed
Fig. 2, a time-resolved strip of such frames; Fig. 3, the features of a forming droplet:
nozzle, ligament, head, pinch-off). This module turns the radius profiles ``r(z)`` of the
axisymmetric liquid bodies computed by a 1D jet solver
(:class:`microfab.process.inkjet.silhouette.Silhouette`) into such frames, so that the
image analyser (:mod:`microfab.measure.imaging`) can be run on simulated and on measured
sequences alike, and checked against known ground truth.

Image model (all ASSUMPTIONS of an idealised back-lit microscope, not from the seed):

* the jet runs DOWN the image (row index grows with the axial distance ``z`` downstream of
  the nozzle exit plane); the jet axis is the vertical centre line of the image
  (``x = width_px / 2`` in pixel-edge coordinates);
* the nozzle is an opaque block of half-width :attr:`Camera.nozzle_outer_factor` times the
  nozzle radius, from the top edge down to the exit plane, which is the lower edge of row
  ``nozzle_rows - 1`` (pixel-edge coordinate ``y = nozzle_rows``);
* a liquid body is opaque: a pixel's intensity is ``background - (background - shadow) *
  coverage``, with ``coverage`` the fraction of the pixel covered by the projected
  silhouette (exact across a row, ``supersample`` sub-rows along the axis);
* optics: a Gaussian point-spread function of standard deviation ``blur_px``; sensor:
  additive white Gaussian noise of standard deviation ``noise_std`` (fraction of full
  scale), then clipping to [0, 1]; quantisation to ``bit_depth`` bits happens when the
  frames are written. An optional quadratic vignetting darkens the corners.

Real shadowgraphs of drops often show a bright spot at the centre of the drop (the drop
acts as a lens); it is not modelled here, but the analyser fills such holes.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from scipy import ndimage

from microfab.core.validate import (
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
)
from microfab.io.atomic import atomic_path, atomic_write_json
from microfab.process.inkjet.silhouette import Silhouette

__all__ = [
    "SIDECAR_NAME",
    "Camera",
    "render",
    "render_sequence",
    "write_frames",
]

#: Name of the JSON file written next to the frames (read by ``imaging.analyze_folder``).
SIDECAR_NAME = "frames.json"


@dataclass(frozen=True, kw_only=True)
class Camera:
    """Idealised strobed back-lit camera (JetXpert-like) that renders silhouettes.

    Attributes
    ----------
    pixel_size_m : float
        Size of one pixel in the object plane, m (default 2 µm: an ASSUMPTION, the seed
        gives no magnification).
    width_px, height_px : int
        Image size in pixels (default 160 × 512).
    blur_px : float
        Standard deviation of the Gaussian point-spread function, pixels (>= 0).
    noise_std : float
        Standard deviation of the additive Gaussian noise, fraction of full scale (>= 0).
    background, shadow : float
        Intensity of the bright background and of a fully opaque silhouette, in [0, 1]
        with ``shadow < background``.
    nozzle_rows : int
        Rows of nozzle visible above the exit plane (>= 1); the exit plane is the lower
        edge of row ``nozzle_rows - 1``.
    nozzle_outer_factor : float
        Half-width of the drawn nozzle block in units of the nozzle radius (default 3, an
        ASSUMPTION for the glass tip of a MicroFab dispenser).
    bit_depth : {8, 16}
        Bits per pixel of the written frames.
    supersample : int
        Sub-rows per pixel row for the coverage (anti-aliasing) along the axis (>= 1).
    vignette : float
        Fractional loss of background at the image corners (quadratic in the distance from
        the centre; 0 = even illumination). Uneven lighting for testing the analyser.
    """

    pixel_size_m: float = 2e-6  # assumption: not in seed 003
    width_px: int = 160
    height_px: int = 512
    blur_px: float = 1.0
    noise_std: float = 0.02
    background: float = 0.85
    shadow: float = 0.1
    nozzle_rows: int = 20
    nozzle_outer_factor: float = 3.0  # assumption: glass tip about 3x the orifice
    bit_depth: Literal[8, 16] = 8
    supersample: int = 4
    vignette: float = 0.0

    def __post_init__(self) -> None:
        check_positive("pixel_size_m", self.pixel_size_m, "m")
        check_int("width_px", self.width_px, 2, "px")
        check_int("height_px", self.height_px, 2, "px")
        check_int("supersample", self.supersample, 1, "(sub-rows per pixel row)")
        check_int("nozzle_rows", self.nozzle_rows, 1, "px")
        if self.nozzle_rows >= self.height_px:
            raise ValueError(
                f"nozzle_rows must be < height_px = {self.height_px} px, got {self.nozzle_rows} px"
            )
        check_nonnegative("blur_px", self.blur_px, "px")
        check_nonnegative("noise_std", self.noise_std, "(fraction of full scale)")
        check_in_range("vignette", self.vignette, 0.0, 1.0, "(fraction)", high_closed=False)
        check_positive("nozzle_outer_factor", self.nozzle_outer_factor, "(nozzle radii)")
        if not (0.0 <= self.shadow < self.background <= 1.0):
            raise ValueError(
                "intensities must satisfy 0 <= shadow < background <= 1, got "
                f"shadow = {self.shadow!r}, background = {self.background!r}"
            )
        if self.bit_depth not in (8, 16):
            raise ValueError(f"bit_depth must be 8 or 16, got {self.bit_depth!r} bits")

    @property
    def nozzle_row(self) -> int:
        """Index of the last nozzle row; the exit plane is its lower edge."""
        return self.nozzle_rows - 1

    def row_of_z(self, z_m: float | np.ndarray) -> float | np.ndarray:
        """Pixel-edge row coordinate of the axial position ``z_m`` (m)."""
        return self.nozzle_rows + np.asarray(z_m) / self.pixel_size_m


def _coverage_1d(half_width_px: np.ndarray, width_px: int) -> np.ndarray:
    """Fraction of each pixel column covered by ``|x - centre| <= half_width``.

    ``half_width_px`` has shape (m,); the result has shape (m, width_px).
    """
    centre = width_px / 2.0
    left = np.arange(width_px, dtype=float)
    lo = centre - half_width_px[:, None]
    hi = centre + half_width_px[:, None]
    return np.clip(np.minimum(left + 1.0, hi) - np.maximum(left, lo), 0.0, 1.0)


def render(
    silhouette: Silhouette, camera: Camera, *, rng: np.random.Generator | None = None
) -> np.ndarray:
    """Render one shadowgraph frame of a silhouette.

    Parameters
    ----------
    silhouette : Silhouette
        Liquid bodies to draw (and the nozzle radius, which sizes the nozzle block).
    camera : Camera
        Optics, sensor and geometry of the image.
    rng : numpy.random.Generator, optional
        Source of the sensor noise. ``None`` uses a generator seeded with 0, so a frame is
        reproducible; pass one generator for a sequence (see :func:`render_sequence`).

    Returns
    -------
    numpy.ndarray
        Float image of shape ``(height_px, width_px)`` with values in [0, 1]; row 0 is the
        top (nozzle side), the jet runs down.

    Examples
    --------
    >>> z = np.linspace(0.0, 100e-6, 51)
    >>> s = Silhouette(time_s=0.0, bodies=((z, np.full_like(z, 10e-6)),), nozzle_radius_m=60e-6)
    >>> img = render(s, Camera(width_px=64, height_px=96, noise_std=0.0))
    >>> img.shape, bool(img[40, 32] < 0.2), bool(img[40, 2] > 0.8)
    ((96, 64), True, True)
    """
    cam = camera
    h, w, s = cam.height_px, cam.width_px, cam.supersample
    # Axial positions of the sub-row centres, m (negative above the exit plane).
    y_sub = (np.arange(h * s, dtype=float) + 0.5) / s
    z_sub = (y_sub - cam.nozzle_rows) * cam.pixel_size_m
    radius = np.zeros(h * s)
    for z, r in silhouette.bodies:  # loop over bodies only; coaxial bodies: union = max r
        inside = (z_sub >= z[0]) & (z_sub <= z[-1])
        radius = np.maximum(radius, np.where(inside, np.interp(z_sub, z, r), 0.0))
    outer = cam.nozzle_outer_factor * silhouette.nozzle_radius_m
    radius = np.where(y_sub < cam.nozzle_rows, np.maximum(radius, outer), radius)
    cover = _coverage_1d(radius / cam.pixel_size_m, w).reshape(h, s, w).mean(axis=1)
    background = np.full((h, w), cam.background)
    if cam.vignette > 0.0:
        yy = (np.arange(h) + 0.5 - h / 2.0) / (h / 2.0)
        xx = (np.arange(w) + 0.5 - w / 2.0) / (w / 2.0)
        background = background * (1.0 - 0.5 * cam.vignette * (yy[:, None] ** 2 + xx[None] ** 2))
    image = background - (background - cam.shadow) * cover
    if cam.blur_px > 0.0:
        image = ndimage.gaussian_filter(image, cam.blur_px, mode="nearest")
    if cam.noise_std > 0.0:
        gen = np.random.default_rng(0) if rng is None else rng
        image = image + gen.normal(0.0, cam.noise_std, size=image.shape)
    return np.clip(image, 0.0, 1.0)


def render_sequence(silhouettes: Sequence[Silhouette], camera: Camera, seed: int = 0) -> np.ndarray:
    """Render a time-resolved sequence of frames with independent noise.

    Parameters
    ----------
    silhouettes : sequence of Silhouette
        Snapshots in the order of the frames.
    camera : Camera
        Camera used for every frame.
    seed : int, optional
        Seed of the noise generator (one generator for the whole sequence).

    Returns
    -------
    numpy.ndarray
        Frames of shape ``(n, height_px, width_px)``, float in [0, 1].

    Examples
    --------
    >>> z = np.linspace(0.0, 50e-6, 11)
    >>> s = Silhouette(time_s=0.0, bodies=((z, np.full_like(z, 5e-6)),), nozzle_radius_m=6e-5)
    >>> render_sequence([s, s], Camera(width_px=32, height_px=48)).shape
    (2, 48, 32)
    """
    rng = np.random.default_rng(seed)
    frames = [render(s, camera, rng=rng) for s in silhouettes]
    if not frames:
        return np.zeros((0, camera.height_px, camera.width_px))
    return np.stack(frames)


def _quantise(frame: np.ndarray, bit_depth: int) -> np.ndarray:
    full = (1 << bit_depth) - 1
    dtype = np.uint8 if bit_depth == 8 else np.uint16
    return np.round(np.clip(frame, 0.0, 1.0) * full).astype(dtype)


def _clear_own_frames(directory: Path, prefix: str) -> None:
    """Remove what an earlier `write_frames` left in ``directory``, and nothing else.

    The folder is written whole: the old sidecar goes first (a folder without it is no
    frame set, so an interrupted write is never read as half old, half new), then every
    ``{prefix}NNNN.png`` / ``.tif`` frame (another render may have had more frames, or the
    other format). Files of other names are the user's and stay.
    """
    if not directory.is_dir():
        return
    (directory / SIDECAR_NAME).unlink(missing_ok=True)
    own = re.compile(re.escape(prefix) + r"[0-9]{4,}\.(png|tif)")
    for entry in directory.iterdir():
        if own.fullmatch(entry.name) and (entry.is_file() or entry.is_symlink()):
            entry.unlink()


def write_frames(
    frames: np.ndarray,
    directory: str | Path,
    *,
    camera: Camera,
    frame_interval_s: float,
    fmt: Literal["png", "tiff"] = "png",
    prefix: str = "frame_",
    t0_s: float = 0.0,
) -> list[Path]:
    """Write frames as numbered 8- or 16-bit images plus a ``frames.json`` sidecar.

    Each file is written atomically (a complete new file or none). The sidecar holds what
    the analyser needs besides the pixels: ``pixel_size_m``, ``frame_interval_s``,
    ``t0_s``, ``nozzle_row`` (index of the last nozzle row, exit plane at its lower edge),
    ``bit_depth`` and the file names.

    Parameters
    ----------
    frames : numpy.ndarray
        Float frames in [0, 1], shape ``(n, h, w)`` (or one ``(h, w)`` frame).
    directory : str or pathlib.Path
        Target folder, created if missing; the sidecar and the frames an earlier call
        wrote there (the same ``prefix``, either format) are removed first, other files
        are left alone.
    camera : Camera
        Camera that rendered the frames (pixel size, nozzle row, bit depth).
    frame_interval_s : float
        Time between consecutive frames, s (> 0).
    fmt : {"png", "tiff"}, optional
        File format; TIFF files get the suffix ``.tif``.
    prefix : str, optional
        File name prefix; names are ``{prefix}{index:0Nd}.{ext}`` with ``N >= 4``.
    t0_s : float, optional
        Time of the first frame, s.

    Returns
    -------
    list of pathlib.Path
        The image files, in frame order.

    Examples
    --------
    >>> cam = Camera(width_px=32, height_px=48)
    >>> frames = np.full((3, 48, 32), 0.85)
    >>> paths = write_frames(frames, "out", camera=cam, frame_interval_s=5e-6)  # doctest: +SKIP
    >>> [p.name for p in paths]  # doctest: +SKIP
    ['frame_0000.png', 'frame_0001.png', 'frame_0002.png']
    """
    check_positive("frame_interval_s", frame_interval_s, "s")
    if fmt not in ("png", "tiff"):
        raise ValueError(f"fmt must be 'png' or 'tiff', got {fmt!r}")
    if not re.fullmatch(r"[A-Za-z0-9_.\-]*", prefix) or prefix.startswith("."):
        raise ValueError(f"prefix must be a plain file-name prefix, got {prefix!r}")
    data = np.asarray(frames, dtype=float)
    if data.ndim == 2:
        data = data[None]
    if data.ndim != 3:
        raise ValueError(f"frames must have shape (n, h, w), got {data.shape}")
    directory = Path(directory)
    ext = "png" if fmt == "png" else "tif"
    digits = max(4, len(str(max(len(data) - 1, 0))))
    _clear_own_frames(directory, prefix)
    paths: list[Path] = []
    for i, frame in enumerate(data):
        path = directory / f"{prefix}{i:0{digits}d}.{ext}"
        pixels = _quantise(frame, camera.bit_depth)
        with atomic_path(path) as tmp:
            if fmt == "png":
                import imageio.v3 as iio

                iio.imwrite(tmp, pixels, extension=".png")
            else:
                import tifffile

                tifffile.imwrite(tmp, pixels)
        paths.append(path)
    atomic_write_json(
        directory / SIDECAR_NAME,
        {
            "pixel_size_m": camera.pixel_size_m,
            "frame_interval_s": float(frame_interval_s),
            "t0_s": float(t0_s),
            "nozzle_row": camera.nozzle_row,
            "bit_depth": camera.bit_depth,
            "n_frames": len(paths),
            "files": [p.name for p in paths],
            "source": "microfab.measure.shadowgraph (synthetic)",
        },
    )
    return paths
