"""Writing a calibration's answer into a sourced twin data file."""

from __future__ import annotations

import tomllib

import pytest

from microfab.calibrate import calibrate
from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.core.provenance import Calibration

from .test_solve import consistent

TWIN = """# a toy twin
[axes.x]
gain = 0.5
gain_source = "assumed: toy"
other = 3.0
other_source = "assumed: kept"

[noise]
level_mm = 1.0e-3
level_mm_source = "assumed: toy"
"""


def test_values_and_sources_name_the_targets_and_checks(tmp_path):
    src = tmp_path / "twin.toml"
    src.write_text(TWIN)
    res = calibrate(consistent(), budget=150, seed=1)
    keys = [TwinKey("x", "axes.x", "gain"), TwinKey("y", "noise", "level_mm", scale=1e-6)]
    out = write_calibrated(
        res, keys, command="microfab calibrate toy", data_file="x.toml", path=src, source=src
    )
    doc = tomllib.loads(out.read_text())
    # values within the fit's tolerance (0.01 on a and b) of the toy's answer x=1, y=2
    assert doc["axes"]["x"]["gain"] == pytest.approx(1.0, abs=0.01)
    assert doc["noise"]["level_mm"] == pytest.approx(2e-6, rel=0.02)
    assert doc["axes"]["x"]["other"] == 3.0 and doc["axes"]["x"]["other_source"] == "assumed: kept"
    text = doc["axes"]["x"]["gain_source"]
    assert text.startswith("calibrated: `microfab calibrate toy`")
    assert "a (" in text and "b (" in text and "checks held back: chk" in text
    assert "every fit target met" in text
    assert out.read_text().startswith("# a toy twin")


def test_an_unknown_key_writes_nothing(tmp_path):
    src = tmp_path / "twin.toml"
    src.write_text(TWIN)
    res = calibrate(consistent(), budget=60, seed=1, polish=False)
    with pytest.raises(ValueError, match="nope"):
        write_calibrated(
            res,
            [TwinKey("x", "axes.x", "nope")],
            command="microfab calibrate toy",
            data_file="x.toml",
            path=src,
            source=src,
        )
    assert src.read_text() == TWIN
    with pytest.raises(ValueError, match="no parameter"):
        write_calibrated(
            res, [TwinKey("z", "axes.x", "gain")], command="c", data_file="x", path=src, source=src
        )


def test_a_number_cannot_be_both_target_and_check():
    with pytest.raises(ValueError, match="both a target and a check"):
        Calibration("microfab calibrate toy", "x.toml", frozenset({"a"}), checks=frozenset({"a"}))
