"""The flexure nanomanipulator of seed 001: one module per role.

- `machine`: the twin, its limits and play;
- `calibration`: the fit of the sensor noise to §4.2;
- `chunks`: a job's chunks and their checkpoints;
- `cure`: cured lines of a job;
- `files`: the plug-in RC step on hardware through files;
- `job`: the §4.2 circle-field job.

The machine module's public names are re-exported here, so that
``from microfab.machines import nanomanipulator``
then ``nanomanipulator.twin(...)`` works; code inside the project imports
``microfab.machines.nanomanipulator.machine`` itself.
"""

from microfab.machines.nanomanipulator import machine as _machine
from microfab.machines.nanomanipulator.machine import *  # noqa: F403 (its __all__, below)

__all__ = list(_machine.__all__)
