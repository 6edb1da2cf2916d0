"""Load shadowgraph frames: PNG/TIFF files in natural order, as one gray float stack.

Step 1 of the analysis described in :mod:`microfab.measure.imaging`: 8/16-bit, gray or
RGB(A), multi-page TIFF stacks, natural order (``frame_2`` before ``frame_10``), and the
``frames.json`` sidecar that :func:`microfab.measure.shadowgraph.write_frames` writes
beside them (pixel size, frame interval, first frame time).
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "IMAGE_SUFFIXES",
    "SIDECAR_NAME",
    "MissingSettingError",
    "as_frames",
    "load_frames",
    "natural_key",
    "read_sidecar",
]

#: File suffixes read by :func:`load_frames` (case-insensitive).
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")
#: Sidecar with acquisition metadata (written by ``shadowgraph.write_frames``).
SIDECAR_NAME = "frames.json"


class MissingSettingError(ValueError):
    """A camera setting that was neither passed nor found in the frames' sidecar.

    Parameters
    ----------
    key : str
        The setting's name (``"pixel_size_m"`` or ``"frame_interval_s"``), so that a
        front end can name its own option for it.
    message : str
        The error message.
    """

    def __init__(self, key: str, message: str) -> None:
        super().__init__(message)
        self.key = key


def natural_key(name: str) -> list[int | str]:
    """Sort key that orders embedded numbers by value (``frame_2`` before ``frame_10``).

    Parameters
    ----------
    name : str
        File name.

    Returns
    -------
    list of int or str
        Alternating text (lower-cased) and integer parts.

    Examples
    --------
    >>> sorted(["f_10.png", "f_2.png", "f_1.png"], key=natural_key)
    ['f_1.png', 'f_2.png', 'f_10.png']
    """
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def _to_float(arr: np.ndarray) -> np.ndarray:
    if arr.dtype == bool:
        return arr.astype(float)
    if np.issubdtype(arr.dtype, np.integer):
        info = np.iinfo(arr.dtype)
        return np.clip(arr.astype(float) / info.max, 0.0, 1.0)
    out = np.asarray(arr, dtype=float)
    top = float(np.nanmax(out)) if out.size else 0.0
    return out / top if top > 1.0 else out


def _rgb_to_gray(arr: np.ndarray) -> np.ndarray:
    from skimage.color import rgb2gray

    return rgb2gray(arr[..., :3])


# tifffile logs what it finds wrong in a damaged file before it raises; without a handler
# Python prints that on stderr, beside the one-line error the file's refusal gives.
logging.getLogger("tifffile").addHandler(logging.NullHandler())


def _read_image(path: Path) -> list[np.ndarray]:
    """Read one file into a list of 2-D gray float frames (several for a TIFF stack)."""
    try:
        if path.suffix.lower() in (".tif", ".tiff"):
            import tifffile

            raw = tifffile.imread(path)
        else:
            import imageio.v3 as iio

            raw = iio.imread(path, plugin="pillow")
    except Exception as exc:
        raise ValueError(f"cannot read image file {path}: {exc}") from exc
    arr = _to_float(np.asarray(raw))
    if arr.ndim == 2:
        return [arr]
    if arr.ndim == 3 and arr.shape[-1] in (3, 4):
        return [_rgb_to_gray(arr)]
    if arr.ndim == 3 and arr.shape[-1] == 2:  # gray + alpha
        return [arr[..., 0]]
    if arr.ndim == 3:  # multi-page stack (n, h, w)
        return list(arr)
    if arr.ndim == 4 and arr.shape[-1] in (3, 4):  # stack of RGB pages
        return [_rgb_to_gray(page) for page in arr]
    raise ValueError(f"cannot use image file {path}: unsupported array shape {arr.shape}")


def load_frames(
    directory: str | Path, *, pattern: str | None = None
) -> tuple[np.ndarray, list[str]]:
    """Read a folder of PNG/TIFF frames into one gray float array.

    Parameters
    ----------
    directory : str or pathlib.Path
        Folder with the frames. Hidden files (names starting with ``.``) are skipped.
    pattern : str, optional
        Glob pattern of the files to read (e.g. ``"cam1_*.tif"``); default: every file
        with a suffix in :data:`IMAGE_SUFFIXES`.

    Returns
    -------
    frames : numpy.ndarray
        Shape ``(n, h, w)``, float in [0, 1] (integers scaled by their type's maximum,
        RGB converted to luminance, alpha ignored).
    names : list of str
        File name of each frame (``name[i]`` for page ``i`` of a multi-page TIFF), in
        natural order.

    Raises
    ------
    ValueError
        If the folder does not exist or holds no matching image, a file cannot be read,
        or the frames differ in size (both sizes and files are named).

    Examples
    --------
    >>> frames, names = load_frames("run_50V")  # doctest: +SKIP
    >>> frames.shape, names[:2]  # doctest: +SKIP
    ((16, 400, 120), ['frame_0000.png', 'frame_0001.png'])
    """
    folder = Path(directory)
    if not folder.is_dir():
        raise ValueError(f"frame folder not found (or not a folder): {folder}")
    if pattern is None:
        files = [
            p
            for p in folder.iterdir()
            if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".")
        ]
    else:
        files = [p for p in folder.glob(pattern) if p.is_file() and not p.name.startswith(".")]
    if not files:
        wanted = pattern if pattern is not None else "/".join(IMAGE_SUFFIXES)
        raise ValueError(f"no image files ({wanted}) in folder {folder}")
    files.sort(key=lambda p: natural_key(p.name))
    frames: list[np.ndarray] = []
    names: list[str] = []
    for path in files:
        pages = _read_image(path)
        for i, page in enumerate(pages):
            name = path.name if len(pages) == 1 else f"{path.name}[{i}]"
            if frames and page.shape != frames[0].shape:
                h0, w0 = frames[0].shape
                h1, w1 = page.shape
                raise ValueError(
                    f"frames differ in size: {names[0]} is {w0} x {h0} px (w x h) but "
                    f"{name} is {w1} x {h1} px"
                )
            frames.append(page)
            names.append(name)
    return np.stack(frames), names


def as_frames(frames: np.ndarray | Sequence[np.ndarray]) -> np.ndarray:
    """Frames as a validated gray float stack, as :func:`analyze` reads them.

    Parameters
    ----------
    frames : numpy.ndarray or sequence of numpy.ndarray
        Gray frames ``(n, h, w)`` or one ``(h, w)`` frame, or RGB(A) frames
        ``(n, h, w, 3 | 4)``; integer or float gray levels.

    Returns
    -------
    numpy.ndarray
        Float frames of shape ``(n, h, w)``: integers divided by their dtype's maximum,
        floats divided by their maximum if it exceeds 1, RGB(A) converted to gray.

    Raises
    ------
    ValueError
        For another shape, frames smaller than 3 x 3 px, or NaN/inf values.
    """
    arr = np.asarray(frames)
    if arr.ndim == 4 and arr.shape[-1] in (3, 4):
        arr = _rgb_to_gray(_to_float(arr))
    elif arr.ndim in (2, 3):
        arr = _to_float(arr)
    else:
        raise ValueError(f"frames must have shape (n, h, w) or (h, w), got {arr.shape}")
    if arr.ndim == 2:
        arr = arr[None]
    if arr.shape[0] == 0 or arr.shape[1] < 3 or arr.shape[2] < 3:
        raise ValueError(f"need at least one frame of at least 3 x 3 px, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("frames contain NaN or infinite values")
    return arr


def read_sidecar(folder: Path) -> dict[str, Any]:
    """The ``frames.json`` sidecar of ``folder`` as a dict ({} if there is none)."""
    path = folder / SIDECAR_NAME
    if not path.is_file():
        return {}
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read sidecar {path}: {exc}") from exc
    if not isinstance(meta, dict):
        raise ValueError(f"sidecar {path} must hold a JSON object, got {type(meta).__name__}")
    return meta
