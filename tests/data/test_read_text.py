"""`microfab.data.read_text`: one read per content, a rewritten file read again."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import microfab.data as data


def test_read_once_per_content_and_again_after_a_rewrite(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(data.resources, "files", lambda _: tmp_path)
    monkeypatch.setattr(data, "_CACHE", {})
    f = tmp_path / "twin.toml"
    f.write_text("a = 1\n", encoding="utf-8")
    reads: list[Path] = []
    real = Path.read_text

    def counted(self: Path, *a: object, **k: object) -> str:
        reads.append(self)
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "read_text", counted)
    assert data.read_text("twin.toml") == "a = 1\n"
    assert data.read_text("twin.toml") == "a = 1\n"
    assert len(reads) == 1
    # an atomic rewrite (a new file renamed over the old one) is seen, same size or not
    tmp = tmp_path / "new"
    tmp.write_text("a = 2\n", encoding="utf-8")
    os.replace(tmp, f)
    assert data.read_text("twin.toml") == "a = 2\n"
    assert len(reads) == 2
    with pytest.raises(FileNotFoundError):
        data.read_text("missing.toml")


def test_the_shipped_files_read_through_it() -> None:
    assert "microfab calibrate galvo" in data.read_text("galvo_twin.toml")
