"""The ``droplet-sweep`` job keys that the ``microfab droplet`` options share (seed 003).

A command-line option that sets what one of these keys sets declares itself with the key
(``number("--duration", key=DURATION)``, `microfab.cli._options`), so that the job file
and the command line accept the same values in the same unit. This module imports only
`microfab.io.job` and the NaAlg table's concentrations (both read by the CLI at start-up
anyway); `job`, which pulls the printhead and the jet models, reads its keys from here.

The voltage range is restated here as numbers, so that this module stays light;
``tests/cli/test_option_rules_droplet_nano_laser.py`` checks that it agrees with
`microfab.machines.printhead.limits` (seed 003 Table 1).

Option / key pairs: ``droplet sweep --duration`` and ``droplet render --duration`` /
``[sweep] duration_us``; ``droplet simulate --after-breakup`` / ``[sweep]
after_breakup_us``; ``droplet sweep --voltage-concentration`` / ``[sweep]
voltage_concentration_pct`` (and ``droplet simulate|render --concentration``, the same
quantity, range and unit, through `CONCENTRATION`); ``droplet sweep --jobs`` and ``droplet
sensitivity --jobs`` / ``[run] workers``; ``droplet simulate|render --voltage`` and each
of ``droplet sweep --voltages`` / ``[sweep] voltages_v`` (each element).
"""

from __future__ import annotations

import dataclasses

from microfab.io.job import Key
from microfab.process.inkjet.fluids import SEED_CONCENTRATIONS_PCT

__all__ = [
    "AFTER_BREAKUP",
    "CONCENTRATION",
    "DURATION",
    "DURATION_RANGE_US",
    "MAX_CONCENTRATION_PCT",
    "MAX_WORKERS",
    "VOLTAGE",
    "VOLTAGE_CONCENTRATION",
    "VOLTAGE_RANGE_V",
    "WORKERS",
]

#: Highest concentration of the property table, % w/v (seed 003 part 1 "Materials": 2 %);
#: the model's fluid (`microfab.process.inkjet.fluids.naalg`) is defined from 0 (water)
#: up to it and nowhere else.
MAX_CONCENTRATION_PCT = max(SEED_CONCENTRATIONS_PCT)
#: Drive amplitudes the printhead model is calibrated for, V (seed 003 part 1, Table 1:
#: 40 to 70 V; `microfab.machines.printhead.limits`).
VOLTAGE_RANGE_V = (40.0, 70.0)
#: Assumed bounds of the simulated time per point, µs: the seed's slowest breakup is
#: 230 µs (1 % at 50 V); 5 ms is far past any drop-on-demand event at 50 Hz drive.
DURATION_RANGE_US = (10.0, 5000.0)
MAX_WORKERS = 256  # assumed: more processes than any one machine here has cores

# fmt: off
#: NaAlg concentration of one drop, % w/v.
CONCENTRATION = Key(name="concentration_pct", type="float", default=1.0, low=0.0,
                    high=MAX_CONCENTRATION_PCT, unit="% w/v",
                    help="NaAlg concentration (the property table's range)")
#: Concentration of the sweep's voltage series (the same quantity and range).
VOLTAGE_CONCENTRATION = dataclasses.replace(CONCENTRATION, name="voltage_concentration_pct",
                                            help="concentration of the voltage series")
#: Bipolar drive amplitude of one drop, V.
VOLTAGE = Key(name="voltage_v", type="float", default=50.0, low=VOLTAGE_RANGE_V[0],
              high=VOLTAGE_RANGE_V[1], unit="V",
              help="bipolar drive amplitude (the model is calibrated for seed 003 Table 1)")
DURATION = Key(name="duration_us", type="float", default=400.0, low=DURATION_RANGE_US[0],
               high=DURATION_RANGE_US[1], unit="µs", help="simulated time per point")
AFTER_BREAKUP = Key(name="after_breakup_us", type="float", default=20.0, low=1.0,
                    high=DURATION_RANGE_US[1], unit="µs",
                    help="how long the bodies are followed after the first breakup")
WORKERS = Key(name="workers", type="int", default=1, low=1, high=MAX_WORKERS,
              help="worker processes of a local Dask cluster (1: in this process)")
# fmt: on
