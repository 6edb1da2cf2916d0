"""Published numbers of seed 002 part 1 (black-box XY stage: linear model and ANNs).

Every value cites its place in ``../shared/seeds/002_1134f04182c173b2.txt``.

Seed points noted here once:

* Table II's two ``a_max`` columns lost their values in the text; Fig. 8 gives them:
  1 and 3 m/s².
* The linear model's training data reach 5 m/s² (§III-D), well below Table I's 40 m/s².
* "Unlike (III-A)" in §III-B means eq. (6), the continuous-time linear model.
* "≈ 34 data points per parameter" (§III-C) is undefined; we count 500 ms windows.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = [
    "ANN_BATCH",
    "ANN_HIDDEN",
    "ANN_HISTORY",
    "ANN_POINTS_PER_WEIGHT",
    "ANN_RANDOM_SHARE",
    "ANN_RATE_HZ",
    "ANN_SIGMA_LIMIT_M",
    "ANN_VALIDATION_SHARE",
    "ANN_WEIGHTS",
    "LINEAR_ORDER",
    "LINEAR_SAMPLES",
    "LINEAR_TRAINING_A_MAX",
    "LOOP_RATE_HZ",
    "REPEATABILITY_M",
    "SLOW_TIME_CONSTANT_S",
    "TABLE_II",
    "TableIIRow",
]

# ---------------------------------------------------------------- Table I
LOOP_RATE_HZ = 10_000.0  # seed 002 Table I: low-level control loop 10 kHz
REPEATABILITY_M = 2e-6  # seed 002 Table I: repeatability (standard deviation) 2 µm
# workspace, speed and acceleration: `microfab.core.limits.MachineLimits.seed002_stage`

# ---------------------------------------------------------------- §III-A, III-B, III-C
LINEAR_ORDER = 4  # seed 002 §III-A: z in R^4; "higher than 4 ... practically the same error"
LINEAR_SAMPLES = 6_000_000  # seed 002 §III-C.1: 6 x 10^6 points of random trajectories
LINEAR_TRAINING_A_MAX = 5.0  # seed 002 §III-D: training data "up to 5 m s^-2"
ANN_RATE_HZ = 400.0  # seed 002 §III-B: discrete time at 400 Hz
ANN_HISTORY = 200  # seed 002 §III-B: the last 500 ms at 400 Hz, 200 inputs
ANN_HIDDEN = (200, 200, 100, 100, 50, 25, 12, 6)  # seed 002 Fig. 5
ANN_WEIGHTS = 117_322  # seed 002 Fig. 5: "total of 117322 weights"
ANN_BATCH = 16_384  # seed 002 §III-C: "batches of 16k segments"
ANN_VALIDATION_SHARE = 0.2  # seed 002 §III-C: 80 % / 20 %
ANN_RANDOM_SHARE = 0.6  # seed 002 §III-C: "about 60 % of the data" random trajectories
ANN_POINTS_PER_WEIGHT = 34.0  # seed 002 §III-C: "≈ 34 data points per parameter"
ANN_SIGMA_LIMIT_M = 20e-6  # seed 002 §III-D: sigma below 20 µm per axis for a <= 3 m/s^2
SLOW_TIME_CONSTANT_S = 0.5 / 25  # seed 002 §III-B reading: 500 ms history / 25 ~ 20 ms


class TableIIRow(NamedTuple):
    """One model and axis of seed 002 Table II: mean and std of the prediction error, m."""

    mu_m: float
    sigma_m: float


#: Seed 002 Table II: ``TABLE_II[model][axis][column]``; columns "training" (linear: its
#: training data; ANN: its validation data), "letters_1" and "letters_3" (the Letters
#: test case after optimisation at a_max = 1 and 3 m/s², Fig. 8).
TABLE_II: dict[str, dict[str, dict[str, TableIIRow]]] = {
    "linear": {
        "x": {
            "training": TableIIRow(3.0e-6, 48.0e-6),  # seed 002 Table II
            "letters_1": TableIIRow(4.7e-6, 30.1e-6),  # seed 002 Table II
            "letters_3": TableIIRow(5.4e-6, 57.2e-6),  # seed 002 Table II
        },
        "y": {
            "training": TableIIRow(-13.2e-6, 156.3e-6),  # seed 002 Table II
            "letters_1": TableIIRow(0.0, 108.5e-6),  # seed 002 Table II
            "letters_3": TableIIRow(0.5e-6, 229.4e-6),  # seed 002 Table II
        },
    },
    "ann": {
        "x": {
            "training": TableIIRow(0.0, 3.2e-6),  # seed 002 Table II (validation data)
            "letters_1": TableIIRow(-0.3e-6, 8.2e-6),  # seed 002 Table II
            "letters_3": TableIIRow(1.0e-6, 11.1e-6),  # seed 002 Table II
        },
        "y": {
            "training": TableIIRow(0.0, 6.0e-6),  # seed 002 Table II (validation data)
            "letters_1": TableIIRow(-2.0e-6, 13.4e-6),  # seed 002 Table II
            "letters_3": TableIIRow(-2.3e-6, 18.7e-6),  # seed 002 Table II
        },
    },
}
