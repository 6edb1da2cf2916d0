"""The registry of file kinds (`microfab.io.filekinds`): a generator per kind, no raw reader
outside the registered loaders, and each kind's schema mutations refused on one line."""

from __future__ import annotations

import ast
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from microfab.io.filekinds import FILE_KINDS, ArraySchema, JsonSchema, TextSchema, resolve

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "fuzz"))

#: Calls that read a file raw (module alias, function); ``loadmat`` by any name.
RAW = {("json", "loads"), ("json", "load"), ("np", "load"), ("numpy", "load"),
       ("h5py", "File"), ("tomllib", "loads"), ("tomllib", "load")}  # fmt: skip

#: Functions a registered loader reads through (besides the loaders of `FILE_KINDS`).
HELPERS = {
    "microfab.io.trace:_read_mat": "trace (read_trace, read_columns)",
    "microfab.io.trace:_read_h5": "trace (read_trace, read_columns)",
    "microfab.io.checkpoint:_read": "ilc-state (read_state: every state file, check_npz first)",
    "microfab.identify.ann_files:read_weights": "ann-model (AnnModel.load)",
    "microfab.io.schema:describe_file": "the schema module (sizes checked before reading)",
    "microfab.io.schema:read_json": "the schema module (size budget, depth, constants)",
}

#: Raw reads that are not of a file a user hands microfab, with the reason.
ALLOWED = {
    "microfab.cli.run:_settings": "parses one --set value of the command line, not a file",
    "microfab.process.slm.build:_models": "parses the JSON text the module made itself as an "
    "lru_cache key, not a file",
    "microfab.io.sweep:_jsonable": "a JSON round trip in memory, not a file",
    "microfab.io.runstore:_plan": "a JSON round trip in memory, not a file",
    "microfab.plants.sourced_toml:_split_comment": "parses one TOML value of a line being "
    "edited, not a file",
    "microfab.plants.sourced_toml:update_sourced": "re-parses the text it is writing",
    "microfab.plants.sourced_toml:_check_update": "re-parses the text it is writing",
    # package data, read from the installed package (digests in the run fingerprints)
    "microfab.experiments.catalog:default_job": "package data (the default job)",
    "microfab.machines.provenance:parameter_source": "package data (twin tables)",
    "microfab.experiments.seed002_stage.shipped:recheck": "package data (shipped record)",
    "microfab.experiments.seed002_stage.shipped:main": "package data (shipped record)",
    # internal resume files of the run store, which refuses stale or damaged state first
    "microfab.io.runstore:read_manifest": "the run store's own manifest (internal)",
    "microfab.io.sweep:_open_dir": "a sweep's own resume file (internal, run store)",
    "microfab.io.sweep:_load_row": "a sweep's own resume file (internal, run store)",
    "microfab.io.sweep:load_results": "a sweep's own resume file (internal, run store)",
    "microfab.machines.xy_stage.generations:_check_folder": "internal resume (run store)",
    "microfab.machines.xy_stage.generations:_read_runs": "internal resume (run store)",
    "microfab.machines.xy_stage.generations:_saved": "internal resume (run store)",
    "microfab.machines.xy_stage.generations:_retrain": "internal resume (run store)",
    "microfab.machines.xy_stage.reference:read_point_summary": "internal resume (run store)",
    "microfab.experiments.seed002_reference.study:_sizes": "internal resume (run store)",
    "microfab.experiments.seed002_reference.report:_outputs": "the job's own result arrays "
    "(its run folder), read by its report",
    "microfab.optimize.models:recorded_validation_sigma": "optional numbers beside a models "
    "folder: a missing or odd file is skipped, values checked finite and >= 0",
    "microfab.control.export:_read": "a controller export: written for hardware by laser "
    "export, read back by no command; member and dataset sizes checked from the headers first",
    "microfab.control.export:load_exported": "the export's JSON header (same file as _read)",
}

