"""The files of a per-axis network model (seed 002 eq. 7): their schema and readers.

A model folder holds ``model.json`` (`microfab.identify.ann.AnnModel.meta`) and
``weights.npz`` (one float32 state dict per axis); `microfab.identify.ann.AnnModel.save`
writes them and `microfab.identify.ann.AnnModel.load` reads them through this module:
``model.json`` by its pydantic schema (`MetaDoc`, `read_model_meta`; another
`FORMAT_VERSION` refused), ``weights.npz`` member by member, shapes from the headers before
any value (`read_weights`). Apart from the networks (:mod:`.ann`) so that what a file may
hold is read in one place; :mod:`.ann` re-exports every name.

PyTorch is not imported here: the networks are only named in annotations.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import (
    SchemaError,
    check_array,
    check_npz,
    describe_file,
    read_json,
    validated,
)

if TYPE_CHECKING:
    from torch import nn

__all__ = [
    "FORMAT_VERSION",
    "MAX_SCALING_M",
    "MAX_WEIGHT",
    "META_KIND",
    "ConfigDoc",
    "MetaDoc",
    "ScalingDoc",
    "WindowDoc",
    "read_model_meta",
    "read_weights",
]


FORMAT_VERSION = 1  # of model.json / weights.npz and of the checkpoints


# --- the files' schema ---------------------------------------------------------------------
#: What `microfab.io.schema.read_json` calls ``model.json``.
META_KIND = FILE_KINDS["ann-model"].what
_STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)
#: Largest offset or scale of the networks' inputs and target read, m (assumed: see
#: `ScalingDoc`).
MAX_SCALING_M = 1e3
#: Largest weight or bias read (assumed: Adam-trained weights of scaled inputs are of
#: order 1; a value of 1e6 is a damaged file, and 1e308 overflows every prediction).
MAX_WEIGHT = 1e6


class WindowDoc(BaseModel):
    """``window`` of ``model.json`` (`WindowSpec.as_dict`); rates in Hz, ``h`` in samples."""

    model_config = _STRICT

    run_rate_hz: float = Field(gt=0, le=1e8)
    rate_hz: float = Field(gt=0, le=1e8)
    h: int = Field(ge=2, le=100_000)
    inputs: Literal["own", "both"]
    encoding: Literal["relative", "extrapolated", "absolute"]
    pad: bool
    features: Literal["none", "position"]


class ScalingDoc(BaseModel):
    """``scaling.<axis>`` of ``model.json`` (`Scaling.as_dict`), m."""

    model_config = _STRICT

    # assumed bounds: the stage's travel and windows are well below a metre; an offset or
    # scale of a kilometre is a damaged file (and 1e308 overflows every prediction)
    in_offset: list[Annotated[float, Field(ge=-MAX_SCALING_M, le=MAX_SCALING_M)]] = Field(
        min_length=1, max_length=100_000
    )
    in_scale: list[Annotated[float, Field(gt=0, le=MAX_SCALING_M)]] = Field(
        min_length=1, max_length=100_000
    )
    out_offset: float = Field(ge=-MAX_SCALING_M, le=MAX_SCALING_M)
    out_scale: float = Field(gt=0, le=MAX_SCALING_M)


class ConfigDoc(BaseModel):
    """``config`` of ``model.json`` (`AnnConfig.fingerprint`)."""

    model_config = _STRICT

    window: WindowDoc
    axes: list[Literal["x", "y"]] = Field(min_length=1, max_length=2)
    offsets: list[Annotated[int, Field(ge=0, le=100_000)]] | None
    batch_size: int = Field(ge=1, le=10**9)
    learning_rate: float = Field(gt=0, le=1e3)
    lr_decay: float = Field(gt=0, le=1)
    patience: int = Field(ge=1, le=10**6)
    epoch_windows: int | None = Field(ge=1, le=10**12)
    val_windows: int | None = Field(ge=1, le=10**12)
    whiten: float | None = Field(default=None, gt=0, le=1)  # absent before the field
    seed: int = Field(ge=0)


class MetaDoc(BaseModel):
    """``model.json`` of a network model folder (`AnnModel.meta`)."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    format_version: int
    window: WindowDoc
    axes: list[Literal["x", "y"]] = Field(min_length=1, max_length=2)
    layers: list[int] = Field(min_length=2, max_length=64)
    config: ConfigDoc
    scaling: dict[str, ScalingDoc]
    info: dict[str, Any] = Field(default_factory=dict)


def read_model_meta(directory: str | os.PathLike[str]) -> MetaDoc:
    """``model.json`` of a model folder, through its schema (`MetaDoc`).

    Raises
    ------
    FileNotFoundError
        No ``model.json``.
    ValueError
        Another format version; `microfab.io.schema.SchemaError` for a file that is not
        JSON, of another kind, or breaks the schema (the line names the field).
    """
    p = Path(directory) / "model.json"
    doc = read_json(p, META_KIND)
    ver = doc.get("format_version") if isinstance(doc, dict) else None
    if ver != FORMAT_VERSION or isinstance(ver, bool):
        raise ValueError(
            f"{p}: model format version {ver}, this microfab reads "
            f"version {FORMAT_VERSION}; retrain the model"
        )
    return validated(MetaDoc, doc, str(p))


def read_weights(path: str | os.PathLike[str], nets: dict[str, nn.Module]) -> dict[str, np.ndarray]:
    """``weights.npz``: one float32 member ``<axis>.<name>`` per tensor of ``nets``.

    Shapes and dtypes are checked from the members' headers before anything is read
    (`microfab.io.schema.check_npz`), the values after (finite).

    Parameters
    ----------
    path : path
        The archive.
    nets : dict of str to torch.nn.Module
        The networks the archive must fill, by axis (their tensors give names and shapes).

    Returns
    -------
    dict of str to numpy.ndarray
        Every member named by ``nets``, float32, shape of its tensor.

    Raises
    ------
    SchemaError
        Unreadable, a member missing, of another shape or dtype, or not finite.
    """
    p = Path(path)
    want = {f"{a}.{k}": tuple(v.shape) for a, n in nets.items() for k, v in n.state_dict().items()}
    try:
        members = check_npz(p)
    except SchemaError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        other = describe_file(p)
        if other is not None and other != "a zip archive":
            raise SchemaError(f"{p}: this is {other}, not ANN weights (weights.npz)") from None
        raise SchemaError(f"{p}: not readable ANN weights ({exc})") from None
    for name, shape in want.items():
        if name not in members:
            raise SchemaError(f"{p}: member {name!r} is missing")
        got, dtype = members[name]
        if got != shape or dtype.kind != "f":
            raise SchemaError(
                f"{p}: member {name!r} must be float of shape {shape}, got {dtype} {got}"
            )
    out = {}
    try:
        with np.load(p, allow_pickle=False) as z:
            for name, shape in want.items():
                arr = check_array(str(p), f"member {name!r}", np.array(z[name]), shape=shape,
                                  low=-MAX_WEIGHT, high=MAX_WEIGHT)  # fmt: skip
                out[name] = arr.astype(np.float32)
    except SchemaError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise SchemaError(f"{p}: not readable ANN weights ({exc})") from None
    return out
