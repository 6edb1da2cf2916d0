"""Every file read through a schema (issue 44, cause A): sizes, units, arrays, JSON, paths.

Each command example is refused with one ``error:`` line, exit 2, before any output is
written and with every file left as it was.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.schema import (
    MAX_SAMPLES,
    SchemaError,
    check_array,
    check_npz,
    inside,
    read_json,
    unit_factor,
)
from microfab.io.trace import read_columns, read_trace, write_columns

runner = CliRunner()


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _refused(args: list[str], folder: Path, says: str) -> None:
    """``microfab args`` exits 2 on one ``error:`` line naming ``says``; files unchanged."""
    before = _snapshot(folder)
    res = runner.invoke(app, args)
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert res.exit_code == 2, res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.output
    assert says in res.output, res.output
    assert _snapshot(folder) == before


def _huge_h5(path: Path, n: int = 2_000_000_000) -> None:
    """A file of about 1 kB whose datasets declare ``n`` samples (chunks never written)."""
    with h5py.File(path, "w", track_order=True) as f:
        for name in ("time", "input_x", "output_x"):
            f.create_dataset(name, shape=(n,), dtype="f8", chunks=(1024,))


# ------------------------------------------------------------------------- pieces
def test_units_convert_when_known_and_are_refused_when_not() -> None:
    assert unit_factor("mm", "m") == pytest.approx(1e-3, rel=1e-15)
    assert unit_factor("µs", "s") == pytest.approx(1e-6, rel=1e-15)
    assert unit_factor("", "m") == 1.0
    with pytest.raises(SchemaError, match="unknown unit 'parsecs'"):
        unit_factor("parsecs", "m")
    with pytest.raises(SchemaError, match="cannot be read as"):
        unit_factor("ms", "m")


def test_arrays_are_checked_for_kind_shape_finiteness_and_range() -> None:
    ok = check_array("f", "a", np.zeros((4, 2)), shape=(None, 2))
    assert ok.shape == (4, 2)
    with pytest.raises(SchemaError, match="must be an array"):
        check_array("f", "a", 3.0)
    with pytest.raises(SchemaError, match=r"shape \(n, 2\)"):
        check_array("f", "a", np.zeros((4, 3)), shape=(None, 2))
    with pytest.raises(SchemaError, match="nan"):
        check_array("f", "a", np.array([0.0, np.nan]))
    with pytest.raises(SchemaError, match="real number"):
        check_array("f", "a", np.array([True]))
    with pytest.raises(SchemaError, match="lie in"):
        check_array("f", "a", np.array([0.0, 3.0]), high=2.0)


def test_listed_paths_stay_inside_their_folder(tmp_path: Path) -> None:
    assert inside(tmp_path, "a/b.png", "idx") == tmp_path / "a" / "b.png"
    for bad in ("../secret.png", "/etc/passwd", "a/../../x", "", 3):
        with pytest.raises(SchemaError):
            inside(tmp_path, bad, "idx")
    (tmp_path / "out").symlink_to(tmp_path.parent)
    with pytest.raises(SchemaError, match="link that leaves"):
        inside(tmp_path, "out/x.png", "idx")


def test_json_documents_have_a_budget_a_depth_and_a_kind(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(SchemaError, match="nested too deeply"):
        read_json(deep, "a frame index (frames.json)")
    runs = tmp_path / "runs.json"
    runs.write_text(json.dumps({"format": 1, "runs": [], "total_samples": 0}))
    with pytest.raises(SchemaError, match="this is a stage run list"):
        read_json(runs, "a frame index (frames.json)")
    nan = tmp_path / "nan.json"
    nan.write_text('{"a": NaN}')
    with pytest.raises(SchemaError, match="NaN is not a JSON number"):
        read_json(nan, "a frame index (frames.json)")


def test_npz_members_are_budgeted_from_their_headers(tmp_path: Path) -> None:
    path = tmp_path / "big.npz"
    np.savez(path, a=np.zeros(3))
    assert check_npz(path)["a"][0] == (3,)
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (2 * MAX_SAMPLES,)
    import zipfile

    with zipfile.ZipFile(path, "w") as zf, zf.open("a.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\0" * 24)
    with pytest.raises(SchemaError, match="declares 4e\\+07 values"):
        check_npz(path)


# ------------------------------------------------------------------------- traces
def test_a_small_hdf5_file_declaring_2e9_samples_is_refused_before_reading(
    tmp_path: Path,
) -> None:
    # in a child process capped at 4 GB: a regression fails here instead of exhausting
    # the machine's memory (reading the file whole allocates 16 GB)
    path = tmp_path / "huge.h5"
    _huge_h5(path)
    assert path.stat().st_size < 64 * 1024
    code = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30))\n"
        "from microfab.io.trace import read_columns\n"
        "try:\n"
        "    read_columns(sys.argv[1])\n"
        "except ValueError as exc:\n"
        "    print(exc)\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60
    )
    assert "declares 2e+09 samples in column 'time'" in res.stdout, res.stdout + res.stderr


def test_a_mat_variable_is_budgeted_from_its_header(tmp_path: Path, monkeypatch) -> None:
    from scipy.io import savemat

    import microfab.io.trace as trace_mod

    path = tmp_path / "t.mat"
    savemat(path, {"time": np.arange(50.0), "x": np.zeros(50)}, oned_as="column")
    monkeypatch.setattr(trace_mod, "MAX_SAMPLES", 10)
    with pytest.raises(ValueError, match="declares 50 samples in column 'time'"):
        read_columns(path)


def test_declared_units_are_converted_or_refused(tmp_path: Path) -> None:
    csv = tmp_path / "t.csv"
    csv.write_text("# unit: parsecs\ntime,x\n0,1\n1e-4,2\n2e-4,3\n")
    with pytest.raises(ValueError, match="unknown unit 'parsecs'"):
        read_trace(csv)
    h5 = tmp_path / "t.h5"
    with h5py.File(h5, "w", track_order=True) as f:
        f.create_dataset("time", data=np.arange(4) * 0.1).attrs["unit"] = "ms"
        f.create_dataset("x", data=np.array([1.0, 2.0, 3.0, 4.0])).attrs["unit"] = "km"
    tr = read_trace(h5)
    assert tr.unit == "km" and tr.dt == pytest.approx(1e-4, rel=1e-12)
    assert read_trace(h5, to_unit="m").values[1, 0] == pytest.approx(2e3, rel=1e-15)
    with h5py.File(h5, "a") as f:
        f.attrs["unit"] = "m"
    tr = read_trace(h5)
    assert tr.unit == "m" and tr.values[3, 0] == pytest.approx(4e3, rel=1e-15)
    with h5py.File(h5, "a") as f:
        f["x"].attrs["unit"] = "parsecs"
    with pytest.raises(ValueError, match="unit of column 'x'"):
        read_trace(h5)
    with h5py.File(h5, "a") as f:
        f["x"].attrs["unit"] = "V"
    with pytest.raises(ValueError, match="cannot be read as 'm'"):
        read_trace(h5)


def test_a_trace_shorter_than_needed_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    write_columns(path, {"time": np.arange(3) * 1e-4, "x": np.zeros(3)}, unit="m")
    with pytest.raises(ValueError, match="3 samples; this needs at least 100"):
        read_trace(path, min_samples=100)


#: The command's peak RSS is read by a wrapper process that runs it as its only child:
#: ``ru_maxrss`` of RUSAGE_CHILDREN is then that command's, whatever ran before.
_WRAPPER = """
import resource, subprocess, sys
limit = 4 * 2**30  # a regression fails the test instead of taking the machine down
cap = lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
cmd = [sys.executable, "-c", "from microfab.cli import app; app()", *sys.argv[1:]]
res = subprocess.run(cmd, capture_output=True, text=True, preexec_fn=cap)
sys.stderr.write(res.stdout + res.stderr)
print(res.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"""


def _peak_rss(*args: str) -> tuple[int, int, str]:
    """``(exit status, peak RSS in KiB, output)`` of ``microfab args`` in a fresh process."""
    res = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *args],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "COLUMNS": "200"},
    )
    code, kib = (int(v) for v in res.stdout.split())
    return code, kib, res.stderr


def test_identify_chirp_on_a_file_declaring_2e9_samples_stays_under_2_gb(
    tmp_path: Path,
) -> None:
    """The memory acceptance of issue 44: peak RSS of the command <= 2 GB.

    Before, this allocated memory until the machine ran out (11.7 GB in 13 s).
    """
    path = tmp_path / "chirp.h5"
    _huge_h5(path)
    code, kib, out = _peak_rss("identify", "chirp", str(path), "--json", str(tmp_path / "m.json"))
    assert code == 2 and "declares 2e+09 samples" in out, out
    assert not (tmp_path / "m.json").exists()
    assert kib <= 2 * 2**20, f"peak RSS {kib / 2**20:.2f} GiB"


def test_ilc_step_on_a_state_declaring_4e9_values_stays_under_2_gb(tmp_path: Path) -> None:
    """The NPZ equivalent: a 1 kB learning state whose member header declares (2e9, 2)."""
    import zipfile

    (tmp_path / "s").mkdir()
    header = np.lib.format.header_data_from_array_1_0(np.zeros((2, 2)))
    header["shape"] = (2_000_000_000, 2)
    with zipfile.ZipFile(tmp_path / "s" / "ilc_state.npz", "w") as zf:
        with zf.open("reference.npy", "w") as f:
            np.lib.format.write_array_header_1_0(f, header)
            f.write(b"\0" * 32)
        with zf.open("meta.npy", "w") as f:
            np.lib.format.write_array(f, np.array('{"kind": "ILC state", "version": 4}'))
    t = np.arange(64) * 1e-6
    cols = {"time": t, "reference_x": np.sin(t * 1e5), "input_x": np.sin(t * 1e5)}
    write_columns(tmp_path / "t.csv", {**cols, "output_x": np.sin(t * 1e5)})
    args = ("ilc", "step", str(tmp_path / "t.csv"), "--state", str(tmp_path / "s"))
    code, kib, out = _peak_rss(*args, "--out", str(tmp_path / "n.csv"))
    assert code == 2 and "declares 4e+09 values in member 'reference'" in out, out
    assert not (tmp_path / "n.csv").exists()
    assert kib <= 2 * 2**20, f"peak RSS {kib / 2**20:.2f} GiB"
