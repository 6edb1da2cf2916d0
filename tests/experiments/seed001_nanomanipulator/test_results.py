"""Seed numbers beside ours only for the seed's set-up (results.is_seed_setup)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from microfab.experiments.catalog import load_job
from microfab.experiments.seed001_nanomanipulator.results import is_seed_setup
from microfab.machines.nanomanipulator.job import JobConfig, TwinSettings
from microfab.measure.circle_tracking import tracking_metrics
from microfab.report.circle_tracking import tracking_table
from microfab.trajectory.circle_pattern import PatternConfig, pattern_reference

EXAMPLE = Path(__file__).parents[3] / "examples" / "nanomanipulator_msl.toml"


def test_the_example_and_the_default_are_the_seed_setup_and_others_are_not() -> None:
    assert is_seed_setup(load_job(EXAMPLE).config)
    d = JobConfig()
    assert is_seed_setup(d)
    bigger = dataclasses.replace(d, pattern=dataclasses.replace(d.pattern, diameter_mm=0.2))
    assert not is_seed_setup(bigger)
    assert not is_seed_setup(dataclasses.replace(d, twin=TwinSettings(noise=False)))
    assert not is_seed_setup(dataclasses.replace(d, twin=TwinSettings(nonlinear=False)))


def test_tracking_table_off_the_setup_sets_no_seed_number_beside_ours() -> None:
    cfg = PatternConfig(n_circles=1, period_s=0.02, periods=3, pause_s=0.01, move_s=0.01,
                        ramp_s=0.01)  # fmt: skip
    ref = pattern_reference(cfg, 1e-4)
    y = ref.position + np.array([2e-4, -1e-4])
    m = tracking_metrics(
        ref.position, y, np.zeros(ref.n_samples, bool), starts=ref.starts,
        period_samples=ref.period_samples, periods=ref.periods, centres=ref.centres,
        radius=ref.radius_mm,
    )  # fmt: skip
    ours = tracking_table(m, seed=False)
    cells = " ".join(" ".join(r) for r in ours.rows)
    assert "485.8" not in cells and "769.5" not in cells and "/" not in cells
    assert ours.columns == ("quantity", "ours", "ours is")
    assert "485.8" in " ".join(" ".join(r) for r in tracking_table(m).rows)
