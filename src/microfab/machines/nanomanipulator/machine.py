"""The flexure nanomanipulator of seed 001 as a machine: its twin, built once, and play.

`twin` builds the plant (`microfab.plants.nanomanipulator.NanomanipulatorPlant`) from the
data file parsed once, once per distinct settings (`microfab.machines.twins`): the job's
check, its run, the comparisons and the calibration of one process share it. `play` runs
a controller on a reference through the twin's loop (`microfab.sim.loop.simulate`,
compiled) and returns what the stage did and what its sensor measured. The same machine on
hardware, through files, is `microfab.machines.nanomanipulator.files`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from microfab.control.base import Controller, Loop
from microfab.core.limits import MachineLimits
from microfab.machines.twins import TwinCache
from microfab.plants.nanomanipulator import NanomanipulatorPlant, nanomanipulator_twin
from microfab.plants.nanomanipulator_params import NanomanipulatorParams, load_params
from microfab.sim.loop import LoopState, simulate
from microfab.sim.result import SimResult

__all__ = ["DATA_FILES", "limits", "play", "twin"]

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


def play(
    controller: Controller | Loop,
    reference: np.ndarray,
    *,
    derivatives: Sequence[np.ndarray] = (),
    seed: int = 0,
    noise: bool = False,
    path: str | os.PathLike[str] | None = None,
    nonlinear: bool = True,
    disturbance: bool = True,
    state: LoopState | None = None,
) -> SimResult:
    """Play ``controller`` on ``reference`` through the twin's loop, from rest or ``state``.

    Parameters
    ----------
    controller : Controller or Loop
        The controller (PID, RBF, a plug-in RC around either, ...).
    reference : numpy.ndarray
        Reference position, mm, shape (n_samples, 2).
    derivatives : sequence of numpy.ndarray
        Its velocity and acceleration (mm/s, mm/s², each (n_samples, 2)) for a controller
        that reads them.
    seed : int
        Seed of the twin's disturbance phases and of the sensor noise.
    noise : bool
        Sensor noise on (the twin's ``noise_rms_mm``, drawn from ``seed``); off, the
        sensor reads the true position.
    path : path-like, optional
        Another twin data file (default the packaged one).
    nonlinear, disturbance : bool
        The §4.1 terms and ``d(t)`` of the twin (`twin`).
    state : LoopState, optional
        Where to continue from (e.g. the plant of an earlier result's ``final_state``
        with another controller's state: a hand-over); at rest if omitted. The noise is
        drawn for ``reference`` alone (from ``seed``).

    Returns
    -------
    SimResult
        True position ``output`` and measured position ``measured`` (mm), command
        ``command`` (V), each (n_samples, 2).
    """
    plant = twin(path, seed=seed, nonlinear=nonlinear, disturbance=disturbance)
    ref = np.asarray(reference, dtype=float)
    v = plant.noise(ref.shape[0], seed) if noise else np.zeros(ref.shape)
    return simulate(plant, controller, ref, v, state, derivatives=tuple(derivatives))
