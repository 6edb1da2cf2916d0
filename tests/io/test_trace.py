from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from microfab.core import signals
from microfab.io import atomic
from microfab.io.trace import Trace, read_columns, read_trace, write_columns, write_trace

SUFFIXES = [".csv", ".mat", ".h5", ".hdf5"]


def _needs(suffix: str) -> None:
    if suffix in (".h5", ".hdf5"):
        pytest.importorskip("h5py")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def trace(rng):
    # Axis order deliberately not alphabetical, values with full float64 mantissas.
    values = rng.normal(scale=1e-3, size=(257, 3)) * np.array([1.0, 1e-9, 1e6])
    return Trace(dt=2.5e-5, values=values, axes=("z", "x", "b_2"), unit="m", t0=0.125)


def test_trace_is_re_exported_from_core():
    assert Trace is signals.Trace


# --- file round trips ------------------------------------------------------------------


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_round_trip_exact(tmp_path, trace, suffix):
    _needs(suffix)
    path = tmp_path / f"trace{suffix}"
    write_trace(trace, path)
    back = read_trace(path)
    assert back.axes == ("z", "x", "b_2")
    assert back.unit == "m"
    assert back.t0 == trace.t0
    assert back.dt == trace.dt
    np.testing.assert_array_equal(back.values, trace.values)  # bit-exact float64
    np.testing.assert_array_equal(back.time, trace.time)
    assert back == trace
    assert os.listdir(tmp_path) == [path.name]


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_str_path_and_unit_override(tmp_path, trace, suffix):
    _needs(suffix)
    path = tmp_path / f"t{suffix}"
    write_trace(trace, str(path))
    assert read_trace(str(path)) == trace
    assert read_trace(path, unit="mm").unit == "mm"


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_round_trip_without_unit_and_single_sample_columns(tmp_path, suffix):
    _needs(suffix)
    path = tmp_path / f"c{suffix}"
    write_columns(path, {"time": [0.5], "only": [1.0 / 3.0]})
    cols = read_columns(path)
    assert list(cols) == ["time", "only"]
    assert cols["only"].shape == (1,)
    assert cols["only"][0] == 1.0 / 3.0


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_read_columns_raw_names(tmp_path, rng, suffix):
    _needs(suffix)
    names = ["time", "reference_x", "input_x", "output_x", "error_y"]
    columns = {name: rng.normal(size=20) for name in names}
    path = tmp_path / f"raw{suffix}"
    write_columns(path, columns, unit="um")
    back = read_columns(path)
    assert list(back) == names  # unit is metadata, not a column
    for name in names:
        assert back[name].dtype == np.float64
        np.testing.assert_array_equal(back[name], columns[name])


def test_csv_layout(tmp_path):
    t = Trace(dt=0.5, values=[[0.1, -2.0], [1 / 3, -2.5e-7]], axes=("y", "x"), unit="V")
    path = tmp_path / "t.csv"
    write_trace(t, path)
    lines = path.read_text().splitlines()
    assert lines[0] == "# unit: V"
    assert lines[1] == "time,y,x"
    assert lines[2] == "0,0.10000000000000001,-2"
    assert lines[3] == "0.5,0.33333333333333331,-2.4999999999999999e-07"


def test_csv_written_by_hand(tmp_path):
    path = tmp_path / "hand.csv"
    path.write_text("# recorded on rig 2\n#unit:mm\n\ntime, a ,b\n0,1,2\n\n1e-3,3,4 # note\n")
    t = read_trace(path)
    assert t.axes == ("a", "b")
    assert t.unit == "mm"
    assert t.dt == 1e-3
    np.testing.assert_array_equal(t.values, [[1.0, 2.0], [3.0, 4.0]])


def test_mat_file_from_scipy_with_extra_metadata(tmp_path):
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "ext.mat"
    sio.savemat(path, {"time": np.arange(4) * 0.25, "q": np.arange(4.0) ** 2, "unit": "rad"})
    t = read_trace(path)
    assert t.axes == ("q",)
    assert t.unit == "rad"
    assert t.dt == 0.25
    np.testing.assert_array_equal(t["q"], [0.0, 1.0, 4.0, 9.0])


def test_h5_file_without_track_order_is_read(tmp_path):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "ext.h5"
    with h5py.File(path, "w") as f:
        f["time"] = np.arange(3.0)
        f["y"] = np.ones(3)
        f["a"] = np.zeros(3)
        f.create_group("meta")
    cols = read_columns(path)
    assert set(cols) == {"time", "y", "a"}
    assert read_trace(path).unit == ""


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_writers_are_atomic(tmp_path, trace, monkeypatch, suffix):
    _needs(suffix)
    path = tmp_path / f"old{suffix}"
    path.write_bytes(b"previous result")
    monkeypatch.setattr(atomic.os, "replace", _boom)
    with pytest.raises(OSError, match="simulated"):
        write_trace(trace, path)
    assert path.read_bytes() == b"previous result"
    assert os.listdir(tmp_path) == [path.name]


def _boom(*args, **kwargs):
    raise OSError("simulated failure in os.replace")


# --- errors ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["t.txt", "t.npz", "t"])
def test_unknown_suffix(tmp_path, trace, name):
    path = tmp_path / name
    path.write_text("time,x\n0,1\n")
    for call in (
        lambda: read_trace(path),
        lambda: read_columns(path),
        lambda: write_trace(trace, path),
    ):
        with pytest.raises(ValueError, match=r"unsupported.*suffix.*\.csv, \.mat, \.h5, \.hdf5"):
            call()


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_missing_file(tmp_path, suffix):
    _needs(suffix)
    path = tmp_path / f"missing{suffix}"
    with pytest.raises(FileNotFoundError, match="missing"):
        read_trace(path)
    with pytest.raises(FileNotFoundError, match=str(path).replace("\\", "\\\\")):
        read_columns(path)


