"""``microfab ilc step`` options: a measured FRF file, the P-type law, per-axis gains."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.io.frf import write_frf
from microfab.io.trace import write_columns
from microfab.machines.galvo.machine import complementary_sensitivity, galvo_twin
from microfab.plants.galvo import default_galvo_axes
from microfab.trajectory.periodic import square_scan

runner = CliRunner()


def _trial(path: Path) -> None:
    ref = square_scan(400, (1.0, 1.44), 1e6)
    y = galvo_twin(seed=3).run(ref).output
    cols = {"time": np.arange(ref.shape[0]) * 1e-6}
    for i, a in enumerate(("x", "y")):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": ref[:, i], f"output_{a}": y[:, i]}
    write_columns(path, cols)


def _step(tmp_path: Path, *extra: str, state: str = "state") -> object:
    args = ["ilc", "step", str(tmp_path / "trial.csv"), "--state", str(tmp_path / state)]
    return runner.invoke(app, [*args, "--out", str(tmp_path / "next.csv"), *extra])


def test_step_from_a_measured_frf(tmp_path: Path) -> None:
    _trial(tmp_path / "trial.csv")
    axes = default_galvo_axes()
    f = np.linspace(0.0, 20e3, 2001)
    h = np.column_stack([complementary_sensitivity(axes[a], f) for a in ("x", "y")])
    write_frf(tmp_path / "frf.csv", f, h, ("x", "y"))
    res = _step(tmp_path, "--frf", str(tmp_path / "frf.csv"))
    assert res.exit_code == 0, res.output
    assert "harmonics x 10, y 10" in res.output
    # a wrong FRF (10x too small) is refused on the first call, naming eq. 5 and the fix
    write_frf(tmp_path / "bad.csv", f, 0.1 * h, ("x", "y"))
    res = _step(tmp_path, "--frf", str(tmp_path / "bad.csv"), state="s2")
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "seed 000 eq. 5" in lines[0], res.output
    assert not (tmp_path / "s2").exists()


def test_step_with_p_type_and_axis_gain(tmp_path: Path) -> None:
    _trial(tmp_path / "trial.csv")
    res = _step(tmp_path, "--law", "p-type", "--axis-gain", "y=0.2", "--cutoff-hz", "2000")
    assert res.exit_code == 0, res.output
    res = _step(tmp_path, "--axis-gain", "y", state="s3")
    assert res.exit_code == 2 and "AXIS=GAIN" in res.output
    res = _step(tmp_path, "--law", "q-type", state="s4")
    assert (
        res.exit_code == 2
        and "error: Invalid value for '--law': 'q-type' is not one of inverse, p-type" in res.output
    )
    res = _step(tmp_path, "--axis-gain", "z=0.1", state="s5")
    assert res.exit_code == 2 and "a gain is given for axis ['z']" in res.output


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--cutoff-hz", "-1"], "'--cutoff-hz': -1 Hz is outside the allowed range [1, 500000] Hz"),
        (["--gain", "5"], "'--gain': 5 is outside the allowed range [1e-06, 2]"),
        (
            ["--max-velocity", "0"],
            "'--max-velocity': 0 (input unit)/s is outside the allowed range (0, 5e+09] "
            "(input unit)/s",
        ),
        (
            ["--advance-us", "-1"],
            "'--advance-us': -1 µs is outside the allowed range [0, 1e+06] µs",
        ),
        (
            ["--axis-gain", "y=3"],
            "--axis-gain y=3: the gain is outside the allowed range [1e-06, 2]",
        ),
    ],
)
def test_option_hints_name_the_option_and_its_unit(
    tmp_path: Path, argv: list[str], says: str
) -> None:
    # issue 13: hints spoke Python names and units ("advance_s ... -1e-06 s" for µs)
    _trial(tmp_path / "trial.csv")
    res = _step(tmp_path, *argv)
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and says in lines[0], res.output
    assert not (tmp_path / "state").exists()
