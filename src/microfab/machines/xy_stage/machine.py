"""The black-box XY stage of seed 002 as a machine: its twin, built once, and runs played on it.

The twin (`microfab.plants.xy_stage`) stands in for the ETEL stage of seed 002: a command
record at 10 kHz (an `microfab.identify.excitation.ExcitationRun`, a case's command of
`microfab.machines.xy_stage.cases`, or an optimised reference) is played from rest at its
first sample through the compiled loop (`microfab.sim.loop.simulate` with
`microfab.control.setpoint.SetPoint`: the black box's input is the set-point ρ), then held
for ``hold_s`` so that the stage settles; the measured position gets the twin's 2 µm
noise (seed 002 eq. 3) drawn from a seed per run. What comes back is a `StageRecord` per
run, the same shape as a measured run read from a file (`microfab identify linear`);
``microfab stage play`` (`microfab.cli.stage`) plays command files (`Command`) this way
and writes them back with their measured columns
(`microfab.identify.stage_runs.record_trace`).

The twin of one configuration (`TwinSettings.changes`) is built once per process and
shared (`twin`): the plant is immutable configuration, its state lives in the loop.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from microfab.control.setpoint import SetPoint
from microfab.core.limits import MachineLimits
from microfab.identify.stage_data import StageRecord
from microfab.machines.twins import TwinCache
from microfab.plants.xy_stage import XYStagePlant, xy_stage_twin
from microfab.plants.xy_stage_params import XYStageParams, load_params
from microfab.sim.loop import LoopState, simulate

__all__ = [
    "DATA_FILES",
    "Command",
    "CommandRun",
    "Played",
    "TwinSettings",
    "limits",
    "play_runs",
    "twin",
]

#: The packaged data file the twin is built from (every value with its source).
DATA_FILES = ("xy_stage_twin.toml",)


def limits() -> MachineLimits:
    """The stage's declared limits (seed 002 Table I: workspace, 1.5 m/s, 40 m/s²)."""
    return MachineLimits.seed002_stage()


_TWINS: TwinCache[XYStageParams, XYStagePlant] = TwinCache(
    load_params, lambda cfg, **s: xy_stage_twin(params=cfg, **s), DATA_FILES[0]
)


def twin(changes: tuple[tuple[str, Any], ...] = ()) -> XYStagePlant:
    """The twin with these `XYStageParams` fields replaced, built once per distinct set.

    Parameters
    ----------
    changes : tuple of (str, value)
        Fields to replace (e.g. the calibrated friction magnitudes).
    """
    return _TWINS(None, **dict(changes))


@dataclass(frozen=True, kw_only=True)
class TwinSettings:
    """The twin a study runs on.

    Parameters
    ----------
    seed : int
        Noise seed (run ``k`` uses ``seed + k``).
    noise : bool
        The 2 µm output noise of eq. (3).
    hold_s : float
        Hold after each command, s (assumed 0.5 s: the calibrated twin's x axis, whose
        friction integrator takes longer than 0.2 s, is then within 0.2 µm).
    changes : tuple of (str, value)
        `XYStageParams` fields to replace (e.g. the calibrated magnitudes).
    """

    seed: int = 0
    noise: bool = True
    hold_s: float = 0.5  # assumed, see above
    changes: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if not self.hold_s >= 0:
            raise ValueError(f"hold_s must be >= 0 s, got {self.hold_s!r}")

    def twin(self) -> XYStagePlant:
        """The twin of these settings (`twin`: built once per distinct ``changes``)."""
        return twin(self.changes)


@dataclass(frozen=True, eq=False)
class Played:
    """Runs played on the twin.

    Attributes
    ----------
    records : list of StageRecord
        Command ``u`` and measured position ``y`` of each run, (n, 2), m, with the hold.
    limited : tuple of int
        Samples the twin's set-point guard changed in each run (0 within Table I).
    dt : float
        Sample time, s.
    """

    records: list[StageRecord]
    limited: tuple[int, ...]
    dt: float


class CommandRun(Protocol):
    """A command to play: an `ExcitationRun` or a case's command (`cases.CaseCommand`)."""

    @property
    def name(self) -> str: ...  # noqa: D102
    @property
    def dt(self) -> float: ...  # noqa: D102
    @property
    def command(self) -> np.ndarray: ...  # noqa: D102


@dataclass(frozen=True, eq=False)
class Command:
    """A command read from a file, to play (`CommandRun`): set-points of x and y.

    Attributes
    ----------
    name : str
        Its name (the file's stem), for the measured run and messages.
    dt : float
        Sample time, s.
    command : numpy.ndarray
        Set-points ``input_x``, ``input_y``, m, shape (n, 2).
    """

    name: str
    dt: float
    command: np.ndarray


def play_runs(
    runs: Sequence[CommandRun],
    settings: TwinSettings | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Played:
    """Play each run on the twin from rest at its first sample, then hold (module doc).

    Parameters
    ----------
    runs : sequence of CommandRun
        Commands (n, 2), m, each at its own ``dt``.
    settings : TwinSettings, optional
        Twin, noise seed (run ``k`` uses ``seed + k``), noise on or off, hold.
    progress : callable, optional
        Called as ``progress(done, total)`` after each run.

    Returns
    -------
    Played
    """
    s = TwinSettings() if settings is None else settings
    twin = s.twin()
    out = []
    limited = []
    for k, run in enumerate(runs):
        u = np.asarray(run.command, dtype=float)
        n_hold = round(s.hold_s / run.dt)
        u = np.vstack([u, np.repeat(u[-1:], n_hold, axis=0)])
        state = LoopState(
            plant=twin.state_at((float(u[0, 0]), float(u[0, 1]))),
            controller=np.zeros(0),
            observer=np.zeros(0),
            command=u[0].copy(),
        )
        v = twin.noise(u.shape[0], s.seed + k) if s.noise else None
        res = simulate(twin, SetPoint(2), u, v, state=state, axes=("x", "y"))
        limited.append(int(twin.guard_counts(res.final_state.plant).limited))
        out.append(StageRecord(name=run.name, u=u, y=np.asarray(res.measured)))
        if progress is not None:
            progress(k + 1, len(runs))
    return Played(records=out, limited=tuple(limited), dt=float(runs[0].dt) if runs else 1e-4)
