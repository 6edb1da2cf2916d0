"""Job files: typed sections, no silent coercion, one-line refusals."""

from __future__ import annotations

import math

import pytest

from microfab.io.job import JobFileError, Key, parse_job, parse_section, read_job

KEYS = (
    Key(name="n", type="int", default=3, low=1, high=10),
    Key(name="x", type="float", default=0.5, low=0.0, high=1.0, unit="V"),
    Key(name="rates", type="int_list", default=None, low=1, high=100),
    Key(name="label", type="str", default="a"),
    Key(name="on", type="bool", default=False),
    Key(name="new", type="int", default=1, alias="old"),
)


def test_defaults_and_values():
    out = parse_section({"n": 4, "x": 1, "rates": [2, 3], "old": 7}, KEYS, "f.toml", "s")
    assert out == {"n": 4, "x": 1.0, "rates": (2, 3), "label": "a", "on": False, "new": 7}
    assert isinstance(out["x"], float)


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"n": 4.9}, "expected an integer"),
        ({"n": True}, "expected an integer"),
        ({"n": [4]}, "expected an integer"),
        ({"n": 0}, "outside the allowed range [1, 10]"),
        ({"x": math.inf}, "finite"),
        ({"x": math.nan}, "finite"),
        ({"x": True}, "expected a number"),
        ({"x": 1e308}, "outside the allowed range [0, 1] V"),
        ({"rates": []}, "non-empty list"),
        ({"rates": [1, 2.5]}, "expected an integer"),
        ({"label": 3}, "string"),
        ({"on": 1}, "true or false"),
        ({"bogus": 1}, "unknown key(s) ['bogus'] in [s]"),
        ({"old": "x"}, "old = 'x'"),
    ],
)
def test_refusals_name_file_key_and_value(body, needle):
    with pytest.raises(JobFileError) as err:
        parse_section(body, KEYS, "f.toml", "s")
    msg = str(err.value)
    assert needle in msg
    assert msg.startswith("f.toml")
    assert "\n" not in msg


def test_job_header_and_unknown_section(tmp_path):
    p = tmp_path / "j.toml"
    p.write_text('[job]\nkind = "k"\nout = "rep"\n[a]\nn = 2\n[zzz]\n', encoding="utf-8")
    job = read_job(p)
    assert (job.kind, str(job.out), job.name) == ("k", "rep", None)
    parsed = job.parse({"a": KEYS, "zzz": KEYS, "b": KEYS[:1]})
    assert parsed["a"]["n"] == 2
    assert parsed["b"] == {"n": 3}
    with pytest.raises(JobFileError, match=r"unknown section\(s\) \['zzz'\]"):
        job.parse({"a": KEYS})


def test_bad_toml_and_non_table(tmp_path):
    p = tmp_path / "j.toml"
    p.write_text("[job\nkind=", encoding="utf-8")
    with pytest.raises(JobFileError, match="not valid TOML"):
        read_job(p)
    with pytest.raises(JobFileError, match="must be a table"):
        parse_job({"scan": 3}, "x.toml")