#: Raw reads of user files still to move to a checked loader (issue 44 A), with what is
#: in the way. Each must still exist (a stale entry fails `test_the_lists_are_not_stale`).
PENDING = {
    "microfab.process.inkjet.fluids_table:load_table": "TOML property table, checked key by "
    "key by _parse_table; no schema-derived generator yet",
    "microfab.plants.sourced_toml:read_sourced": "twin TOML tables, checked key by key by "
    "_table; no schema-derived generator yet",
    "microfab.plants.sourced_toml:sources_of": "as read_sourced",
}


def raw_reads() -> Iterator[tuple[str, str, int]]:
    """``(module:function, call, line)`` of every raw file read under src/microfab."""
    src = ROOT / "src"
    for f in sorted((src / "microfab").rglob("*.py")):
        mod = ".".join(f.relative_to(src).with_suffix("").parts)
        found: list[tuple[str, str, int]] = []

        def visit(node: ast.AST, stack: list[str], mod: str = mod, out: list = found) -> None:
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                    visit(child, [*stack, child.name])
                    continue
                if isinstance(child, ast.Call):
                    fn, name = child.func, None
                    if isinstance(fn, ast.Attribute) and isinstance(fn.value, ast.Name):
                        if (fn.value.id, fn.attr) in RAW:
                            name = f"{fn.value.id}.{fn.attr}"
                    if isinstance(fn, ast.Attribute | ast.Name):
                        if getattr(fn, "attr", getattr(fn, "id", "")) == "loadmat":
                            name = "loadmat"
                    mode = [a.value for a in child.args[1:2] if isinstance(a, ast.Constant)]
                    if name and not (name == "h5py.File" and mode and mode[0] != "r"):
                        out.append((f"{mod}:{'.'.join(stack) or '<module>'}", name, child.lineno))
                visit(child, stack)

        visit(ast.parse(f.read_text(encoding="utf-8")), [])
        yield from found


def _loaders() -> set[str]:
    out = set(HELPERS)
    for k in FILE_KINDS.values():
        out.add(k.loader)
    return out


# ------------------------------------------------------------------------ the registry
def test_every_file_kind_has_a_generator() -> None:
    import fuzz_cases  # noqa: F401  (fuzz_files is registered at its end)
    from fuzz_files import missing_generators

    assert missing_generators() == []


def test_every_kind_names_a_loader_and_a_schema_that_exist() -> None:
    for name, k in FILE_KINDS.items():
        assert callable(resolve(k.loader)), name
        if isinstance(k.schema, JsonSchema):
            assert hasattr(resolve(k.schema.model), "model_validate"), name
        elif isinstance(k.schema, ArraySchema):
            assert k.schema.members and k.schema.container in ("npz", "columns"), name
        else:
            assert isinstance(k.schema, TextSchema) and ":" in k.schema.generator, name


def test_no_module_reads_a_file_raw_outside_the_registered_loaders() -> None:
    ok = _loaders() | set(ALLOWED) | set(PENDING)
    stray = [f"{where} ({call}, line {line})" for where, call, line in raw_reads()
             if where not in ok]  # fmt: skip
    assert not stray, "raw reads outside a checked loader (register a kind or allow it):\n" + (
        "\n".join(stray)
    )


def test_the_lists_are_not_stale() -> None:
    found = {where for where, _, _ in raw_reads()}
    stale = sorted((set(ALLOWED) | set(PENDING)) - found)
    assert not stale, f"no raw read left in {stale}: remove them from the lists"


# ----------------------------------------------------------------- refusals per kind
def _one_line_refusal(load: Callable[[], object], where: Path, note: str) -> str:
    with pytest.raises((ValueError, FileNotFoundError)) as exc:
        load()
    text = str(exc.value)
    assert "\n" not in text and str(where.name) in text, f"{note}: {text!r}"
    return text


def _json_cases(base: dict, model: object, notes: tuple[str, ...]) -> Iterator[tuple[str, bytes]]:
    from fuzz_files import json_mutations

    cases = dict(json_mutations(json.dumps(base).encode(), model))
    for n in notes:
        assert n in cases, f"{n} not among {sorted(cases)[:20]}"
        yield n, cases[n]


