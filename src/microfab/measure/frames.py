"""Load shadowgraph frames: PNG/TIFF files in natural order, as one gray float stack.

Step 1 of the analysis described in :mod:`microfab.measure.imaging`: 8/16-bit, gray or
RGB(A), multi-page TIFF stacks, natural order (``frame_2`` before ``frame_10``), and the
``frames.json`` sidecar that :func:`microfab.measure.shadowgraph.write_frames` writes
beside them (pixel size, frame interval, first frame time).

The sidecar is read through its schema (`FrameIndex`, :mod:`microfab.io.schema`): strict
types, a pixel size and a frame interval in the ranges a shadowgraph camera has, a bit
depth of 8 or 16, and frame files listed relative to the folder, inside it, all present
(then exactly those files are the frames, in the order listed).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import inside, read_json, validated

__all__ = [
    "IMAGE_SUFFIXES",
    "SIDECAR_NAME",
    "FrameIndex",
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
#: What `microfab.io.schema.read_json` calls a sidecar.
SIDECAR_KIND = FILE_KINDS["frame-index"].what
#: Pixel sizes a sidecar may give, m: the range ``droplet analyze --pixel-size`` takes
#: (0.1-100 µm; assumed: from a microscope objective to a plain lens on the nozzle).
PIXEL_SIZE_RANGE_M = (1e-7, 1e-4)
#: Frame intervals a sidecar may give, s: the range ``droplet analyze --frame-interval``
#: takes (0.1-1000 µs; assumed: a droplet's flight of about 100 µs needs frames in it).
FRAME_INTERVAL_RANGE_S = (1e-7, 1e-3)
#: Most frames a sidecar may list (assumed: 1e5 frames of 64 x 64 px are 3 GB as floats).
MAX_FRAMES = 100_000


class FrameIndex(BaseModel):
    """The schema of ``frames.json`` (every key optional; other keys are kept aside).

    Attributes
    ----------
    pixel_size_m : float, optional
        Pixel size, m, in `PIXEL_SIZE_RANGE_M`.
    frame_interval_s : float, optional
        Time between frames, s, in `FRAME_INTERVAL_RANGE_S`.
    t0_s : float, optional
        Time of the first frame, s, finite.
    nozzle_row : int or None, optional
        Last image row of the nozzle (>= 0); null: detected.
    bit_depth : {8, 16}, optional
        Bits per pixel of the files.
    n_frames : int, optional
        Number of frame files (>= 1); equal to the length of ``files`` when both are given.
    files : list of str, optional
        The frame files, relative to the folder.
    """

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    pixel_size_m: float | None = Field(None, ge=PIXEL_SIZE_RANGE_M[0], le=PIXEL_SIZE_RANGE_M[1])
    frame_interval_s: float | None = Field(
        None, ge=FRAME_INTERVAL_RANGE_S[0], le=FRAME_INTERVAL_RANGE_S[1]
    )
    t0_s: float | None = None
    nozzle_row: int | None = Field(None, ge=0)
    bit_depth: Literal[8, 16] | None = None
    n_frames: int | None = Field(None, ge=1, le=MAX_FRAMES)
    files: list[str] | None = Field(None, min_length=1, max_length=MAX_FRAMES)


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
    listed = _listed_files(folder) if pattern is None else None
    if listed is not None:
        files = listed
    elif pattern is None:
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
    if listed is None:
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
    """The ``frames.json`` sidecar of ``folder``, checked by `FrameIndex` ({} if none).

    Returns
    -------
    dict
        The keys the file gives (other keys too), values checked.

    Raises
    ------
    ValueError
        Not a JSON object of the schema (the message names the file and the key), or a
        file of another kind.
    """
    path = folder / SIDECAR_NAME
    if not path.exists():
        return {}
    try:
        doc = read_json(path, SIDECAR_KIND)
    except ValueError as exc:
        raise ValueError(f"cannot read sidecar {exc}") from None
    if not isinstance(doc, dict):
        raise ValueError(f"sidecar {path} must hold a JSON object, got {type(doc).__name__}")
    index = validated(FrameIndex, doc, str(path))
    if (
        index.files is not None
        and index.n_frames is not None
        and len(index.files) != index.n_frames
    ):
        raise ValueError(
            f"{path}: n_frames is {index.n_frames} but files lists {len(index.files)} frames"
        )
    return index.model_dump(exclude_unset=True)


def _listed_files(folder: Path) -> list[Path] | None:
    """The frame files ``frames.json`` lists (inside ``folder``, all present), or None."""
    files = read_sidecar(folder).get("files")
    if files is None:
        return None
    where = f"{folder / SIDECAR_NAME}: files"
    out = [inside(folder, name, where) for name in files]
    seen: set[Path] = set()
    for name, p in zip(files, out, strict=True):
        if p in seen:
            raise ValueError(f"{where}: {name!r} is listed twice")
        seen.add(p)
    missing = [p for p in out if not p.is_file()]
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise ValueError(f"{where}: the frame {missing[0].name!r} is missing{more}")
    return out