def test_ragged_csv_names_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x,y\n0,1,2\n1,3\n2,5,6\n")
    with pytest.raises(ValueError, match=r"bad\.csv, line 3: expected 3 fields, got 2"):
        read_columns(path)


def test_non_numeric_csv_names_line_and_column(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("# unit: m\ntime,x,y\n0,1,2\n1,3,4\n2,oops,6\n")
    with pytest.raises(ValueError, match=r"bad\.csv, line 5, column 'x': not a number: 'oops'"):
        read_trace(path)


def test_csv_without_header_or_duplicate_names(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("# unit: m\n\n")
    with pytest.raises(ValueError, match="no header"):
        read_columns(empty)
    dup = tmp_path / "dup.csv"
    dup.write_text("time,x,x\n0,1,2\n")
    with pytest.raises(ValueError, match="line 1: empty or duplicate"):
        read_columns(dup)


def test_read_trace_needs_time_column(tmp_path):
    path = tmp_path / "notime.csv"
    path.write_text("t,x\n0,1\n1,2\n")
    with pytest.raises(
        ValueError, match=r"notime\.csv: no 'time' column; columns are \['t', 'x'\]"
    ):
        read_trace(path)


def test_read_trace_non_uniform_names_file(tmp_path):
    path = tmp_path / "jitter.csv"
    path.write_text("time,x\n0,1\n1,2\n2.5,3\n3,4\n")
    with pytest.raises(ValueError, match=r"jitter\.csv: time must be uniformly sampled"):
        read_trace(path)


def test_read_trace_nan_names_file_axis_and_sample(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("time,x,y\n0,1,2\n1,nan,4\n2,5,6\n")
    with pytest.raises(ValueError, match=r"nan\.csv: values of axis 'x' .* at sample 1"):
        read_trace(path)


def test_write_columns_validation(tmp_path):
    with pytest.raises(ValueError, match="equal length"):
        write_columns(tmp_path / "a.csv", {"time": np.arange(3.0), "x": np.arange(4.0)})
    with pytest.raises(ValueError, match="equal length"):
        write_columns(tmp_path / "a.csv", {"time": np.zeros((3, 2))})
    with pytest.raises(ValueError, match="'bad name'"):
        write_columns(tmp_path / "a.csv", {"bad name": np.arange(3.0)})
    with pytest.raises(ValueError, match="clashes"):
        write_columns(tmp_path / "a.mat", {"unit": np.arange(3.0)}, unit="m")
    assert os.listdir(tmp_path) == []


def test_malformed_mat_and_h5(tmp_path):
    bad_mat = tmp_path / "bad.mat"
    bad_mat.write_bytes(b"this is not a MAT file at all" * 10)
    with pytest.raises(ValueError, match=r"bad\.mat"):
        read_columns(bad_mat)
    pytest.importorskip("h5py")
    bad_h5 = tmp_path / "bad.h5"
    bad_h5.write_bytes(b"not hdf5")
    with pytest.raises(ValueError, match=r"bad\.h5: not an HDF5 file"):
        read_columns(bad_h5)


def test_mat_matrix_variable_is_rejected(tmp_path):
    sio = pytest.importorskip("scipy.io")
    path = tmp_path / "m.mat"
    sio.savemat(path, {"time": np.arange(3.0), "M": np.ones((3, 2))})
    with pytest.raises(ValueError, match=r"'M' is not a numeric 1-D column"):
        read_columns(path)


def test_missing_h5py_message(tmp_path, trace, monkeypatch):
    monkeypatch.setitem(sys.modules, "h5py", None)  # makes `import h5py` raise ImportError
    with pytest.raises(
        ImportError, match=r"HDF5 support needs h5py: pip install 'microfab\[hdf5\]'"
    ):
        write_trace(trace, tmp_path / "t.h5")
    assert os.listdir(tmp_path) == []


def test_cut_mat_files_are_read_or_refused_as_value_error(tmp_path):
    # scipy raised IndexError, TypeError or OSError ("could not read bytes") on cut files
    path = tmp_path / "t.mat"
    write_columns(path, {"time": np.arange(10.0), "x": np.ones(10)})
    data = path.read_bytes()
    cut = tmp_path / "cut.mat"
    refused = 0
    for k in range(0, len(data) - 1, 3):
        cut.write_bytes(data[:k])
        try:
            cols = read_columns(cut)
        except ValueError as exc:
            assert str(exc).startswith(f"{cut}: not a readable MAT file")
            refused += 1
        else:  # cut after a whole variable
            assert set(cols) <= {"time", "x"}
    assert refused > 100


def test_damaged_h5_files_are_read_or_refused_as_value_error(tmp_path):
    # h5py raised RuntimeError, TypeError or KeyError on damaged files
    pytest.importorskip("h5py")
    path = tmp_path / "t.h5"
    write_columns(path, {"time": np.arange(10.0), "x": np.ones(10)})
    data = path.read_bytes()
    bad = tmp_path / "bad.h5"
    for k in range(0, len(data), 5):
        damaged = bytearray(data)
        damaged[k] ^= 0xFF
        bad.write_bytes(bytes(damaged))
        try:
            cols = read_columns(bad)
        except ValueError as exc:
            assert "bad.h5" in str(exc)
        else:
            assert set(cols) <= {"time", "x"}
