"""The SLM galvo scanner of seed 003 part 2 as a machine: its twin, built once.

`twin` builds the scanner (`microfab.plants.galvo_slm.galvo_slm_twin`) from the data file
parsed once, once per distinct settings (`microfab.machines.twins`), so the
identification, the shaper comparison, the scan-time estimates and the whole build of one
process share it.
"""

from __future__ import annotations

import os
from typing import Any

from microfab.machines.twins import TwinCache
from microfab.plants.galvo_slm import GalvoSLMParams, GalvoSLMPlant, galvo_slm_twin, load_params

__all__ = ["DATA_FILES", "twin"]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("galvo_slm.toml",)

_TWINS: TwinCache[GalvoSLMParams, GalvoSLMPlant] = TwinCache(
    load_params, lambda cfg, **s: galvo_slm_twin(params=cfg, **s), DATA_FILES[0]
)


def twin(
    path: str | os.PathLike[str] | None = None, *, mirror_mode: bool = False, **overrides: Any
) -> GalvoSLMPlant:
    """`galvo_slm_twin` (same arguments), parsed and built once per distinct settings."""
    return _TWINS(path, mirror_mode=mirror_mode, **overrides)
