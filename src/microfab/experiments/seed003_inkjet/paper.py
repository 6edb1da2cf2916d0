"""Published numbers of seed 003 part 1 (Xu et al., droplet formation of alginate solutions).

Every value cites its table, figure or section in
``../shared/seeds/003_4915b267b12a78d4.txt``. The drive waveform's Table 1 values (rise and
fall 3 µs, dwell 30 µs, echo 30 µs, 50 Hz) are defaults of
:class:`microfab.trajectory.waveform.Waveform` and live there; the concentrations are also
the table points of :mod:`microfab.process.inkjet.fluids`; the Fig. 4 voltage is the
sweep's (:mod:`microfab.machines.printhead`) and the two quoted breakups are the targets of
the relaxation-law calibration (:mod:`microfab.machines.printhead.calibration`). All are
taken from those modules here, so that each number is written once.
"""

from __future__ import annotations

from microfab.machines.printhead.calibration import SEED_BREAKUP, SEED_VOLTAGE_V
from microfab.machines.printhead.machine import FIG4_VOLTAGE_V
from microfab.process.inkjet.fluids import SEED_CONCENTRATIONS_PCT as _FLUID_CONCENTRATIONS
from microfab.trajectory.waveform import SEED003_VOLTAGES_V

__all__ = [
    "FIG4_VOLTAGE_V",
    "SEED_BREAKUP",
    "SEED_CONCENTRATIONS_PCT",
    "SEED_VOLTAGES_V",
    "SEED_VOLTAGE_V",
]

#: NaAlg concentrations, % w/v: 0.15, 0.20, 0.25, 1, 1.5 and 2 %.
SEED_CONCENTRATIONS_PCT: tuple[float, ...] = _FLUID_CONCENTRATIONS  # seed 003 part 1, "Materials"
#: Excitation voltages, V: 40 to 70 V in 5 V steps.
SEED_VOLTAGES_V: tuple[float, ...] = SEED003_VOLTAGES_V  # seed 003 part 1, Table 1
# FIG4_VOLTAGE_V: voltage of the concentration series, 50 V (seed 003 part 1, Fig. 4).
# SEED_VOLTAGE_V: drive voltage of the seed's quoted breakup times, 50 V (seed 003 part 1,
# Fig. 2 and 4).
# SEED_BREAKUP: first breakup at 50 V, concentration % w/v -> (time s, mode): 0.15 % at
# 95 µs by front-pinching, 1 % at 230 µs by exit-pinching (seed 003 part 1, "Typical
# droplet formation process" and Fig. 2).
