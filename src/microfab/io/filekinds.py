"""Every kind of file a user hands microfab: what it is, its loader and its schema, as data.

`FILE_KINDS` is the one list of them (issue 44, cause A). Each `FileKind` names:

- ``what``: the file as `microfab.io.schema.describe_file` and the refusals say it;
- ``loader``: the checked loader, a dotted path (``"package.module:function"`` or
  ``"package.module:Class.method"``), not imported here;
- ``schema``: what the loader checks, as data: a `JsonSchema` (the pydantic model, a
  dotted path), an `ArraySchema` (the members or columns: dtype kind, shape with
  ``None`` for a free length, range, unit; and the pydantic model of a JSON header), or
  a `TextSchema` (drawings, job TOML: the fuzz generator that already covers them);
- ``command``: the ``microfab`` command that reads it (``tests/fuzz/fuzz_files.py``
  runs each generated file through that command).

Nothing heavy is imported: `resolve` imports a dotted path when it is asked for.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

__all__ = [
    "FILE_KINDS",
    "ArraySchema",
    "FileKind",
    "JsonSchema",
    "Member",
    "TextSchema",
    "resolve",
]


@dataclass(frozen=True)
class Member:
    """One array member (``.npz``) or column (trace) of an array file.

    Attributes
    ----------
    name : str
        Member or column name (``"<axis>.<name>"`` patterns are written with ``*``).
    kind : {"f", "c", "b", "i"}
        dtype kind (`microfab.io.schema.check_array`).
    shape : tuple of (int, str or None)
        Shape; ``None`` a free length, a letter a length shared with other members
        (``"n"`` samples, ``"a"`` axes, ``"b"`` rfft bins, ``"i"`` trials).
    low, high : float or None
        Range of the values, in ``unit``.
    unit : str
        Unit of the values (``""``: none, or declared in the file).
    """

    name: str
    kind: str = "f"
    shape: tuple[int | str | None, ...] = (None,)
    low: float | None = None
    high: float | None = None
    unit: str = ""


@dataclass(frozen=True)
class JsonSchema:
    """A JSON document checked by a pydantic model (``"module:Class"``)."""

    model: str


@dataclass(frozen=True)
class ArraySchema:
    """Arrays: an ``.npz`` archive (``container="npz"``) or trace columns (``"columns"``).

    ``header``: the pydantic model (``"module:Class"``) of a JSON member or companion
    file, or ``""``; ``free``: other members or columns are allowed (a trace's columns).
    """

    container: str
    members: tuple[Member, ...]
    header: str = ""
    free: bool = False


@dataclass(frozen=True)
class TextSchema:
    """A text or TOML kind whose generator already exists (``"fuzz module:strategy"``)."""

    generator: str


@dataclass(frozen=True)
class FileKind:
    """One kind of file (module docstring)."""

    name: str
    what: str
    loader: str
    schema: JsonSchema | ArraySchema | TextSchema
    command: str
    suffixes: tuple[str, ...] = ()
    #: Key sets by which a JSON document of this kind is recognised (any one suffices;
    #: `microfab.io.schema.describe_file` names a file of another kind by them).
    json_keys: tuple[frozenset[str], ...] = ()


def resolve(dotted: str) -> Any:
    """The object at ``"package.module:Name.attr"`` (imported now)."""
    module, _, attr = dotted.partition(":")
    obj: Any = importlib.import_module(module)
    for part in attr.split(".") if attr else ():
        obj = getattr(obj, part)
    return obj


_TRACE = ArraySchema(
    "columns",
    (
        Member("time", shape=(None,), low=0.0, unit="s"),
        Member("ref_x", unit="m"),
        Member("ref_y", unit="m"),
        Member("x", unit="m"),
        Member("y", unit="m"),
    ),
    free=True,
)
_ILC = ArraySchema(
    "npz",
    (
        Member("reference", shape=("n", "a")),
        Member("inputs", shape=("i+1", "n", "a")),
        Member("pinv", kind="c", shape=("b", "a")),
        Member("mask", kind="b", shape=("b", "a")),
        Member("rms", shape=("i", "a"), low=0.0),
        Member("pp", shape=("i", "a"), low=0.0),
        Member("gain", shape=("b", "a"), low=0.0, high=2.0),
    ),
    header="microfab.control.ilc_state:checked_state",
)

#: Every kind of file a user hands microfab, by name.
FILE_KINDS: dict[str, FileKind] = {
    k.name: k
    for k in (
        FileKind(
            "trace",
            "a measured trace (CSV, MAT or HDF5 columns)",
            "microfab.io.trace:read_trace",
            _TRACE,
            "ilc step",
            (".csv", ".mat", ".h5", ".hdf5"),
        ),
        FileKind(
            "frf",
            "a frequency response table (CSV of shaper design --frf)",
            "microfab.io.frf:read_frf",
            ArraySchema(
                "columns",
                (Member("freq_hz", low=0.0, unit="Hz"), Member("mag"), Member("phase_deg")),
                free=True,
            ),
            "shaper design",
            (".csv",),
        ),
        FileKind(
            "ilc-state",
            "an ILC state file",
            "microfab.control.ilc:FrequencyILC.load",
            _ILC,
            "ilc step",
            (".npz",),
        ),
        FileKind(
            "rc-contour",
            "the contour of an RC state (contour.npz)",
            "microfab.machines.nanomanipulator.files:read_contour",
            ArraySchema("npz", (Member("reference", shape=("n", 2), unit="mm"),)),
            "rc step",
            (".npz",),
        ),
        FileKind(
            "frame-index",
            "a frame index (frames.json)",
            "microfab.measure.frames:read_sidecar",
            JsonSchema("microfab.measure.frames:FrameIndex"),
            "droplet analyze",
            (".json",),
            (frozenset({"pixel_size_m", "frame_interval_s"}),),
        ),
        FileKind(
            "run-list",
            "a stage run list (runs.json of stage excite)",
            "microfab.identify.excitation:read_runs",
            JsonSchema("microfab.identify.excitation:_RunIndex"),
            "stage play",
            (".json",),
            (frozenset({"runs", "total_samples"}),),
        ),
        FileKind(
            "ann-model",
            "an ANN model (model.json of identify ann)",
            "microfab.identify.ann:AnnModel.load",
            ArraySchema(
                "npz",
                (Member("*.<layer>.weight", shape=(None, None)), Member("*.<layer>.bias")),
                header="microfab.identify.ann_files:MetaDoc",
            ),
            "identify validate",
            (),
            (frozenset({"format_version", "layers", "scaling"}),),
        ),
        FileKind(
            "tf-model",
            "a transfer-function model (JSON)",
            "microfab.identify.model:read_tf_model",
            JsonSchema("microfab.identify.model:TFModelDoc"),
            "shaper design",
            (".json",),
            (frozenset({"num", "den"}),),
        ),
        FileKind(
            "shaper",
            "a shaper (JSON of shaper design)",
            "microfab.control.shaper_io:read_shaper",
            JsonSchema("microfab.control.shaper_io:ImpulseShaperDoc"),
            "slm scan-time",
            (".json",),
            (frozenset({"kind", "amplitudes", "times_s"}), frozenset({"kind", "model", "config"})),
        ),
        FileKind(
            "stage-model",
            "a stage model (JSON of identify linear)",
            "microfab.identify.stage_data:read_stage_model",
            JsonSchema("microfab.identify.stage_data:StageLinearDoc"),
            "identify validate",
            (".json",),
            (frozenset({"kind", "axes", "input_rate_hz", "model"}),),
        ),
        FileKind(
            "optimize-summary",
            "an optimize summary (summary.json of microfab optimize)",
            "microfab.optimize.summary_file:read_optimize_summary",
            JsonSchema("microfab.optimize.summary_file:OptimizeSummaryDoc"),
            "stage score",
            (".json",),
            (frozenset({"drawing", "sizing", "commands", "path_length_m"}),),
        ),
        FileKind(
            "dxf",
            "a DXF drawing",
            "microfab.geometry.dxf:read_dxf",
            TextSchema("fuzz_cases:dxf_case"),
            "path show",
            (".dxf",),
        ),
        FileKind(
            "svg",
            "an SVG drawing",
            "microfab.geometry.svg:read_svg",
            TextSchema("fuzz_cases:svg_case"),
            "path show",
            (".svg",),
        ),
        FileKind(
            "dat",
            "an airfoil coordinate file (Selig or Lednicer)",
            "microfab.geometry.load:load_drawing",
            TextSchema("fuzz_cases:dat_case"),
            "path show",
            (".dat",),
        ),
        FileKind(
            "job",
            "a job file (TOML)",
            "microfab.io.job:read_job",
            TextSchema("fuzz_cases:job_case"),
            "run",
            (".toml",),
        ),
        FileKind(
            "frames",
            "camera frames (PNG, TIFF)",
            "microfab.measure.frames:load_frames",
            TextSchema("fuzz_cases:frames_case"),
            "droplet analyze",
            (".png", ".tif", ".tiff"),
        ),
    )
}
