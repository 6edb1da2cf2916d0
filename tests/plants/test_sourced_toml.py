"""The sourced parameter files: `update_sourced` rewrites values and sources in place."""

from __future__ import annotations

import tomllib
from importlib import resources

import pytest

from microfab.plants.lmw_stage_params import load_params
from microfab.plants.sourced_toml import read_sourced, toml_value, update_sourced

TEXT = """# A twin's data file: a comment above everything.
# Units SI.

[sampling]
sample_rate_hz = 10000.0  # a comment after a value, kept
sample_rate_hz_source = "assumed: 10 kHz"

[axes.x]
# the x axis
mass_kg = 1.5
mass_kg_source = "assumed: x # not a comment"
tags = ["a", "b#c"]   # trailing
tags_source = "assumed"

[axes.y]
mass_kg = 0.5
mass_kg_source = "assumed: y"
tags = ["d"]
tags_source = "assumed"
"""


@pytest.fixture
def twin_file(tmp_path):
    p = tmp_path / "twin.toml"
    p.write_text(TEXT, encoding="utf-8")
    return p


def test_round_trip_keeps_every_other_line(twin_file):
    out = update_sourced(
        twin_file,
        "unused.toml",
        {
            ("axes.x", "mass_kg"): (1.75, "calibrated: fitted"),
            ("sampling", "sample_rate_hz"): (2.0e4, 'assumed: "20 kHz"'),
            ("axes.y", "tags"): (("e", "f"), "assumed: two"),
        },
    )
    old, new = TEXT.splitlines(), out.splitlines()
    assert len(old) == len(new)
    changed = [(a, b) for a, b in zip(old, new, strict=True) if a != b]
    assert changed == [
        ("sample_rate_hz = 10000.0  # a comment after a value, kept",
         "sample_rate_hz = 20000.0  # a comment after a value, kept"),
        ('sample_rate_hz_source = "assumed: 10 kHz"',
         'sample_rate_hz_source = "assumed: \\"20 kHz\\""'),
        ("mass_kg = 1.5", "mass_kg = 1.75"),
        ('mass_kg_source = "assumed: x # not a comment"',
         'mass_kg_source = "calibrated: fitted"'),
        ('tags = ["d"]', 'tags = ["e", "f"]'),
        ('tags_source = "assumed"', 'tags_source = "assumed: two"'),
    ]  # fmt: skip
    data = read_sourced(
        _write(twin_file, out),
        "unused.toml",
        {"sampling": ("sample_rate_hz",)},
        ("mass_kg", "tags"),
    )
    assert data == {
        "sample_rate_hz": 2.0e4,
        "mass_kg": (1.75, 0.5),
        "tags": (("a", "b#c"), ("e", "f")),
    }


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def test_crlf_endings_and_the_last_line_are_kept(tmp_path):
    p = tmp_path / "crlf.toml"
    p.write_bytes(b'[s]\r\nk = 1.0\r\nk_source = "a"')
    out = update_sourced(p, "unused.toml", {("s", "k"): (2.5, "b")})
    assert out == '[s]\r\nk = 2.5\r\nk_source = "b"'


@pytest.mark.parametrize(
    ("updates", "match"),
    [
        ({("axes.z", "mass_kg"): (1.0, "s")}, r"unknown section \[axes\.z\].*known: axes\.x"),
        ({("axes.x", "inertia"): (1.0, "s")}, r"unknown key 'inertia': \[axes\.x\] must hold"),
        ({("axes.x", "mass_kg_source"): ("x", "s")}, "unknown key 'mass_kg_source'"),
        ({("axes.x", "mass_kg"): (1.0, "")}, r"\[axes\.x\]: mass_kg_source must be a non-empty"),
        ({("axes.x", "mass_kg"): (1.0, "a\nb")}, "single-line"),
        ({("axes.x", "mass_kg"): (float("inf"), "s")}, r"\[axes\.x\]: mass_kg: .*finite"),
        ({("axes.x", "mass_kg"): (None, "s")}, "must be a bool, int, float, string or list"),
    ],
)
def test_unknown_sections_keys_and_bad_values_are_refused(twin_file, updates, match):
    with pytest.raises(ValueError, match=match):
        update_sourced(twin_file, "unused.toml", updates)


def test_a_key_without_its_source_is_refused(tmp_path):
    p = _write(tmp_path / "t.toml", '[s]\nk = 1.0\nj = 2.0\nj_source = "a"\n')
    with pytest.raises(ValueError, match=r"\[s\] must hold k and k_source once"):
        update_sourced(p, "unused.toml", {("s", "k"): (2.0, "b")})


def test_a_value_over_several_lines_is_refused(tmp_path):
    p = _write(tmp_path / "t.toml", '[s]\nk = [\n  1.0,\n  2.0,\n]\nk_source = "a"\n')
    with pytest.raises(ValueError, match=r"the updated file is not valid TOML"):
        update_sourced(p, "unused.toml", {("s", "k"): (3.0, "b")})


def test_the_packaged_file_is_the_default():
    text = resources.files("microfab.data").joinpath("lmw_stage.toml").read_text()
    out = update_sourced(
        None, "lmw_stage.toml", {("disturbance", "disturbance_scale"): (2.0, "assumed: test")}
    )
    assert out.count("\n") == text.count("\n")
    assert tomllib.loads(out)["disturbance"]["disturbance_scale"] == 2.0
    assert [ln for ln in out.splitlines() if ln.startswith("#")] == [
        ln for ln in text.splitlines() if ln.startswith("#")
    ]


def test_written_file_loads_as_a_twin(tmp_path):
    out = update_sourced(None, "lmw_stage.toml", {("axes.y", "coulomb_n"): (0.12, "assumed: t")})
    p = _write(tmp_path / "twin.toml", out)
    assert load_params(p).coulomb_n == (0.15, 0.12)


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (True, "true"),
        (3, "3"),
        (24.0, "24.0"),
        (0.15, "0.15"),
        (3.2323e-4, "3.2323e-4"),
        (4e7, "4e7"),
        (-1.25e-9, "-1.25e-9"),
        (0.0, "0.0"),
        ('µm "q"', '"µm \\"q\\""'),
        ((1.0, 2), "[1.0, 2]"),
    ],
)
def test_toml_values_read_back(value, text):
    assert toml_value(value) == text
    back = tomllib.loads(f"v = {text}")["v"]
    assert back == (list(value) if isinstance(value, tuple) else value)
