"""The ``summary.json`` of ``microfab optimize`` as ``microfab stage score`` reads it back.

`read_optimize_summary` reads the file through `microfab.io.schema` (a size budget, deep
nesting refused, a file of another kind named) and checks the keys ``stage score`` uses
with `OptimizeSummaryDoc` (strict types, finite numbers, ranges); the other keys of the
file (the optimiser's statistics, the warning) are kept aside, unchecked, as they are
only shown. Each refusal is one `microfab.io.schema.SchemaError` line naming the file and
the key.
"""

from __future__ import annotations

import os
from pathlib import PurePosixPath

from pydantic import BaseModel, ConfigDict, Field, field_validator

from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import read_json, validated

__all__ = ["CommandDoc", "OptimizeSummaryDoc", "SizingDoc", "read_optimize_summary"]

#: What the file is, for messages and `microfab.io.schema.describe_file`.
SUMMARY_KIND = FILE_KINDS["optimize-summary"].what
#: Most lead samples, and most points M of the optimised reference (assumed: 1e7, far
#: above the 5000 points `optimize --n` allows; only a guard against a damaged file).
MAX_COUNT = 10_000_000


class CommandDoc(BaseModel):
    """One command file the folder holds: its name and its lead samples."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    file: str = Field(min_length=1, max_length=255)
    lead: int = Field(ge=0, le=MAX_COUNT)

    @field_validator("file")
    @classmethod
    def _a_plain_name(cls, v: str) -> str:
        p = PurePosixPath(v)
        if p.name != v or v in (".", "..") or "\\" in v or "\x00" in v:
            raise ValueError("must be a file name in the folder, not a path")
        return v


class SizingDoc(BaseModel):
    """How the drawing was sized (`microfab.cli.geometry` options)."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    chord: float = Field(gt=0.0, le=10.0)  # m, as `--chord`
    text_height: float = Field(gt=0.0, le=10.0)  # m, as `--text-height`
    units: str | None = None


class OptimizeSummaryDoc(BaseModel):
    """The keys of ``summary.json`` that ``stage score`` reads."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    drawing: str = Field(min_length=1)
    contour: int = Field(ge=0, le=MAX_COUNT)
    sizing: SizingDoc
    m: int = Field(ge=1, le=MAX_COUNT)
    path_length_m: float = Field(gt=0.0, le=1e3)
    drawing_sha256: str | None = Field(None, pattern=r"^[0-9a-f]{64}$")
    commands: dict[str, CommandDoc] = Field(min_length=1)


def read_optimize_summary(path: str | os.PathLike[str]) -> OptimizeSummaryDoc:
    """The checked summary of an ``optimize`` folder.

    Raises
    ------
    ValueError
        (`microfab.io.schema.SchemaError`) Unreadable, of another kind, a key missing, of
        the wrong type or out of range; one line naming the file and the key.
    """
    doc = read_json(path, SUMMARY_KIND)
    return validated(OptimizeSummaryDoc, doc, str(path))
