"""The seed 002 part 1 numbers the library copies (it may not import paper.py) are the seed's."""

from __future__ import annotations

from microfab.experiments.seed002_stage import paper
from microfab.machines.xy_stage import calibration as xy_stage_calibration
from microfab.machines.xy_stage import identify as xy_stage_identify


def test_machine_copies_match_paper():
    assert xy_stage_identify.LINEAR_TOTAL_S == paper.LINEAR_SAMPLES / paper.LOOP_RATE_HZ
    assert xy_stage_identify.LINEAR_A_MAX == paper.LINEAR_TRAINING_A_MAX
    assert xy_stage_identify.LINEAR_ORDER == paper.LINEAR_ORDER
    table = paper.TABLE_II["linear"]
    assert xy_stage_calibration.TARGET_SIGMA_M == (
        table["x"]["training"].sigma_m,
        table["y"]["training"].sigma_m,
    )
