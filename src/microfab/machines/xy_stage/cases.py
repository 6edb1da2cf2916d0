"""The black-box XY stage's test cases (seed 002: letters u, r, c, h, airfoil) as commands.

Used by the identification job, the reference optimisation and the benchmarks.

Seed 002 evaluates its models (Table II columns 2-3, Fig. 9) on the letters *after
optimisation* at ``a_max``; that optimisation (eqs. 8-14) is the companion part. Here the
command of a case at ``a_max`` is the jerk-free time-optimal reference
(`microfab.trajectory.optimal.time_optimal`) along the exact contour under Table I's speed
(1.5 m/s) and ``a_max`` per axis, from rest to rest, sampled at 10 kHz. It is a stand-in
for the optimised input: it has the same time scale and the same acceleration bound, but
it follows the contour instead of pre-compensating the stage.

Sizes. The seed gives none. A documented step sets them (`case_sizes`):

* the letter height so that "r" takes ``R_TIME_S`` = 0.807 s at 1 m/s² (seed 002 §V-A and
  Table III: letter r, a_max = 1, T = 0.807 s);
* the airfoil chord so that it takes ``AIRFOIL_TIME_S`` = 1.322 s at 1 m/s² (seed 002
  Table III: airfoil, a_max = 1, T = 1.322 s).

Both by a root find on the time-optimal duration (which grows like the square root of the
size when acceleration limits it). The other letters' times are then checks, not fits.
Each case is centred on the workspace's origin.

`case_commands` makes every case's command at each ``a_max``; `play_cases` plays them on
the twin and scores each identified model on them (`CaseRun`: Table II columns 2-3 and
Fig. 9 of the ``stage-identify`` job).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.core.provenance import Calibration, quantity
from microfab.geometry.airfoil import airfoil_path
from microfab.geometry.path import Path
from microfab.geometry.text import SEED002_LETTERS, letters_seed002
from microfab.identify.excitation_run import DT
from microfab.identify.stage_data import RunErrors, StageRecord
from microfab.machines.xy_stage.machine import TwinSettings, play_runs
from microfab.trajectory.optimal import time_optimal

__all__ = [
    "AIRFOIL_TIME_S",
    "CALIBRATION",
    "CASES",
    "DATA_FILES",
    "R_TIME_S",
    "SIZE_A_MAX",
    "CaseCommand",
    "CaseRun",
    "CaseSizes",
    "case_command",
    "case_commands",
    "case_paths",
    "case_sizes",
    "centred",
    "play_cases",
    "table_iii_quantity",
]

R_TIME_S = 0.807  # seed 002 §V-A, Table III: letter "r" at a_max = 1 m/s² takes 0.807 s
AIRFOIL_TIME_S = 1.322  # seed 002 Table III: airfoil at a_max = 1 m/s² takes 1.322 s
SIZE_A_MAX = 1.0  # seed 002 Table III: the a_max of both times above, m/s²


def table_iii_quantity(case: str, a_max: float, what: str) -> str:
    """Id of one Table III number: ``what`` is ``"T"`` or a tolerance column."""
    return quantity("002", "Table III", case, f"{a_max:g} m/s²", what)


#: The case sizes (here for the time-optimal command, in ``seed002_reference.sizing`` for
#: stage 1's) are fitted at every run to these two times; every other length is a check.
CALIBRATION = Calibration(
    command="case sizing (letter height and airfoil chord)",
    data_file="",
    targets=frozenset(
        {table_iii_quantity("r", SIZE_A_MAX, "T"), table_iii_quantity("airfoil", SIZE_A_MAX, "T")}
    ),
    what="letter height to 'r', airfoil chord to the airfoil, at 1 m/s²",
)
#: The cases: the four letters (seed 002 §II-C) and the airfoil.
CASES = (*SEED002_LETTERS, "airfoil")
#: The packaged data the cases read (the airfoil coordinates).
DATA_FILES = ("airfoils",)
_N_GRID = 1000  # time_optimal grid nodes (issue 18: N = 1000 for a letter)


@dataclass(frozen=True)
class CaseSizes:
    """Sizes of the cases (module docstring).

    Attributes
    ----------
    letter_height_m : float
        Font size of the letters, m.
    airfoil_chord_m : float
        Chord of the airfoil, m.
    """

    letter_height_m: float
    airfoil_chord_m: float


def case_paths(sizes: CaseSizes, names: Sequence[str] = CASES) -> dict[str, Path]:
    """The closed contour of each named case, centred on the origin, m.

    Raises
    ------
    ValueError
        An unknown case name (naming the known ones).
    """
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise ValueError(f"unknown case(s) {unknown}; known: {', '.join(CASES)}")
    letters = letters_seed002(sizes.letter_height_m)
    out = {}
    for n in names:
        if n == "airfoil":
            # seed 002 Fig. 13: clockwise from the leading edge
            p = airfoil_path(chord=sizes.airfoil_chord_m, start="leading", direction="cw")
        else:
            p = letters[n].contours[0]  # each letter is one closed contour (DejaVu Sans)
        out[n] = centred(p)
    return out


def centred(path: Path) -> Path:
    """``path`` moved so that its bounding box is centred on the origin."""
    x0, y0, x1, y1 = path.bbox
    return path.translated((-(x0 + x1) / 2, -(y0 + y1) / 2))


def _limits(a_max: float) -> MachineLimits:
    if not (math.isfinite(a_max) and a_max > 0):
        raise ValueError(f"a_max must be a positive acceleration, got {a_max!r} m/s²")
    table1 = MachineLimits.seed002_stage()
    return dataclasses.replace(table1, acceleration=(float(a_max), float(a_max)))


@dataclass(frozen=True, eq=False)
class CaseCommand:
    """A case's command at one ``a_max`` (time-optimal, module docstring).

    Attributes
    ----------
    name : str
        File-safe: ``"<case>_a<a_max>"``.
    case : str
        One of `CASES`.
    a_max : float
        Acceleration bound per axis, m/s².
    dt : float
        Sample time, s (10 kHz).
    command : numpy.ndarray
        Shape (n, 2), m, from rest to rest; it passed ``check_trajectory`` (Table I).
    duration_s : float
        Its length, s.
    """

    name: str
    case: str
    a_max: float
    dt: float
    command: np.ndarray
    duration_s: float


def case_command(case: str, path: Path, a_max: float) -> CaseCommand:
    """The time-optimal command of ``path`` at ``a_max`` (per axis), 10 kHz.

    Raises
    ------
    ValueError
        A non-positive ``a_max``.
    microfab.trajectory.optimal.PlanningError
        No trajectory within the limits.
    """
    res = time_optimal(path, _limits(a_max), n_grid=_N_GRID, sample_rate_hz=1.0 / DT)
    return CaseCommand(
        name=f"{case}_a{a_max:g}",
        case=case,
        a_max=float(a_max),
        dt=DT,
        command=np.asarray(res.trajectory.position),
        duration_s=float(res.duration),
    )


def _fit_size(make: Callable[[float], Path], target_s: float, guess: float) -> float:
    """Size whose time-optimal duration at `SIZE_A_MAX` is ``target_s`` (to 1e-4 relative)."""
    from scipy.optimize import brentq

    lim = _limits(SIZE_A_MAX)

    def duration(size: float) -> float:
        return float(time_optimal(make(size), lim, n_grid=_N_GRID).duration)

    t0 = duration(guess)
    first = guess * (target_s / t0) ** 2  # T grows like sqrt(size) when acceleration binds
    lo, hi = first / 1.5, first * 1.5
    return float(brentq(lambda k: duration(k) - target_s, lo, hi, rtol=1e-4))


def case_sizes(r_time_s: float = R_TIME_S, airfoil_time_s: float = AIRFOIL_TIME_S) -> CaseSizes:
    """The documented sizing step (module docstring): letter height and airfoil chord."""
    h = _fit_size(lambda k: letters_seed002(k)["r"].contours[0], r_time_s, 0.01)
    c = _fit_size(lambda k: airfoil_path(chord=k, start="leading", direction="cw"),
                  airfoil_time_s, 0.1)  # fmt: skip
    return CaseSizes(letter_height_m=h, airfoil_chord_m=c)


def case_commands(
    sizes: CaseSizes,
    a_values: Sequence[float],
    names: Sequence[str] = CASES,
    progress: Callable[[int, int], None] | None = None,
) -> list[CaseCommand]:
    """`case_command` of each named case at each of ``a_values`` (m/s²), a_max by a_max.

    ``progress(i, n)`` is called before the ``i``-th of the ``n`` accelerations.
    """
    paths = case_paths(sizes, names)
    out: list[CaseCommand] = []
    for i, a_max in enumerate(a_values):
        if progress is not None:
            progress(i, len(a_values))
        out += [case_command(name, p, a_max) for name, p in paths.items()]
    return out


@dataclass(frozen=True, eq=False)
class CaseRun:
    """One case at one a_max, played on the twin, and each model's errors there.

    Attributes
    ----------
    case, a_max, duration_s
        Which, m/s², and the command's length, s.
    limited : int
        Samples the set-point guard changed (0 within Table I).
    record : StageRecord
        Command and measured position.
    errors : mapping of str to RunErrors or None
        Each named model's errors ``y - y_model`` (every sample kept); None where the
        model was not given.
    """

    case: str
    a_max: float
    duration_s: float
    limited: int
    record: StageRecord
    errors: Mapping[str, RunErrors | None]

    @property
    def linear(self) -> RunErrors | None:
        """The errors of the model named "linear"."""
        return self.errors.get("linear")


def play_cases(
    commands: Sequence[CaseCommand], twin: TwinSettings, models: Mapping[str, Any]
) -> tuple[CaseRun, ...]:
    """Play each command on the twin and score each model on its run.

    Parameters
    ----------
    commands : sequence of CaseCommand
        `case_commands`'.
    twin : TwinSettings
        The twin and its noise seed (run ``k`` uses ``seed + k``).
    models : mapping of str to stage model or None
        Models with ``errors(records, keep=True) -> RunErrors``
        (`microfab.identify.stage_data.StageLinearModel`,
        `microfab.identify.stage_ann.StageAnnModel`); None: not scored.
    """
    played = play_runs(commands, twin)
    return tuple(
        CaseRun(
            case=cmd.case,
            a_max=cmd.a_max,
            duration_s=cmd.duration_s,
            limited=lim,
            record=rec,
            errors={
                k: None if m is None else m.errors([rec], keep=True) for k, m in models.items()
            },
        )
        for cmd, rec, lim in zip(commands, played.records, played.limited, strict=True)
    )
