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
from microfab.plants.lmw_focus import LMWFocus, LMWFocusParams
from microfab.plants.lmw_focus import load_params as load_focus
from microfab.plants.lmw_stage import LMWStage
from microfab.plants.lmw_stage_params import LMWStageParams
from microfab.plants.lmw_stage_params import load_params as load_stage

__all__ = ["DATA_FILES", "focus", "limits", "stage"]

#: The packaged data files the twins are built from (every value with its source).
DATA_FILES = ("lmw_stage.toml", "lmw_focus.toml")


def _stage(cfg: LMWStageParams, ideal: bool, **overrides: Any) -> LMWStage:
    if ideal:
        cfg = cfg.linear()
    return LMWStage(cfg.with_(**overrides) if overrides else cfg)


def _focus(cfg: LMWFocusParams, **overrides: Any) -> LMWFocus:
    return LMWFocus(cfg.with_(**overrides) if overrides else cfg)


_STAGES: TwinCache[LMWStageParams, LMWStage] = TwinCache(load_stage, _stage, DATA_FILES[0])
_FOCUS: TwinCache[LMWFocusParams, LMWFocus] = TwinCache(load_focus, _focus, DATA_FILES[1])


def stage(
    path: str | os.PathLike[str] | None = None, *, ideal: bool = False, **overrides: Any
) -> LMWStage:
    """The XY stage twin (as `microfab.plants.lmw_stage.lmw_stage_twin`), built once.

    Parameters
    ----------
    path : path-like, optional
        Another parameter file (default ``data/lmw_stage.toml``).
    ideal : bool
        Every nonlinear part off (`LMWStageParams.linear`).
    **overrides
        `LMWStageParams` fields to replace (after ``ideal``).
    """
    return _STAGES(path, ideal=ideal, **overrides)


def focus(path: str | os.PathLike[str] | None = None, **overrides: Any) -> LMWFocus:
    """The focus-axis twin (as `microfab.plants.lmw_focus.lmw_focus_twin`), built once."""
    return _FOCUS(path, **overrides)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 004 Table I)."""
    return MachineLimits.seed004_stage()
