"""The sizes of seed 002's test cases for the reference optimisation (a documented step).

The seed gives no sizes. As part 1 does with the time-optimal command
(`microfab.machines.xy_stage_cases.case_sizes`), one number per family is fitted
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
from microfab.machines.xy_stage_cases import (
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

    Returns
    -------
    SizingResult
    """
    st = Stage1Settings() if settings is None else settings
    g = CaseSizes(20e-3, 0.18) if guess is None else guess
    h, steps_h = _fit(lambda k: letters_seed002(k)["r"].contours[0], model, R_TIME_S,
                      g.letter_height_m, tolerance_m, st)  # fmt: skip
    c, steps_c = _fit(
        lambda k: airfoil_path(chord=k, start="leading", direction="cw"),
        model, AIRFOIL_TIME_S, g.airfoil_chord_m, tolerance_m, st,
    )  # fmt: skip
    return SizingResult(CaseSizes(h, c), {"letter": steps_h, "airfoil": steps_c})
