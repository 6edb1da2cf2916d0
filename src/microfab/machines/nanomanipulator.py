"""The flexure nanomanipulator of seed 001 as a machine: its twin, built once.

`twin` builds the plant (`microfab.plants.nanomanipulator.NanomanipulatorPlant`) from the
data file parsed once, once per distinct settings (`microfab.machines.twins`): the job's
check, its run, the comparisons and the calibration of one process share it.
"""

from __future__ import annotations

import os
from typing import Any

from microfab.core.limits import MachineLimits
from microfab.machines.twins import TwinCache
from microfab.plants.nanomanipulator import NanomanipulatorPlant, nanomanipulator_twin
from microfab.plants.nanomanipulator_params import NanomanipulatorParams, load_params

__all__ = ["DATA_FILES", "limits", "twin"]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("nanomanipulator_twin.toml",)


_TWINS: TwinCache[NanomanipulatorParams, NanomanipulatorPlant] = TwinCache(
    load_params, lambda cfg, **s: nanomanipulator_twin(params=cfg, **s), DATA_FILES[0]
)


def twin(
    path: str | os.PathLike[str] | None = None,
    *,
    seed: int = 0,
    nonlinear: bool = True,
    disturbance: bool = True,
    **overrides: Any,
) -> NanomanipulatorPlant:
    """`nanomanipulator_twin` (same arguments), parsed and built once per distinct settings."""
    return _TWINS(path, seed=seed, nonlinear=nonlinear, disturbance=disturbance, **overrides)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 001)."""
    return MachineLimits.seed001_stage()
