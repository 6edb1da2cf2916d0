"""The piezo drop-on-demand printhead of seed 003 part 1: one module per role.

- `machine`: the twin, its limits and the droplet sweep;
- `calibration`: the relaxation law fitted to the seed's breakup times;
- `sensitivity`: the breakup times against the assumed fluid values.

The machine module's public names are re-exported here, so that
``from microfab.machines import printhead``
then ``printhead.twin(...)`` works; code inside the project imports
``microfab.machines.printhead.machine`` itself.
"""

from microfab.machines.printhead import machine as _machine
from microfab.machines.printhead.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
