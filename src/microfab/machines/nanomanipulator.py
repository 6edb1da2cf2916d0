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
from microfab.plants.nanomanipulator import NanomanipulatorPlant
from microfab.plants.nanomanipulator_params import NanomanipulatorParams, load_params

__all__ = ["DATA_FILES", "limits", "twin"]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("nanomanipulator_twin.toml",)


def _build(
    cfg: NanomanipulatorParams, seed: int, nonlinear: bool, disturbance: bool, **overrides: Any
) -> NanomanipulatorPlant:
    cfg = cfg.with_(disturbance_seed=seed, **overrides)
    if not nonlinear:
        cfg = cfg.linear()
    if not disturbance:
        cfg = cfg.with_(disturbance_mm_s2=(0.0, 0.0))
    return NanomanipulatorPlant(cfg)


_TWINS: TwinCache[NanomanipulatorParams, NanomanipulatorPlant] = TwinCache(
    load_params, _build, DATA_FILES[0]
)


def twin(
    path: str | os.PathLike[str] | None = None,
    *,
    seed: int = 0,
    nonlinear: bool = True,
    disturbance: bool = True,
    **overrides: Any,
) -> NanomanipulatorPlant:
    """The twin (as `microfab.plants.nanomanipulator.nanomanipulator_twin`), built once.

    Parameters
    ----------
    path : path-like, optional
        Another parameter file (default ``data/nanomanipulator_twin.toml``).
    seed : int
        Disturbance phase seed.
    nonlinear, disturbance : bool
        The §4.1 terms; ``d(t)``.
    **overrides
        `NanomanipulatorParams` fields to replace (before ``nonlinear``, ``disturbance``).
    """
    return _TWINS(path, seed=seed, nonlinear=nonlinear, disturbance=disturbance, **overrides)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 001)."""
    return MachineLimits.seed001_stage()
