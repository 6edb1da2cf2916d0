"""Published numbers of seed 003 part 2 (Buls et al., SLM galvo scanner input shaping).

Every value cites its section in ``../shared/seeds/003_4915b267b12a78d4.txt`` (second
paper). The scan-time numbers of §4 live with the estimate that uses them
(`microfab.process.slm.estimate`: 4686 -> 4219 s, jump delay 750 -> 250 µs) and the
identified model of §1 with the machine (`microfab.machines.slm_galvo`); both are
re-exported here.

Seed errors noted here once:

* §2 prints the shaper's poles at "3000 rad/s"; its own coefficients give
  ``p^4 = 5.075e28 / 1.272e11`` and ``4 p = 1.279e16 / 1.272e11``: ``p = 2π·4000 rad/s``.
* §2's "fs = 1e-5" is the sample period (10 µs), not a frequency.
* The printed 4-digit discrete numerator sums to about 0 (a zero at z = 1): taken
  literally the filter has no static gain; the filter is built from the continuous design.
* Fig. 7 says the shaped axis reaches its speed "25 % faster", the conclusion "twice as
  fast"; the model gives 2.55x (788 -> 309 µs to 95 % speed).
"""

from __future__ import annotations

from microfab.machines.slm_galvo.machine import SEED_MODEL_DEN as MODEL_DEN
from microfab.machines.slm_galvo.machine import SEED_MODEL_NUM as MODEL_NUM
from microfab.process.slm.estimate import (
    SEED_JUMP_DELAY_SHAPED_S,
    SEED_JUMP_DELAY_UNSHAPED_S,
    SEED_TOTAL_SHAPED_S,
    SEED_TOTAL_UNSHAPED_S,
)

__all__ = [
    "CONTINUOUS_SHAPER_DEN",
    "CONTINUOUS_SHAPER_NUM",
    "DISCRETE_SHAPER_DEN",
    "DISCRETE_SHAPER_NUM",
    "MODEL_DEN",
    "MODEL_NUM",
    "SEED_JUMP_DELAY_SHAPED_S",
    "SEED_JUMP_DELAY_UNSHAPED_S",
    "SEED_TOTAL_SHAPED_S",
    "SEED_TOTAL_UNSHAPED_S",
]

# ---------------------------------------------------------------- §1: identified model
# MODEL_NUM, MODEL_DEN (§1, G(s)): microfab.machines.slm_galvo.SEED_MODEL_NUM / _DEN
CHIRP_BAND_HZ = (10.0, 2000.0)  # seed 003 part 2 §1: chirp 10 Hz to 2 kHz
CHIRP_AMPLITUDE_BIT = 100.0  # seed 003 part 2 §1: amplitude 100 bit
CHIRP_DURATION_S = 1.0  # seed 003 part 2 §1: 1 s

# ---------------------------------------------------------------- §2: the shaper
CONTINUOUS_SHAPER_NUM = (3.99e17, 3.797e21, 2.303e25, 5.075e28)  # seed 003 part 2 §2
CONTINUOUS_SHAPER_DEN = (1.272e11, 1.279e16, 4.82e20, 8.076e24, 5.075e28)  # seed 003 part 2 §2
DISCRETE_SHAPER_NUM = (19.61, -56.99, 55.26, -17.88)  # seed 003 part 2 §2 (z^-1 .. z^-4)
DISCRETE_SHAPER_DEN = (1.0, -3.111, 3.63, -1.882, 0.3659)  # seed 003 part 2 §2
LAG_FACTOR = 2.0  # seed 003 part 2 §3 (Fig. 6): position lag "reduced by a factor two"
SETTLING_FACTOR = 2.0  # seed 003 part 2 §3 (Fig. 6): settling time "reduced by a factor two"
SPEED_FASTER_FIG7 = 0.25  # seed 003 part 2 §3 (Fig. 7): nominal speed "25% faster"
SPEED_FACTOR_CONCLUSION = 2.0  # seed 003 part 2, Conclusion: "twice as fast"
SCAN_TIME_REDUCTION = 0.10  # seed 003 part 2 §4: "total scan time reduction of 10%"
