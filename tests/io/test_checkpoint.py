"""State files of the run store: round trip, and every way a saved state is refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.io.checkpoint import StateFileError, read_state, save_state
from microfab.io.runstore import RunRefusedError

KIND = "test state"


def _save(path: Path, **settings_: object) -> Path:
    return save_state(
        path,
        kind=KIND,
        version=3,
        arrays={"x": np.arange(6.0).reshape(3, 2), "flag": np.array([True, False])},
        meta={"iteration": 7, "note": "ok"},
        settings=settings_ or {"gain": 0.4, "file": Path("a/b.csv")},
    )


def test_round_trip(tmp_path: Path) -> None:
    path = _save(tmp_path / "sub" / "s.npz")
    got = read_state(path, kind=KIND, versions=(3,), settings={"gain": 0.4, "file": "a/b.csv"})
    assert got is not None
    assert got.version == 3 and got.meta == {"iteration": 7, "note": "ok"}
    np.testing.assert_array_equal(got.arrays["x"], np.arange(6.0).reshape(3, 2))
    assert got.arrays["flag"].dtype == bool


def test_absent_is_none(tmp_path: Path) -> None:
    assert read_state(tmp_path / "none.npz", kind=KIND, versions=(3,)) is None


def test_other_settings_name_the_first_difference(tmp_path: Path) -> None:
    path = _save(tmp_path / "s.npz")
    before = path.read_bytes()
    with pytest.raises(RunRefusedError, match=r"gain 0\.4 -> 0\.2; remove it"):
        read_state(path, kind=KIND, versions=(3,), settings={"gain": 0.2, "file": "a/b.csv"})
    assert path.read_bytes() == before


def test_other_version_and_kind_refused(tmp_path: Path) -> None:
    path = _save(tmp_path / "s.npz")
    with pytest.raises(RunRefusedError, match="format 3; this microfab reads format 4"):
        read_state(path, kind=KIND, versions=(4,))
    with pytest.raises(RunRefusedError, match="a test state file where a network"):
        read_state(path, kind="network", versions=(3,))


def test_empty_folder_and_foreign_files(tmp_path: Path) -> None:
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(StateFileError, match=r"is empty.*start again"):
        read_state(empty, kind=KIND, versions=(3,))
    folder = tmp_path / "dir.npz"
    folder.mkdir()
    with pytest.raises(StateFileError, match="found a folder"):
        read_state(folder, kind=KIND, versions=(3,))
    text = tmp_path / "text.npz"
    text.write_text("not an archive")
    with pytest.raises(StateFileError, match="not a readable test state"):
        read_state(text, kind=KIND, versions=(3,))
    other = tmp_path / "other.npz"
    np.savez(other, x=np.zeros(3))  # an archive, but no metadata
    with pytest.raises(StateFileError, match="no 'meta' member"):
        read_state(other, kind=KIND, versions=(3,), fix="rerun with --fresh")


@settings(max_examples=40, deadline=None)
@given(cut=st.floats(0.0, 0.999), flip=st.booleans())
def test_cut_or_damaged_file_refused_never_partial(
    tmp_path_factory, cut: float, flip: bool
) -> None:
    folder = tmp_path_factory.mktemp("cut")
    path = _save(folder / "s.npz")
    data = bytearray(path.read_bytes())
    if flip:  # one byte damaged somewhere in the archive
        i = int(cut * len(data))
        data[i] ^= 0xFF
    else:  # cut short
        data = data[: max(1, int(cut * len(data)))]
    path.write_bytes(bytes(data))
    try:
        got = read_state(path, kind=KIND, versions=(3,), settings={"gain": 0.4, "file": "a/b.csv"})
    except (StateFileError, RunRefusedError) as exc:
        assert str(path) in str(exc)
    else:  # a flipped byte the archive does not check (e.g. a timestamp): the state is whole
        assert got is not None and got.arrays["x"].shape == (3, 2)


def test_legacy_file_without_kind_and_byte_metadata(tmp_path: Path) -> None:
    path = tmp_path / "old.npz"
    blob = np.frombuffer(json.dumps({"version": 2, "epoch": 5}).encode(), dtype=np.uint8)
    np.savez(path, meta=blob, w=np.ones(2))
    got = read_state(path, kind=KIND, versions=(2,))
    assert got is not None and got.meta == {"epoch": 5}


def test_reserved_names_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="may not be named"):
        save_state(tmp_path / "s.npz", kind=KIND, version=1, arrays={"meta": np.zeros(1)})
    with pytest.raises(ValueError, match="may not use the names"):
        save_state(tmp_path / "s.npz", kind=KIND, version=1, arrays={}, meta={"version": 2})
    assert not (tmp_path / "s.npz").exists()


@pytest.mark.parametrize("offset, value", [(10, 0x63), (8, 0x01)], ids=["method", "encrypted"])
def test_a_member_entry_naming_an_unknown_method_or_encryption_is_refused(
    tmp_path: Path, offset: int, value: int
) -> None:
    """Bytes of the first central-directory entry: 10-11 the compression method (99: AES,
    which zipfile lacks: NotImplementedError), 8-9 the flags (bit 0, encrypted:
    RuntimeError 'password required')."""
    path = _save(tmp_path / "s.npz")
    data = bytearray(path.read_bytes())
    entry = data.index(b"PK\x01\x02")
    data[entry + offset] = value
    path.write_bytes(bytes(data))
    with pytest.raises(StateFileError, match=str(path.name)):
        read_state(path, kind=KIND, versions=(3,), settings={"gain": 0.4, "file": "a/b.csv"})


def test_every_single_flipped_byte_is_refused_or_loads_the_whole_state(tmp_path: Path) -> None:
    """Exhaustive over the archive's bytes. A member's name and its directory fields are
    covered by no checksum: a flipped byte there loaded a state without its 'x' (found by
    the property test above); the saved member list refuses it."""
    path = _save(tmp_path / "s.npz")
    whole = path.read_bytes()
    for i in range(len(whole)):
        data = bytearray(whole)
        data[i] ^= 0xFF
        path.write_bytes(bytes(data))
        try:
            got = read_state(
                path, kind=KIND, versions=(3,), settings={"gain": 0.4, "file": "a/b.csv"}
            )
        except (StateFileError, RunRefusedError):
            continue
        assert got is not None and sorted(got.arrays) == ["flag", "x"], i
        assert got.arrays["x"].shape == (3, 2), i
