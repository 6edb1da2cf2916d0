"""The piezo drop-on-demand printhead of seed 003 part 1: one module per role.

- `machine`: the twin, its limits and the droplet sweep;
- `calibration`: the relaxation law fitted to the seed's breakup times;
- `sensitivity`: the breakup times against the assumed fluid values.

The machine module's public names are re-exported here, so that
``from microfab.machines import printhead``
then ``printhead.twin(...)`` works; code inside the project imports
``microfab.machines.printhead.machine`` itself.
"""

from microfab.machines.printhead.machine import (
    DATA_FILES,
    EULER_SWEEP_MAX_STEPS,
    FIG4_VOLTAGE_V,
    SWEEP_MAX_STEPS,
    DropletSettings,
    PrintheadLimits,
    SweepPoint,
    droplet_sweep,
    limits,
    model_sweep,
    play,
    run_point,
    simulate_point,
    sweep_points,
    twin,
)

__all__ = [
    "DATA_FILES",
    "EULER_SWEEP_MAX_STEPS",
    "FIG4_VOLTAGE_V",
    "SWEEP_MAX_STEPS",
    "DropletSettings",
    "PrintheadLimits",
    "SweepPoint",
    "droplet_sweep",
    "limits",
    "model_sweep",
    "play",
    "run_point",
    "simulate_point",
    "sweep_points",
    "twin",
]
