"""The laser-micromachining stage of seed 004 as a machine: the XY twin and the focus twin.

Each data file is parsed once and each twin built once per distinct settings
(`microfab.machines.twins`): the contour runs, the sweep, the margins, the calibration and
the hardware export of one process share them.
"""

from __future__ import annotations

import os
from typing import Any

from microfab.core.limits import MachineLimits
from microfab.machines.twins import TwinCache
from microfab.plants import lmw_focus, lmw_stage_params
from microfab.plants.lmw_focus import LMWFocus, LMWFocusParams, lmw_focus_twin
from microfab.plants.lmw_stage import LMWStage, lmw_stage_twin
from microfab.plants.lmw_stage_params import LMWStageParams

__all__ = ["DATA_FILES", "focus", "limits", "stage"]

#: The packaged data files the twins are built from (every value with its source).
DATA_FILES = ("lmw_stage.toml", "lmw_focus.toml")

_STAGES: TwinCache[LMWStageParams, LMWStage] = TwinCache(
    lmw_stage_params.load_params, lambda cfg, **s: lmw_stage_twin(params=cfg, **s), DATA_FILES[0]
)
_FOCUS: TwinCache[LMWFocusParams, LMWFocus] = TwinCache(
    lmw_focus.load_params, lambda cfg, **s: lmw_focus_twin(params=cfg, **s), DATA_FILES[1]
)


def stage(
    path: str | os.PathLike[str] | None = None, *, ideal: bool = False, **overrides: Any
) -> LMWStage:
    """`lmw_stage_twin` (same arguments), parsed and built once per distinct settings."""
    return _STAGES(path, ideal=ideal, **overrides)


def focus(path: str | os.PathLike[str] | None = None, **overrides: Any) -> LMWFocus:
    """`lmw_focus_twin` (same arguments), parsed and built once per distinct settings."""
    return _FOCUS(path, **overrides)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 004 Table I)."""
    return MachineLimits.seed004_stage()
