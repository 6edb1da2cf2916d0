"""The black-box XY stage of seed 002: one module per role.

- `machine`: the twin and runs played on it;
- `ann`: the per-axis networks (eq. 7);
- `calibration`: the disturbance magnitudes fitted;
- `cases`: the test cases (letters, airfoil) as commands;
- `generations`: the networks' generations (Fig. 7);
- `identify`: identification runs and the linear model;
- `memory`: how far back the twin remembers;
- `reference`: optimised references (§V);
- `score`: a measured run scored as the reference job scores it.

The machine module's public names are re-exported here, so that
``from microfab.machines import xy_stage``
then ``xy_stage.twin(...)`` works; code inside the project imports
``microfab.machines.xy_stage.machine`` itself.
"""

from microfab.machines.xy_stage import machine as _machine
from microfab.machines.xy_stage.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
