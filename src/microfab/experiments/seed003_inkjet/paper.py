"""Published numbers of seed 003 part 1 (Xu et al., droplet formation of alginate solutions).

Every value cites its table, figure or section in
``../shared/seeds/003_4915b267b12a78d4.txt``. The drive waveform's Table 1 values (rise and
fall 3 µs, dwell 30 µs, echo 30 µs, 50 Hz) are defaults of
:class:`microfab.trajectory.waveform.Waveform` and live there; the concentrations are also
the table points of :mod:`microfab.process.inkjet.fluids`. Both are taken from those
modules here, so that each number is written once.
"""

from __future__ import annotations

from microfab.process.inkjet.breakup import BreakupMode
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
#: Voltage of the concentration series, V.
FIG4_VOLTAGE_V = 50.0  # seed 003 part 1, Fig. 4
#: Drive voltage of the seed's quoted breakup times, V.
SEED_VOLTAGE_V = 50.0  # seed 003 part 1, Fig. 2 and 4

#: First breakup at 50 V: concentration % w/v → (time s, mode). Seed 003 part 1,
#: "Typical droplet formation process" and Fig. 2: 0.15 % at 95 µs by front-pinching,
#: 1 % at 230 µs by exit-pinching.
SEED_BREAKUP: dict[float, tuple[float, BreakupMode]] = {
    0.15: (95e-6, "front"),
    1.0: (230e-6, "exit"),
}
