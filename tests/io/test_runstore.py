"""The run store: resume on the same settings, refuse others, --fresh moves only its own files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from microfab.io.atomic import atomic_save_npz, atomic_write_json, atomic_write_text
from microfab.io.runstore import (
    MANIFEST,
    PREVIOUS,
    RunRefusedError,
    check_run,
    content_digest,
    open_run,
    settings_difference,
)

SETTINGS = {"kind": "k", "scan.rate": 400, "ilc.gain": 0.4, "rates": (100, 400)}


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_a_new_run_records_its_files_and_a_rerun_resumes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with open_run(out, SETTINGS) as run:
        assert not run.resumed
        atomic_write_json(out / "summary.json", {"x": 1})
        atomic_save_npz(out / "state" / "a.npz", x=[1.0])
        atomic_write_text(tmp_path / "elsewhere.txt", "not ours")
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["files"] == ["summary.json", "state/a.npz"]
    assert manifest["settings"]["rates"] == [100, 400]
    with open_run(out, dict(SETTINGS)) as again:
        assert again.resumed and again.files == ["summary.json", "state/a.npz"]
    assert check_run(out, SETTINGS) == "resume"


def test_other_settings_are_refused_naming_the_first_difference(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with open_run(out, SETTINGS):
        atomic_write_json(out / "summary.json", {"x": 1})
    before = _tree(out)
    changed = {**SETTINGS, "ilc.gain": 0.2, "scan.rate": 200}
    with pytest.raises(RunRefusedError) as err:
        with open_run(out, changed):
            raise AssertionError("must not run")
    msg = str(err.value)
    assert "scan.rate 400 -> 200 (and 1 more)" in msg and "--fresh" in msg
    assert "\n" not in msg
    assert _tree(out) == before  # a refusal changes nothing
    with pytest.raises(RunRefusedError, match=r"scan\.rate"):
        check_run(out, changed)


def test_a_new_or_removed_setting_is_a_difference() -> None:
    assert settings_difference({"a": 1}, {"a": 1, "b": 2}) == ["b (absent) -> 2"]
    assert settings_difference({"a": 1, "b": 2}, {"a": 1}) == ["b 2 -> (absent)"]
    assert settings_difference({"a": 1.0}, {"a": 1}) == []  # JSON: equal numbers
    digest = "sha256:" + "ab" * 32
    other = "sha256:" + "cd" * 32
    assert settings_difference({"f": digest}, {"f": other}) == [
        "f content abababab -> content cdcdcdcd"
    ]


def test_fresh_moves_only_the_files_the_run_wrote(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with open_run(out, SETTINGS):
        atomic_write_json(out / "summary.json", {"x": 1})
        atomic_save_npz(out / "state" / "a.npz", x=[1.0])
    (out / "notes.txt").write_text("the user's own file")
    with open_run(out, {**SETTINGS, "ilc.gain": 0.2}, fresh=True) as run:
        assert not run.resumed and run.moved_to is not None
        assert not (out / "summary.json").exists() and not (out / "state").exists()
        atomic_write_json(out / "summary.json", {"x": 2})
    assert (out / "notes.txt").read_text() == "the user's own file"
    moved = run.moved_to
    assert moved.parent == out / PREVIOUS
    assert json.loads((moved / "summary.json").read_text()) == {"x": 1}
    assert (moved / "state" / "a.npz").is_file() and (moved / MANIFEST).is_file()
    assert json.loads((out / MANIFEST).read_text())["files"] == ["summary.json"]
    # the same settings with --fresh start clean too
    with open_run(out, {**SETTINGS, "ilc.gain": 0.2}, fresh=True) as run2:
        assert run2.moved_to is not None and run2.moved_to != moved


def test_a_folder_no_run_wrote_is_refused_even_with_fresh(tmp_path: Path) -> None:
    out = tmp_path / "data"
    out.mkdir()
    (out / "trial.csv").write_text("t,x\n0,1\n")
    for fresh in (False, True):
        with pytest.raises(RunRefusedError, match=r"holds no run\.json"):
            with open_run(out, SETTINGS, fresh=fresh):
                pass
    assert (out / "trial.csv").read_text() == "t,x\n0,1\n"
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / ".hidden").write_text("")
    assert check_run(tmp_path / "empty", SETTINGS) == "start"


def test_a_file_or_a_broken_manifest_is_refused(tmp_path: Path) -> None:
    f = tmp_path / "job.toml"
    f.write_text("[job]\n")
    with pytest.raises(RunRefusedError, match="is a file, not an output folder"):
        check_run(f, SETTINGS)
    assert f.read_text() == "[job]\n"
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / MANIFEST).write_text("{not json")
    with pytest.raises(RunRefusedError, match="not a readable run manifest"):
        check_run(bad, SETTINGS)
    (bad / MANIFEST).write_text("[1, 2]")
    with pytest.raises(RunRefusedError, match="not a run manifest"):
        check_run(bad, SETTINGS)


def test_nothing_is_written_until_the_run_writes(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with pytest.raises(ValueError, match="refused later"):
        with open_run(out, SETTINGS):
            raise ValueError("refused later")
    assert not out.exists()


def test_an_interrupted_run_keeps_what_it_recorded(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        with open_run(out, SETTINGS):
            atomic_write_json(out / "state" / "1.json", {"i": 1})
            raise KeyboardInterrupt
    with open_run(out, SETTINGS) as again:
        assert again.resumed and again.files == ["state/1.json"]


def test_content_digest_of_files_and_folders(tmp_path: Path) -> None:
    d = tmp_path / "models"
    (d / "ann").mkdir(parents=True)
    (d / "a.json").write_text("1")
    (d / "ann" / "w.bin").write_bytes(b"\0\1")
    first = content_digest(d)
    (d / ".a.json.tmp").write_text("a temporary file is not content")
    assert content_digest(d) == first
    (d / "ann" / "w.bin").write_bytes(b"\0\2")
    assert content_digest(d) != first
    assert content_digest(d / "a.json") != content_digest(d / "ann" / "w.bin")
    with pytest.raises(FileNotFoundError):
        content_digest(tmp_path / "nothing")


_values = st.one_of(
    st.integers(), st.floats(allow_nan=False, allow_infinity=False), st.text(), st.booleans(),
    st.none(), st.lists(st.integers(), max_size=3),
)  # fmt: skip


@given(st.dictionaries(st.text(min_size=1), _values), st.dictionaries(st.text(min_size=1), _values))
def test_settings_differ_exactly_when_they_are_not_equal(a: dict, b: dict) -> None:
    diff = settings_difference(a, b)
    assert (diff == []) == (a == b)
    gone = object()
    assert len(diff) == len([k for k in {*a, *b} if a.get(k, gone) != b.get(k, gone)])


def test_floats_shown_short_unless_only_their_last_digits_differ() -> None:
    diff = settings_difference({"h": 100 * 1e-6, "t": 0.1 + 0.2}, {"h": 120 * 1e-6, "t": 0.3})
    assert diff == ["h 0.0001 -> 0.00012", "t 0.30000000000000004 -> 0.3"]
