"""The test cases of seed 002 as commands: the sizing step and the time-optimal stand-in."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.core.limits import MachineLimits, check_trajectory
from microfab.machines.xy_stage.cases import (
    AIRFOIL_TIME_S,
    CASES,
    R_TIME_S,
    CaseSizes,
    case_command,
    case_paths,
    case_sizes,
)
from microfab.trajectory.base import Trajectory


@pytest.fixture(scope="module")
def sizes():
    return case_sizes()


def test_sizing_hits_the_two_fitted_times(sizes):
    paths = case_paths(sizes, ("r", "airfoil"))
    assert case_command("r", paths["r"], 1.0).duration_s == pytest.approx(R_TIME_S, rel=2e-4)
    t_air = case_command("airfoil", paths["airfoil"], 1.0).duration_s
    assert t_air == pytest.approx(AIRFOIL_TIME_S, rel=2e-4)
    # a letter of about a centimetre, an airfoil of about 10 cm
    assert 5e-3 < sizes.letter_height_m < 2e-2
    assert 0.05 < sizes.airfoil_chord_m < 0.2


def test_paths_are_centred_and_commands_within_table_i(sizes):
    paths = case_paths(sizes)
    assert tuple(paths) == CASES
    lim = MachineLimits.seed002_stage()
    for name, p in paths.items():
        x0, y0, x1, y1 = p.bbox
        assert abs(x0 + x1) < 1e-9 and abs(y0 + y1) < 1e-9
        cmd = case_command(name, p, 3.0)
        traj = Trajectory(dt=cmd.dt, position=cmd.command)
        check_trajectory(traj, lim)  # raises on a violation
        acc = np.diff(cmd.command, 2, axis=0) / cmd.dt**2
        assert np.abs(acc).max() <= 3.0 * 1.05  # the a_max bound per axis (sampled)
        assert np.allclose(cmd.command[0], p.start, atol=1e-9)


def test_time_shrinks_like_the_square_root_of_the_acceleration(sizes):
    p = case_paths(sizes, ("c",))["c"]
    t1 = case_command("c", p, 1.0).duration_s
    t4 = case_command("c", p, 4.0).duration_s
    assert 0.45 < t4 / t1 < 0.6  # acceleration-bound: 1/2; speed caps it a little higher


def test_refusals():
    with pytest.raises(ValueError, match="unknown case"):
        case_paths(CaseSizes(0.01, 0.1), ("q",))
    p = case_paths(CaseSizes(0.01, 0.1), ("r",))["r"]
    with pytest.raises(ValueError, match="a_max"):
        case_command("r", p, 0.0)
