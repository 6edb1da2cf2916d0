"""The keys of the ``nanomanipulator-msl`` job that ``microfab rc step`` shares.

A light module (it imports `microfab.io.job` only), so that the command line declares its
options with these keys without importing the job: ``rc step --tau-ms``, ``--gain``,
``--lead-samples`` and ``--period-s`` set what ``[rc] tau_ms``, ``gain``, ``lead_samples``
and ``[pattern] period_s`` set, with the same unit and range.
"""

from __future__ import annotations

import math

from microfab.io.job import Key

__all__ = [
    "PATTERN_DIAMETER_MM",
    "PATTERN_FIELD_MM",
    "PATTERN_KEYS",
    "PATTERN_MOVE_S",
    "PATTERN_N_CIRCLES",
    "PATTERN_PAUSE_S",
    "PATTERN_PERIODS",
    "PATTERN_PERIOD_S",
    "PATTERN_RAMP_S",
    "RC_GAIN",
    "RC_LEAD_SAMPLES",
    "RC_TAU_MS",
]

#: Longest period, s (assumed: one loop of a circle a minute is already far slower than
#: any contour the seed 001 machine writes; its set-up gives no speed).
MAX_PERIOD_S = 60.0

#: Time per loop of the contour (assumed 1 s: seed 001 gives no speed).
PATTERN_PERIOD_S = Key(
    name="period_s",
    type="float",
    default=1.0,
    low=0.0,
    low_open=True,
    high=MAX_PERIOD_S,
    unit="s",
    help="time per loop (assumed 1 s; a whole number of samples)",
)
#: Q(s) = 1/(τs + 1). Upper bound assumed: Q must pass at least the fundamental of the
#: longest period, 1/(2πτ) >= 1/MAX_PERIOD_S, so τ <= 60/(2π) s = 9.5 s, rounded up to 1e4 ms.
RC_TAU_MS = Key(
    name="tau_ms",
    type="float",
    default=1e3 / (2 * math.pi * 100.0),
    low=0.0,
    low_open=True,
    high=1e4,
    unit="ms",
    help="Q(s) = 1/(τs + 1) time constant (default a 100 Hz cutoff)",
)
#: Learning gain k_r (seed 001 §3.3 gives none; the RC update converges for 0 < k_r <= 2).
RC_GAIN = Key(
    name="gain",
    type="float",
    default=1.0,
    low=0.0,
    low_open=True,
    high=2.0,
    help="learning gain (0, 2]",
)
#: Phase lead in samples (below the period's samples, checked against the trial).
RC_LEAD_SAMPLES = Key(
    name="lead_samples", type="int", default=20, low=0, unit="samples", help="phase lead"
)

# ------------------------------------------------- [pattern], shared by nanomanipulator analyze
# `nanomanipulator analyze --circles`, `--diameter-mm`, `--field-mm`, `--period`,
# `--periods`, `--pause-s`, `--move-s`, `--ramp-s` set what these keys set. The seed's
# numbers are restated here (this module stays light); the tests of
# ``tests/cli/test_option_rules_droplet_nano_laser.py`` check them against
# `microfab.trajectory.circle_pattern`, where `PatternConfig` refuses a count below 1 and a
# length or time that is not positive.

#: Circles in one operation (seed 001 §4.2: four).
N_CIRCLES = 4
#: Circle diameter, mm (seed 001 §4.2: 0.15 mm).
CIRCLE_DIAMETER_MM = 0.15
#: Side of the field, mm (seed 001 §4.2: a working range of about 0.5 mm).
FIELD_MM = 0.5
#: Working range per axis, ±mm (seed 001 §2: up to ±1.5 mm): a circle or a field wider
#: than 2 × 1.5 mm does not fit the stage.
TRAVEL_MM = 1.5
#: Most circles (assumed: 25 times the seed's four, already hours of writing at 1 s a loop).
MAX_CIRCLES = 100
#: Most loops per circle (assumed: the gate needs a few; 1000 is far past convergence).
MAX_PERIODS = 1000
#: Longest pause, move or ramp, s (assumed, as `MAX_PERIOD_S`: a minute per step of a
#: 0.15 mm pattern is already far slower than anything the machine does).
MAX_STEP_S = 60.0

# fmt: off
PATTERN_N_CIRCLES = Key(name="n_circles", type="int", default=N_CIRCLES, low=1,
                        high=MAX_CIRCLES, unit="circles", help="circles (seed 001 §4.2: four)")
PATTERN_DIAMETER_MM = Key(name="diameter_mm", type="float", default=CIRCLE_DIAMETER_MM,
                          low=0.0, low_open=True, high=2 * TRAVEL_MM, unit="mm",
                          help="circle diameter (seed: 0.15 mm)")
PATTERN_FIELD_MM = Key(name="field_mm", type="float", default=FIELD_MM, low=0.0,
                       low_open=True, high=2 * TRAVEL_MM, unit="mm",
                       help="side of the field the circles fill (not less than the diameter)")
PATTERN_PERIODS = Key(name="periods", type="int", default=6, low=1, high=MAX_PERIODS,
                      unit="periods",
                      help="loops per circle (the gate exposes one after convergence)")
PATTERN_PAUSE_S = Key(name="pause_s", type="float", default=0.2, low=0.0, low_open=True,
                      high=MAX_STEP_S, unit="s",
                      help="pause at the start point before each circle")
PATTERN_MOVE_S = Key(name="move_s", type="float", default=0.3, low=0.0, low_open=True,
                     high=MAX_STEP_S, unit="s", help="move to each circle's start point")
PATTERN_RAMP_S = Key(name="ramp_s", type="float", default=0.25, low=0.0, low_open=True,
                     high=MAX_STEP_S, unit="s", help="spin-up and spin-down of each circle")
# fmt: on

#: The ``[pattern]`` section of the job, in `PatternConfig`'s order.
PATTERN_KEYS = (
    PATTERN_N_CIRCLES,
    PATTERN_DIAMETER_MM,
    PATTERN_FIELD_MM,
    PATTERN_PERIOD_S,
    PATTERN_PERIODS,
    PATTERN_PAUSE_S,
    PATTERN_MOVE_S,
    PATTERN_RAMP_S,
)
