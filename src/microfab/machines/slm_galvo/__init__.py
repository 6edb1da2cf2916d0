"""The SLM galvo scanner of seed 003 part 2: one module per role.

- `machine`: the twin, its limits and loop;
- `shapers`: shapers side by side on both twins;
- `shaping`: identification, input shaping and scan time (`run_shaping`).

The machine module's public names are re-exported here, so that
``from microfab.machines import slm_galvo``
then ``slm_galvo.twin(...)`` works; code inside the project imports
``microfab.machines.slm_galvo.machine`` itself.
"""

from microfab.machines.slm_galvo import machine as _machine
from microfab.machines.slm_galvo.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
