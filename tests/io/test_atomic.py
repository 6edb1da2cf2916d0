from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from microfab.io import atomic
from microfab.io.atomic import (
    atomic_path,
    atomic_save_npz,
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
)


def _boom(*args, **kwargs):
    raise OSError("simulated failure in os.replace")


def test_write_bytes_creates_parent_and_writes(tmp_path):
    target = tmp_path / "a" / "b" / "out.bin"
    atomic_write_bytes(target, b"\x00\x01hello")
    assert target.read_bytes() == b"\x00\x01hello"
    assert os.listdir(target.parent) == ["out.bin"]


def test_write_bytes_replaces_existing(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old content that is longer")
    atomic_write_bytes(str(target), b"new")
    assert target.read_bytes() == b"new"
    assert os.listdir(tmp_path) == ["out.bin"]


def test_write_bytes_failed_replace_keeps_old_file_and_no_temp(tmp_path, monkeypatch):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    monkeypatch.setattr(atomic.os, "replace", _boom)
    with pytest.raises(OSError, match="simulated failure"):
        atomic_write_bytes(target, b"new")
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["out.bin"]


def test_write_bytes_bad_data_keeps_old_file_and_no_temp(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(TypeError):
        atomic_write_bytes(target, "a str is not bytes")  # type: ignore[arg-type]
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["out.bin"]


def test_failed_write_to_new_target_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(atomic.os, "replace", _boom)
    with pytest.raises(OSError):
        atomic_write_bytes(tmp_path / "new.bin", b"data")
    assert os.listdir(tmp_path) == []


@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_permissions_of_existing_file_are_kept(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    target.chmod(0o640)
    atomic_write_text(target, "new")
    assert stat.S_IMODE(target.stat().st_mode) == 0o640


@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_new_file_gets_umask_permissions_not_mkstemp_0600(tmp_path):
    target = tmp_path / "new.txt"
    atomic_write_text(target, "x")
    assert stat.S_IMODE(target.stat().st_mode) == atomic._NEW_FILE_MODE
    reference = tmp_path / "plain.txt"
    reference.write_text("x")
    assert stat.S_IMODE(target.stat().st_mode) == stat.S_IMODE(reference.stat().st_mode)


def test_write_text_encoding_and_newlines(tmp_path):
    target = tmp_path / "t.txt"
    atomic_write_text(target, "µm\r\nline2\n")
    assert target.read_bytes() == "µm\r\nline2\n".encode()
    atomic_write_text(target, "µm", encoding="latin-1")
    assert target.read_bytes() == b"\xb5m"


def test_write_json_round_trip_keeps_key_order_and_indent(tmp_path):
    target = tmp_path / "r.json"
    obj = {"zeta": 1, "alpha": [1.5, 2.5], "n": np.int64(3), "x": np.array([0.25, 1.0])}
    atomic_write_json(target, obj)
    text = target.read_text()
    assert text.endswith("}\n")
    assert '\n  "zeta": 1,' in text
    loaded = json.loads(text)
    assert list(loaded) == ["zeta", "alpha", "n", "x"]
    assert loaded == {"zeta": 1, "alpha": [1.5, 2.5], "n": 3, "x": [0.25, 1.0]}


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), np.array([1.0, np.nan])])
def test_write_json_rejects_nan_and_keeps_old_file(tmp_path, bad):
    target = tmp_path / "r.json"
    target.write_text('{"old": true}\n')
    with pytest.raises(ValueError, match="NaN"):
        atomic_write_json(target, {"value": bad})
    assert target.read_text() == '{"old": true}\n'
    assert os.listdir(tmp_path) == ["r.json"]


def test_write_json_unserialisable_raises_type_error(tmp_path):
    with pytest.raises(TypeError, match="object"):
        atomic_write_json(tmp_path / "r.json", {"x": object()})
    assert os.listdir(tmp_path) == []


def test_save_npz_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(4, 3)), rng.integers(0, 10, size=7)
    target = tmp_path / "arrays.npz"
    atomic_save_npz(target, a=a, b=b)
    assert os.listdir(tmp_path) == ["arrays.npz"]
    with np.load(target) as data:
        assert sorted(data.files) == ["a", "b"]
        np.testing.assert_array_equal(data["a"], a)
        np.testing.assert_array_equal(data["b"], b)


def test_atomic_path_moves_onto_target(tmp_path):
    target = tmp_path / "sub" / "x.npy"
    with atomic_path(target) as tmp:
        assert tmp.parent == target.parent
        assert tmp.suffix == ".npy"
        assert tmp != target
        assert not target.exists()
        np.save(tmp, np.arange(5.0))
    np.testing.assert_array_equal(np.load(target), np.arange(5.0))
    assert os.listdir(target.parent) == ["x.npy"]


def test_atomic_path_cleans_up_on_exception(tmp_path):
    target = tmp_path / "x.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError, match="library failed"), atomic_path(target) as tmp:
        tmp.write_text("half-written")
        raise RuntimeError("library failed")
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["x.txt"]


def test_atomic_path_cleans_up_when_replace_fails(tmp_path, monkeypatch):
    target = tmp_path / "x.txt"
    target.write_text("old")
    monkeypatch.setattr(atomic.os, "replace", _boom)
    with pytest.raises(OSError, match="simulated failure"), atomic_path(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["x.txt"]


def test_atomic_path_with_savemat(tmp_path):
    sio = pytest.importorskip("scipy.io")
    target = tmp_path / "m.mat"
    with atomic_path(target) as tmp:
        sio.savemat(tmp, {"x": np.arange(3.0)})
    np.testing.assert_array_equal(sio.loadmat(target, squeeze_me=True)["x"], [0.0, 1.0, 2.0])
    assert os.listdir(tmp_path) == ["m.mat"]


def test_atomic_path_with_h5py(tmp_path):
    h5py = pytest.importorskip("h5py")
    target = tmp_path / "d.h5"
    with atomic_path(target) as tmp, h5py.File(tmp, "w") as f:
        f["x"] = np.arange(4.0)
    with h5py.File(target, "r") as f:
        np.testing.assert_array_equal(f["x"][()], np.arange(4.0))
    assert os.listdir(tmp_path) == ["d.h5"]
