"""A fuzz generator per file kind of `microfab.io.filekinds.FILE_KINDS`, from its schema.

Each kind starts from a valid file of the fuzz workspace (`fuzz_workspace`; the ANN model
folder is trained here once per process) and mutates every field its schema declares:

- **type**: a string for a number, a list for a scalar, ``null``, a number for a string;
- **shape**: a scalar for a list, an empty list, half the length, an extra dimension;
- **value**: NaN, infinity, -1, 1e308, and just outside each declared bound (``gt``,
  ``ge``, ``lt``, ``le`` of the pydantic field);
- **size**: an ``.npz`` member or HDF5 dataset whose header declares 2e9 samples in a
  file of a few kB; JSON nested 100 000 deep;
- **unit**: an unknown unit, a unit of another dimension (a CSV ``# unit:`` line, an
  HDF5 ``unit`` attribute);
- **missing and extra** fields, members and columns; **the file of another kind**
  (every other kind's valid file in its place).

Each mutated file replaces the valid one in the workspace and the command that reads
the kind (`SOURCES`: its recipe of `fuzz_workspace.RECIPES`) runs on it, as a
`fuzz_driver.Case` of kind ``file-<kind>``. Cases are enumerated (`cases_of`) and drawn
by hypothesis from that list (`FILE_KINDS_CASES`, registered in `fuzz_cases.KINDS`).
"""

from __future__ import annotations

import copy
import functools
import io
import json
import math
import shutil
import tempfile
import typing
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fuzz_driver
import numpy as np
from fuzz_driver import Case
from fuzz_workspace import RECIPES, RUNS, build_workspace, template
from hypothesis import strategies as st

from microfab.io.filekinds import FILE_KINDS, ArraySchema, JsonSchema, TextSchema, resolve

__all__ = ["FILE_KINDS_CASES", "SOURCES", "cases_of", "missing_generators"]

fuzz_driver.FIXTURES.setdefault("workspace", build_workspace)

#: Declared samples of a forged member or dataset (a header of 2e9 samples, 16 GB of
#: float64, in a file of a few kB: issue 44 A).
HUGE = 2_000_000_000


@dataclass(frozen=True)
class Source:
    """Where a kind's valid file lies in the workspace and the command that reads it."""

    files: tuple[str, ...]  # workspace paths; the first is the one mutated
    argv: tuple[str, ...]
    keep: tuple[str, ...]


def _recipe(name: str, files: tuple[str, ...]) -> Source:
    r = RECIPES[name]
    return Source(files, r.argv, tuple(i for i in r.inputs if i not in r.outputs))


_ANN = "ann_model"
#: Each generated kind: its valid file(s) and the command that reads them.
SOURCES: dict[str, list[Source]] = {
    "trace": [
        _recipe("ilc step", ("ilc_trial.csv",)),
        _recipe("nanomanipulator analyze", ("nano_trace.h5",)),
    ],
    "frf": [
        Source(
            ("frf.csv",),
            ("shaper", "design", "--kind", "zv", "--frf", "frf.csv", "--out", "designed.json"),
            ("frf.csv",),
        ),
    ],
    "ilc-state": [_recipe("ilc step", ("ilc_state/ilc_state.npz",))],
    "rc-contour": [_recipe("rc step", ("rc_state/contour.npz",))],
    "frame-index": [_recipe("droplet analyze", ("frames/frames.json",))],
    "run-list": [_recipe("stage play", ("excited/runs.json",))],
    "ann-model": [
        Source(
            (f"{_ANN}/model.json", f"{_ANN}/weights.npz"),
            ("identify", "validate", _ANN, RUNS[0], "--json", "validate.json"),
            (RUNS[0],),
        ),
        Source(
            (f"{_ANN}/weights.npz", f"{_ANN}/model.json"),
            ("identify", "validate", _ANN, RUNS[0], "--json", "validate.json"),
            (RUNS[0],),
        ),
    ],
    "tf-model": [_recipe("shaper design", ("model.json",))],
    "shaper": [_recipe("slm scan-time", ("shaper.json",))],
    "stage-model": [_recipe("identify validate", ("linear_model.json",))],
    "optimize-summary": [_recipe("stage score", ("opt_done/summary.json",))],
}


