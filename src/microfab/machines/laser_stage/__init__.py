"""The laser-micromachining stage of seed 004: one module per role.

- `machine`: XY and focus twins, their loops;
- `calibration`: the fit to seed 004 Fig. 3's peak;
- `contour`: contour runs and the speed sweep;
- `files`: export for a real-time target, trace replay;
- `focus`: the autofocus search and its study.

The machine module's public names are re-exported here, so that
``from microfab.machines import laser_stage``
then ``laser_stage.twin(...)`` works; code inside the project imports
``microfab.machines.laser_stage.machine`` itself.
"""

from microfab.machines.laser_stage import machine as _machine
from microfab.machines.laser_stage.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
