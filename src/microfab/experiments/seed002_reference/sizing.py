"""The sizes of seed 002's test cases for the reference optimisation (a documented step).

The seed gives no sizes. As part 1 does with the time-optimal command
(`microfab.machines.xy_stage.cases.case_sizes`), one number per family is fitted
and everything else is a check, but here the time is the *optimised* one, stage 1's
``T`` (eqs. 8-12) on the identified linear model at ``a_max = 1 m/s²`` and μ = 20 µm:

* the letter height so that "r" takes 0.807 s (seed 002 §V-A, Table III);
* the airfoil chord so that it takes 1.322 s (seed 002 Table III).

The other letters' times, every time at 3 m/s² and the airfoil at 2 m/s² are checks.

The fit is a secant search on ``log T`` against ``log size`` (``T`` grows like the square
root of the size where acceleration limits it, so the first step takes slope 1/2), to
0.1 % of the target time; each step is one stage-1 solve.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from microfab.geometry.airfoil import airfoil_path
from microfab.geometry.path import Path
from microfab.geometry.text import letters_seed002
from microfab.identify.subspace_model import ContinuousModel
from microfab.machines.xy_stage.cases import (
    AIRFOIL_TIME_S,
    R_TIME_S,
    SIZE_A_MAX,
    CaseSizes,
    centred,
)
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Settings, solve_stage1

__all__ = ["SIZE_A_MAX", "SizingResult", "reference_sizes"]

_RTOL = 1e-3  # assumed: 0.1 % of the target time
_MAX_STEPS = 8


@dataclass(frozen=True)
class SizingResult:
    """The fitted sizes and the stage-1 solves of the search.

    Attributes
    ----------
    sizes : CaseSizes
        Letter height and airfoil chord, m.
    steps : dict of str to list of (float, float)
        Per family ("letter", "airfoil"): (size m, T s) of every solve.
    """

    sizes: CaseSizes
    steps: dict[str, list[tuple[float, float]]] = field(default_factory=dict)


def _fit(
    make: Callable[[float], Path],
    model: ContinuousModel,
    target_s: float,
    guess: float,
    tolerance_m: float,
    settings: Stage1Settings,
) -> tuple[float, list[tuple[float, float]]]:
    def duration(size: float) -> float:
        p = ContourProblem(centred(make(size)), a_max=SIZE_A_MAX, tolerance_m=tolerance_m)
        return solve_stage1(p, model, settings).duration

    steps = [(guess, duration(guess))]
    slope = 0.5
    size = guess * (target_s / steps[0][1]) ** (1 / slope)
    for _ in range(_MAX_STEPS):
        t = duration(size)
        steps.append((size, t))
        if abs(t / target_s - 1) <= _RTOL:
            return size, steps
        (s0, t0), (s1, t1) = steps[-2], steps[-1]
        if s1 != s0 and t1 != t0:
            slope = min(max(math.log(t1 / t0) / math.log(s1 / s0), 0.2), 1.0)
        size = s1 * (target_s / t1) ** (1 / slope)
    raise RuntimeError(
        f"sizing did not reach {target_s:g} s within {_MAX_STEPS} stage-1 solves: {steps}"
    )


def reference_sizes(
    model: ContinuousModel,
    *,
    tolerance_m: float = 20e-6,
    settings: Stage1Settings | None = None,
    guess: CaseSizes | None = None,
    workers: int = 1,
) -> SizingResult:
    """Letter height and airfoil chord from stage 1 on ``model`` (module docstring).

    Parameters
    ----------
    model : ContinuousModel
        The identified linear model (eq. 6), m.
    tolerance_m : float
        μ, m.
    settings : Stage1Settings, optional
        Stage-1 settings of every solve.
    guess : CaseSizes, optional
        Starting sizes (default 20 mm and 0.18 m).
    workers : int
        With 2 or more, the letter and the airfoil searches run side by side in two
        worker processes (`microfab.io.sweep.run_sweep`, each on
        `microfab.core.threads.policy_threads` threads); the same solves either way.

    Returns
    -------
    SizingResult
    """
    st = Stage1Settings() if settings is None else settings
    g = CaseSizes(20e-3, 0.18) if guess is None else guess
    task = _FitTask(model=model, tolerance_m=tolerance_m, settings=st, guess=g)
    families = [_Family("letter"), _Family("airfoil")]
    if workers > 1:  # the two searches are independent: one process each
        from microfab.io.sweep import run_sweep

        rows = run_sweep(task, families, workers=min(workers, 2)).rows
    else:
        rows = [task(f) for f in families]
    fit = {f.name: row for f, row in zip(families, rows, strict=True)}
    steps = {k: [(float(a), float(b)) for a, b in v["steps"]] for k, v in fit.items()}
    sizes = CaseSizes(float(fit["letter"]["size"]), float(fit["airfoil"]["size"]))
    return SizingResult(sizes, steps)


@dataclass(frozen=True)
class _Family:
    """One sizing search: ``"letter"`` (the height of "r") or ``"airfoil"`` (its chord)."""

    name: str


def _letter_r(height_m: float) -> Path:
    return letters_seed002(height_m)["r"].contours[0]


def _airfoil(chord_m: float) -> Path:
    return airfoil_path(chord=chord_m, start="leading", direction="cw")


@dataclass(frozen=True)
class _FitTask:
    """`_fit` of one family, picklable for a worker process (`reference_sizes`)."""

    model: ContinuousModel
    tolerance_m: float
    settings: Stage1Settings
    guess: CaseSizes

    def __call__(self, family: _Family) -> dict[str, object]:
        if family.name == "letter":
            make, target, guess = _letter_r, R_TIME_S, self.guess.letter_height_m
        else:
            make, target, guess = _airfoil, AIRFOIL_TIME_S, self.guess.airfoil_chord_m
        size, steps = _fit(make, self.model, target, guess, self.tolerance_m, self.settings)
        return {"size": size, "steps": [list(step) for step in steps]}