# ------------------------------------------------------------------------ valid files
@functools.cache
def _ann_folder() -> Path:
    """An ANN model folder trained once per process by ``identify ann`` (one epoch)."""
    from fuzz_driver import _template_dir
    from fuzz_workspace import _cli

    out = _template_dir() / "ann_base"
    if not out.is_dir():
        work = Path(tempfile.mkdtemp(prefix="ann-", dir=_template_dir()))
        build_workspace(work)
        _cli(work, *RECIPES["identify ann"].argv)
        (work / _ANN).rename(out)
        shutil.rmtree(work)
    return out


def valid(rel: str) -> bytes:
    """The valid workspace file ``rel`` (the ANN model's files included)."""
    if rel.startswith(_ANN + "/"):
        return (_ann_folder() / rel.split("/", 1)[1]).read_bytes()
    return (template() / rel).read_bytes()


# ----------------------------------------------------------------------- JSON mutations
def _bounds(info: Any) -> list[tuple[str, float]]:
    """Values just outside the bounds a pydantic field declares."""
    out = []
    for m in getattr(info, "metadata", ()):
        for attr, sign in (("gt", 0), ("ge", -1), ("lt", 0), ("le", 1)):
            b = getattr(m, attr, None)
            if isinstance(b, int | float) and not isinstance(b, bool):
                step = max(abs(b), 1.0) * 0.5
                value = b if sign == 0 else b + sign * step
                out.append((f"{attr} {b:g} broken", float(value)))
    return out


def _walk(
    model: Any, doc: Any, path: tuple[Any, ...] = ()
) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """(path, field info) of every field of ``model`` present in ``doc``, nested models too."""
    from pydantic import BaseModel

    if not isinstance(doc, dict):
        return
    for name, info in model.model_fields.items():
        if name not in doc:
            continue
        yield (*path, name), info
        ann, value = info.annotation, doc[name]
        args = [a for a in typing.get_args(ann) if isinstance(a, type)]
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            yield from _walk(ann, value, (*path, name))
        elif args and issubclass(args[-1], BaseModel):
            sub = args[-1]
            if isinstance(value, dict) and typing.get_origin(ann) is dict and value:
                key = next(iter(value))
                yield from _walk(sub, value[key], (*path, name, key))
            elif isinstance(value, list) and value:
                yield from _walk(sub, value[0], (*path, name, 0))