def test_tf_model_mutations_are_refused(tmp_path: Path) -> None:
    from microfab.identify.model import TFModelDoc, read_tf_model

    base = {"num": [1.242e11], "den": [1, 9517, 5.773e7, 1.272e11], "unit": "bit/bit"}
    p = tmp_path / "model.json"
    notes = ("num: str", "den: NaN in", "num: extra dim", "den: empty", "unit: unknown",
             "unit: int", "den: missing", "extra field", "nested 100 000 deep",
             "not JSON")  # fmt: skip
    for note, data in _json_cases(base, TFModelDoc, notes):
        p.write_bytes(data)
        _one_line_refusal(lambda: read_tf_model(p), p, note)


def test_shaper_mutations_are_refused(tmp_path: Path) -> None:
    from microfab.control.shaper_io import ImpulseShaperDoc, read_shaper, shaper_to_dict
    from microfab.control.shapers import design_shaper

    base = shaper_to_dict(design_shaper("zv", 2500.0, 0.1))
    p = tmp_path / "shaper.json"
    notes = ("freq_hz: str", "freq_hz: NaN", "freq_hz: gt 0 broken", "damping: lt 1 broken",
             "amplitudes: scalar", "amplitudes: NaN in", "times_s: -1 in", "name: null",
             "numeric: int", "extra field")  # fmt: skip
    for note, data in _json_cases(base, ImpulseShaperDoc, notes):
        p.write_bytes(data)
        _one_line_refusal(lambda: read_shaper(p), p, note)
    p.write_text(json.dumps({"num": [1.0], "den": [1.0, 1.0]}))
    assert "this is a transfer-function model" in _one_line_refusal(
        lambda: read_shaper(p), p, "a model file"
    )


def test_frame_index_mutations_are_refused(tmp_path: Path) -> None:
    from microfab.measure.frames import FrameIndex, read_sidecar

    base = {"pixel_size_m": 2e-6, "frame_interval_s": 1e-5, "nozzle_row": 3, "bit_depth": 8}
    p = tmp_path / "frames.json"
    notes = ("pixel_size_m: le 0.0001 broken", "pixel_size_m: str", "nozzle_row: -1",
             "bit_depth: float", "frame_interval_s: inf", "nested 100 000 deep")  # fmt: skip
    for note, data in _json_cases(base, FrameIndex, notes):
        p.write_bytes(data)
        _one_line_refusal(lambda: read_sidecar(tmp_path), p, note)


def test_run_list_mutations_are_refused(tmp_path: Path) -> None:
    from microfab.identify.excitation import _RunIndex, read_runs

    run = {"name": "r0", "kind": "random", "file": "r0.csv", "seed": 1, "dt_s": 1e-4,
           "n_samples": 10, "sha256": "0" * 64, "params": {}}  # fmt: skip
    base = {"format": 1, "runs": [run], "unit": "m", "total_samples": 10}
    p = tmp_path / "runs.json"
    notes = ("runs.0.dt_s: str", "runs.0.dt_s: gt 0 broken", "runs.0.n_samples: float",
             "runs.0.n_samples: 1e308", "runs.0.file: path out", "runs: empty", "unit: unknown",
             "runs.0.seed: -1")  # fmt: skip
    for note, data in _json_cases(base, _RunIndex, notes):
        p.write_bytes(data)
        _one_line_refusal(lambda: read_runs(tmp_path), p, note)


