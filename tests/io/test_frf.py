from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from microfab.io.frf import FRFFileError, read_frf, write_frf
from microfab.io.trace import write_columns


def test_round_trip_and_interpolation(tmp_path: Path) -> None:
    f = np.array([0.0, 100.0, 200.0])
    h = np.column_stack([[1.0, 1 - 1j, -2j], [0.5, 0.5j, 1.0]])
    write_frf(tmp_path / "g.csv", f, h, ("x", "y"))
    table = read_frf(tmp_path / "g.csv")
    assert table.axes == ("x", "y")
    np.testing.assert_allclose(table.response, h)
    model = table.model(("y", "x"))  # the learner's order
    out = model(np.array([50.0, 150.0, 250.0]))
    np.testing.assert_allclose(out[0], [0.25 + 0.25j, 1 - 0.5j])
    np.testing.assert_allclose(out[1], [0.5 + 0.25j, 0.5 - 1.5j])
    assert np.all(np.isnan(out[2]))  # outside the measured range: no model
    with pytest.raises(FRFFileError, match="no axis 'z'"):
        table.model(("z",))


def test_magnitude_and_phase_columns(tmp_path: Path) -> None:
    p = tmp_path / "m.csv"
    write_columns(
        p,
        {
            "freq_hz": np.array([1.0, 2.0]),
            "mag_x": np.array([2.0, 1.0]),
            "phase_deg_x": np.array([0.0, -90.0]),
        },
    )
    np.testing.assert_allclose(read_frf(p).response[:, 0], [2.0, -1j], atol=1e-15)


@pytest.mark.parametrize(
    ("cols", "match"),
    [
        ({"f": [1.0, 2.0], "re_x": [1.0, 1.0], "im_x": [0.0, 0.0]}, "no 'freq_hz'"),
        ({"freq_hz": [1.0, 2.0], "re_x": [1.0, 1.0]}, "no 'im_x'"),
        ({"freq_hz": [1.0, 2.0], "gain": [1.0, 1.0]}, "no axis columns"),
        ({"freq_hz": [2.0, 1.0], "re_x": [1.0, 1.0], "im_x": [0.0, 0.0]}, "increasing"),
        ({"freq_hz": [1.0, 2.0], "re_x": [1.0, np.nan], "im_x": [0.0, 0.0]}, "NaN/inf"),
        ({"freq_hz": [1.0], "re_x": [1.0], "im_x": [0.0]}, "at least 2"),
        ({"freq_hz": [1.0, 2.0], "mag_x": [-1.0, 1.0], "phase_deg_x": [0.0, 0.0]}, ">= 0"),
    ],
)
def test_bad_files_are_refused(tmp_path: Path, cols: dict, match: str) -> None:
    p = tmp_path / "bad.csv"
    write_columns(p, {k: np.asarray(v, dtype=float) for k, v in cols.items()})
    with pytest.raises(FRFFileError, match=match):
        read_frf(p)
