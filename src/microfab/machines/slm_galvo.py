"""The SLM galvo scanner of seed 003 part 2 as a machine: its twin, built once.

`twin` builds the scanner (`microfab.plants.galvo_slm.GalvoSLMPlant`) from the data file
parsed once, once per distinct settings (`microfab.machines.twins`), so the
identification, the shaper comparison, the scan-time estimates and the whole build of one
process share it.
"""

from __future__ import annotations

import os
from typing import Any

from microfab.machines.twins import TwinCache
from microfab.plants.galvo_slm import GalvoSLMParams, GalvoSLMPlant, load_params

__all__ = ["DATA_FILES", "twin"]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("galvo_slm.toml",)


def _build(cfg: GalvoSLMParams, mirror_mode: bool, **overrides: Any) -> GalvoSLMPlant:
    return GalvoSLMPlant(cfg.with_(**overrides) if overrides else cfg, mirror_mode=mirror_mode)


_TWINS: TwinCache[GalvoSLMParams, GalvoSLMPlant] = TwinCache(load_params, _build, DATA_FILES[0])


def twin(
    path: str | os.PathLike[str] | None = None, *, mirror_mode: bool = False, **overrides: Any
) -> GalvoSLMPlant:
    """The scanner twin (as `microfab.plants.galvo_slm.galvo_slm_twin`), built once.

    Parameters
    ----------
    path : path-like, optional
        Another parameter file (default ``data/galvo_slm.toml``).
    mirror_mode : bool
        Add the lightly damped mirror mode (assumed 3 kHz, ζ 0.02).
    **overrides
        `GalvoSLMParams` fields to replace (validated; unknown names refused).
    """
    return _TWINS(path, mirror_mode=mirror_mode, **overrides)
