"""The galvo-scanner MSL machine of seed 000: one module per role.

- `machine`: the twin, its limits and loop;
- `calibration`: the fit to seed 000 Table 1;
- `ilc`: the ILC learning run (`run_msl_ilc`).

The machine module's public names are re-exported here, so that
``from microfab.machines import galvo``
then ``galvo.twin(...)`` works; code inside the project imports
``microfab.machines.galvo.machine`` itself.
"""

from microfab.machines.galvo import machine as _machine
from microfab.machines.galvo.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