def _values(value: Any, info: Any) -> list[tuple[str, Any]]:
    """Replacements of one field's value: type, shape and value mutations."""
    if isinstance(value, bool):
        return [("str", "true"), ("int", 1), ("null", None), ("list", [value])]
    if isinstance(value, int | float):
        out: list[tuple[str, Any]] = [
            ("str", str(value)),
            ("list", [value]),
            ("null", None),
            ("NaN", math.nan),
            ("inf", math.inf),
            ("-inf", -math.inf),
            ("-1", -1),
            ("1e308", 1e308),
            ("negated", -value if value else -1.0),
            ("float", float(value) + 0.5),
        ]
        return out + _bounds(info)
    if isinstance(value, str):
        return [
            ("int", 1),
            ("null", None),
            ("list", [value]),
            ("empty", ""),
            ("unknown", "zz-unknown"),
            ("path out", "../outside.json"),
        ]
    if isinstance(value, list):
        out = [
            ("empty", []),
            ("scalar", value[0] if value else 0.0),
            ("null", None),
            ("str", "1,2"),
            ("extra dim", [value]),
            ("half", value[: len(value) // 2]),
        ]
        if value and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
            out += [
                ("NaN in", [math.nan, *value[1:]]),
                ("str in", ["1", *value[1:]]),
                ("1e308 in", [1e308, *value[1:]]),
                ("-1 in", [-1, *value[1:]]),
            ]
        return out
    if isinstance(value, dict):
        return [("null", None), ("list", []), ("str", "x"), ("empty", {})]
    return [("str", "x"), ("list", [])]


def _set(doc: Any, path: tuple[Any, ...], value: Any, delete: bool = False) -> Any:
    new = copy.deepcopy(doc)
    node = new
    for p in path[:-1]:
        node = node[p]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return new


def _dumps(doc: Any) -> bytes:
    return json.dumps(doc, allow_nan=True).encode()


def json_mutations(base: bytes, model: Any) -> Iterator[tuple[str, bytes]]:
    """(note, bytes) of every schema-derived mutation of the JSON document ``base``."""
    doc = json.loads(base)
    for path, info in _walk(model, doc):
        where = ".".join(str(p) for p in path)
        node = doc
        for p in path:
            node = node[p]
        for note, new in _values(node, info):
            yield f"{where}: {note}", _dumps(_set(doc, path, new))
        yield f"{where}: missing", _dumps(_set(doc, path, None, delete=True))
    yield "extra field", _dumps({**doc, "zz_extra": 1})
    yield "nested 100 000 deep", b"[" * 100_000 + b"]" * 100_000
    yield "a list", _dumps([doc])
    yield "not JSON", base[: len(base) // 2]
    yield "empty", b""


# --------------------------------------------------------------------- array mutations
def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _forged(arrays: dict[str, np.ndarray], name: str) -> bytes:
    """An ``.npz`` whose member ``name`` declares `HUGE` float64 samples and holds 16 bytes."""
    src = zipfile.ZipFile(io.BytesIO(_npz_bytes(arrays)))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for info in src.infolist():
            if info.filename == f"{name}.npy":
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(
                    head, {"descr": "<f8", "fortran_order": False, "shape": (HUGE,)}
                )
                z.writestr(info.filename, head.getvalue() + b"\x00" * 16)
            else:
                z.writestr(info, src.read(info))
    return out.getvalue()


def _array_values(arr: np.ndarray) -> list[tuple[str, np.ndarray]]:
    out = [
        ("str dtype", arr.astype(str)),
        ("scalar", np.asarray(arr.flat[0] if arr.size else 0.0)),
        ("empty", arr.reshape(-1)[:0]),
        ("half", arr[: len(arr) // 2] if arr.ndim else arr),
        ("extra dim", arr[None]),
        ("int dtype", np.zeros(arr.shape, dtype=np.int64)),
        ("bool dtype", np.ones(arr.shape, dtype=bool)),
    ]
    if arr.dtype.kind in "fc" and arr.size:
        for note, v in (("NaN", np.nan), ("inf", np.inf), ("1e308", 1e308), ("-1", -1.0)):
            bad = arr.copy()
            with np.errstate(over="ignore"):  # 1e308 in float32 is inf: also refused
                bad.flat[0] = v
            out.append((note, bad))
    if arr.dtype.kind == "f":
        out.append(("complex dtype", arr.astype(complex) + 1j))
    return out


def npz_mutations(base: bytes) -> Iterator[tuple[str, bytes]]:
    """(note, bytes) of every member mutation of the ``.npz`` archive ``base``."""
    with np.load(io.BytesIO(base), allow_pickle=False) as z:
        arrays = {k: np.array(z[k]) for k in z.files}
    for name, arr in arrays.items():
        if name == "meta":  # a state file's JSON header: its fields mutated as JSON
            doc = json.loads(str(arr))
            for key in list(doc)[:8]:
                for note, new in _values(doc[key], None)[:5]:
                    meta = np.array(json.dumps({**doc, key: new}, allow_nan=True))
                    yield f"meta.{key}: {note}", _npz_bytes({**arrays, "meta": meta})
                rest = {k: v for k, v in doc.items() if k != key}
                yield (
                    f"meta.{key}: missing",
                    _npz_bytes({**arrays, "meta": np.array(json.dumps(rest))}),
                )
            continue
        for note, new in _array_values(arr):
            yield f"{name}: {note}", _npz_bytes({**arrays, name: new})
        yield f"{name}: missing", _npz_bytes({k: v for k, v in arrays.items() if k != name})
        yield f"{name}: declares {HUGE:.0e} samples", _forged(arrays, name)
    yield "extra member", _npz_bytes({**arrays, "zz_extra": np.zeros(3)})
    yield "cut in half", base[: len(base) // 2]
    yield "empty", b""


def _csv_columns(base: bytes) -> tuple[str, list[str], np.ndarray]:
    lines = base.decode().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if not ln.startswith("#")]
    header = body[0].split(",")
    data = np.loadtxt(io.StringIO("\n".join(body[1:])), delimiter=",", ndmin=2)
    return "\n".join(comments), header, data


def _csv(
    comments: str, header: list[str], data: np.ndarray, cells: list[list[str]] | None = None
) -> bytes:
    rows = cells if cells is not None else [[repr(float(v)) for v in r] for r in data]
    text = (comments + "\n" if comments else "") + ",".join(header) + "\n"
    return (text + "\n".join(",".join(r) for r in rows) + "\n").encode()


def csv_mutations(base: bytes) -> Iterator[tuple[str, bytes]]:
    """(note, bytes) of every column, unit and size mutation of the CSV trace ``base``."""
    comments, header, data = _csv_columns(base)
    cells = [[repr(float(v)) for v in r] for r in data]
    for j, name in enumerate(header):
        for note, text in (
            ("NaN", "nan"),
            ("inf", "inf"),
            ("1e308", "1e308"),
            ("str", "abc"),
            ("-1", "-1"),
            ("empty cell", ""),
        ):
            bad = copy.deepcopy(cells)
            bad[1][j] = text
            yield f"{name}: {note}", _csv(comments, header, data, bad)
        yield (
            f"{name}: missing",
            _csv(comments, header[:j] + header[j + 1 :], np.delete(data, j, axis=1)),
        )
        yield (
            f"{name}: half length",
            _csv(
                comments,
                header,
                data,
                [
                    r if i < len(cells) // 2 else [c if k != j else "" for k, c in enumerate(r)]
                    for i, r in enumerate(cells)
                ],
            ),
        )
        yield (
            f"{name}: doubled",
            _csv(comments, [*header, name], np.column_stack([data, data[:, j]])),
        )
    if "time" in header:
        t = data.copy()
        t[:, header.index("time")] *= 1e3
        yield "time in ms", _csv(comments, header, t)
        t = data.copy()
        t[:, header.index("time")] = t[::-1, header.index("time")]
        yield "time reversed", _csv(comments, header, t)
    for unit in ("parsecs", "s", "km", "m/s", "furlong"):
        yield f"# unit: {unit}", _csv(f"# unit: {unit}", header, data)
    yield "3 samples", _csv(comments, header, data[:3])
    yield "1 sample", _csv(comments, header, data[:1])
    yield "header only", _csv(comments, header, data[:0])
    yield "extra column", _csv(comments, [*header, "zz_extra"], np.column_stack([data, data[:, 0]]))
    yield "cut in half", base[: len(base) // 2]
    yield "empty", b""


def _h5(
    columns: dict[str, Any],
    unit: str = "m",
    attrs: dict[str, dict[str, str]] | None = None,
    huge: str = "",
) -> bytes:
    import h5py

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "t.h5"
        with h5py.File(p, "w", track_order=True) as f:
            f.attrs["unit"] = unit
            for name, col in columns.items():
                if name == huge:  # chunked, never written: a tiny file that declares HUGE
                    f.create_dataset(name, shape=(HUGE,), dtype="f8", chunks=(1024,))
                else:
                    col = col.astype("S") if col.dtype.kind == "U" else col  # h5py: bytes
                    d = f.create_dataset(name, data=col)
                    for k, v in (attrs or {}).get(name, {}).items():
                        d.attrs[k] = v
        return p.read_bytes()


def h5_mutations(base: bytes) -> Iterator[tuple[str, bytes]]:
    """(note, bytes) of every dataset, unit and size mutation of the HDF5 trace ``base``."""
    import h5py

    with h5py.File(io.BytesIO(base), "r") as f:
        unit = f.attrs.get("unit", "")
        unit = unit.decode() if isinstance(unit, bytes) else str(unit)
        cols = {k: np.array(v[()]) for k, v in f.items()}
    for name, arr in cols.items():
        for note, new in _array_values(arr):
            yield f"{name}: {note}", _h5({**cols, name: new}, unit)
        yield f"{name}: missing", _h5({k: v for k, v in cols.items() if k != name}, unit)
        yield f"{name}: declares {HUGE:.0e} samples", _h5(cols, unit, huge=name)
        for u in ("parsecs", "s"):
            yield f"{name}: unit={u}", _h5(cols, unit, {name: {"unit": u}})
    for u in ("km", "parsecs", "V"):
        yield f"unit={u}", _h5(cols, u)
    yield "extra dataset", _h5({**cols, "zz_extra": np.zeros(3)}, unit)
    yield "cut in half", base[: len(base) // 2]


# --------------------------------------------------------------------------- the cases
def _mutations(kind: str, rel: str, base: bytes) -> Iterator[tuple[str, bytes]]:
    schema = FILE_KINDS[kind].schema
    if rel.endswith(".json"):
        model = resolve(schema.model) if isinstance(schema, JsonSchema) else None
        if model is None and isinstance(schema, ArraySchema) and schema.header:
            model = resolve(schema.header)
        yield from json_mutations(base, model)
    elif rel.endswith(".npz"):
        yield from npz_mutations(base)
    elif rel.endswith((".h5", ".hdf5")):
        yield from h5_mutations(base)
    else:
        yield from csv_mutations(base)


def _other_kinds(kind: str, rel: str) -> Iterator[tuple[str, bytes]]:
    """The valid file of every other generated kind in place of this one."""
    for other, sources in SOURCES.items():
        if other != kind:
            o = sources[0].files[0]
            yield f"a {other} file ({o})", valid(o)


@functools.cache
def cases_of(kind: str) -> tuple[Case, ...]:
    """Every case of the generated kind ``kind`` (a `SOURCES` key), in a fixed order."""
    out = []
    for src in SOURCES[kind]:
        rel = src.files[0]
        base = valid(rel)
        companions = tuple((f, valid(f)) for f in src.files[1:])
        for note, data in (*_mutations(kind, rel, base), *_other_kinds(kind, rel)):
            out.append(
                Case(
                    kind=f"file-{kind}",
                    argv=src.argv,
                    files=(*companions, (rel, data)),
                    setup=("workspace",),
                    note=f"{rel}: {note}",
                    keep=src.keep,
                )
            )
    return tuple(out)


def _strategy(kind: str) -> Callable[[], st.SearchStrategy[Case]]:
    def strategy() -> st.SearchStrategy[Case]:
        return st.sampled_from(cases_of(kind))

    strategy.__name__ = f"file_{kind.replace('-', '_')}_case"
    return strategy


def missing_generators() -> list[str]:
    """The kinds of `FILE_KINDS` with no generator (here or, for text kinds, in fuzz_cases)."""
    from fuzz_cases import KINDS

    out = []
    for name, k in FILE_KINDS.items():
        if isinstance(k.schema, TextSchema):
            module, _, attr = k.schema.generator.partition(":")
            if not callable(getattr(__import__(module), attr, None)):
                out.append(f"{name} (no {k.schema.generator})")
        elif name not in SOURCES or f"file-{name}" not in KINDS:
            out.append(f"{name} (no file-{name} in fuzz_files)")
    return out


#: The kinds of this module and their share of ``make fuzz`` (as `fuzz_cases.KINDS`).
FILE_KINDS_CASES: dict[str, tuple[Callable[[], st.SearchStrategy[Case]], float]] = {
    f"file-{k}": (_strategy(k), 0.01) for k in SOURCES
}