def test_stage_model_mutations_are_refused(tmp_path: Path) -> None:
    from microfab.identify.stage_data import StageLinearDoc, read_stage_model

    sub = {"format": "microfab.identify.SubspaceModel", "version": 1, "dt": 1e-3,
           "rate_hz": 1e3, "order": 1, "block_rows": 10, "weighting": "n4sid",
           "a": [[0.5]], "b": [[1.0, 0.0]], "c": [[1.0], [1.0]], "d": [[0.0, 0.0], [0.0, 0.0]],
           "x0": [], "singular_values": [1.0], "fit_mean": [0.0] * 4,
           "fit_std": [1.0] * 4}  # fmt: skip
    base = {"format": "microfab.identify.StageModel", "version": 1, "kind": "linear",
            "axes": ["x", "y"], "unit": "m", "input_rate_hz": 1e4, "decimate": 10,
            "model_rate_hz": 1e3, "anti_alias": "fir", "model": sub}  # fmt: skip
    p = tmp_path / "linear_model.json"
    notes = ("input_rate_hz: str", "input_rate_hz: le 1e+07 broken", "decimate: float",
             "unit: unknown", "model.dt: NaN", "model.a: scalar", "model.order: gt 0 broken",
             "axes: half")  # fmt: skip
    notes = tuple(n.replace("gt 0 broken", "ge 1 broken") if "order" in n else n for n in notes)
    for note, data in _json_cases(base, StageLinearDoc, notes):
        p.write_bytes(data)
        _one_line_refusal(lambda: read_stage_model(p), p, note)


def test_rc_contour_mutations_are_refused(tmp_path: Path) -> None:
    from fuzz_files import npz_mutations

    from microfab.machines.nanomanipulator.files import read_contour

    buf = tmp_path / "contour.npz"
    np.savez(buf, reference=np.zeros((20, 2)), dt=np.array(1e-4))
    cases = dict(npz_mutations(buf.read_bytes()))
    for note in ("reference: NaN", "reference: half", "reference: extra dim", "reference: "
                 "str dtype", "reference: missing", "reference: declares 2e+09 samples",
                 "dt: -1", "dt: extra dim", "cut in half", "empty"):  # fmt: skip
        buf.write_bytes(cases[note])
        _one_line_refusal(lambda: read_contour(buf, 20), buf, note)


def test_trace_mutations_are_refused(tmp_path: Path) -> None:
    from fuzz_files import csv_mutations, h5_mutations

    from microfab.io.trace import read_trace, write_columns

    cols = {"time": np.arange(20) * 1e-3, "x": np.linspace(0, 1e-3, 20)}
    write_columns(tmp_path / "t.csv", cols, unit="m")
    write_columns(tmp_path / "t.h5", cols, unit="m")
    cases = [(".csv", n, d) for n, d in csv_mutations((tmp_path / "t.csv").read_bytes())]
    cases += [(".h5", n, d) for n, d in h5_mutations((tmp_path / "t.h5").read_bytes())]
    wanted = {(".csv", "x: NaN"), (".csv", "x: str"), (".csv", "# unit: parsecs"),
              (".csv", "# unit: s"), (".h5", "x: declares 2e+09 samples"),
              (".h5", "x: unit=parsecs"), (".h5", "unit=V"), (".h5", "x: half"),
              (".h5", "x: str dtype")}  # fmt: skip
    seen = set()
    for suffix, note, data in cases:
        if (suffix, note) in wanted:
            p = tmp_path / f"m{suffix}"
            p.write_bytes(data)
            _one_line_refusal(lambda p=p: read_trace(p, to_unit="m"), p, note)
            seen.add((suffix, note))
    assert seen == wanted


def test_ann_model_mutations_are_refused(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from fuzz_files import npz_mutations
    from torch import nn

    from microfab.identify.ann import MetaDoc, read_weights

    nets = {"x": nn.Sequential(nn.Linear(3, 2), nn.LeakyReLU(0.01), nn.Linear(2, 1))}
    p = tmp_path / "weights.npz"
    np.savez(p, **{f"x.{k}": v.detach().numpy() for k, v in nets["x"].state_dict().items()})
    cases = dict(npz_mutations(p.read_bytes()))
    for note in ("x.0.weight: NaN", "x.0.weight: half", "x.0.weight: int dtype",
                 "x.2.bias: declares 2e+09 samples", "x.2.bias: missing", "x.0.bias: 1e308",
                 "cut in half"):  # fmt: skip
        p.write_bytes(cases[note])
        _one_line_refusal(lambda: read_weights(p, nets), p, note)
    assert MetaDoc.model_fields["scaling"] is not None  # the header's schema (fuzz_files)
