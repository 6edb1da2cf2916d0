"""The contouring problem of seed 002 (eq. 5): a contour, a tolerance, the machine's bounds.

`ContourProblem` holds what both optimisation stages share and refuses a bad one with a
message that names the fix:

* ``path``: the exact target geometry ``Ξ(s)`` (`microfab.geometry.path.Path`, m), traced
  from ``s = 0`` to ``S``; it must lie in the workspace.
* ``tolerance_m``: ``μ`` of eq. (5) and (12h), constant along ``s`` (seed 002 §II-A:
  "μ(s) = 20 µm" for laser cutting), > 0 and below 1 mm.
* ``a_max``: the output acceleration bound of (12j) and (14f), per axis, m/s²: the
  trade-off knob (seed 002 §IV-B). Refused at or below 0 and above Table I's 40 m/s².
* ``limits``: Table I (`MachineLimits.seed002_stage`): workspace (12e, 14d), speed
  ``v_max`` = 1.5 m/s (12i, 14e) and the command's acceleration (40 m/s²), which the
  10 kHz command must pass before it is written or run.

`n_points` is the documented rule for the number of stage-1 points ``N`` (eq. 8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.geometry.path import Path

__all__ = ["A_MAX_LIMIT", "ContourProblem", "n_points"]

A_MAX_LIMIT = 40.0  # seed 002 Table I: the machine's acceleration limit, m/s²
TOLERANCE_M = 20e-6  # seed 002 §II-A and §V-A: μ = 20 µm
_N_MIN = 10  # fewer points cannot resolve even a square's corners (issue 18: N >= 10)
_N_MIN_RULE, _N_MAX_RULE = 200, 2000  # assumed bounds of the rule in `n_points`


def n_points(length_m: float, tolerance_m: float) -> int:
    """Number of stage-1 points ``N`` for a contour (eq. 8).

    The seed: "selected based on the total path length and tolerance bound", ``N ≈ 10³``
    for its letters (§IV-A, §IV-C).

    Rule (ours): the spacing ``Δs = S / (N - 1)`` is the tolerance, so that a chord
    between neighbouring points leaves an arc of radius ``R`` by ``Δs² / (8 R)``, at most
    ``μ / 8`` wherever ``R ≥ μ``; with at least 200 points and at most 2000 (a longer
    contour gets a coarser spacing, still sagging < 2 µm on radii ≥ 1 mm at 100 µm). The
    letter "r" of our sizing (S = 20.4 mm) with μ = 20 µm gets 1019 points, the seed's
    ``N ≈ 10³``.

    Parameters
    ----------
    length_m : float
        Path length ``S``, m.
    tolerance_m : float
        ``μ``, m.

    Returns
    -------
    int
        ``N``.
    """
    if not (math.isfinite(length_m) and length_m > 0):
        raise ValueError(f"the path length must be positive, got {length_m!r} m")
    if not (math.isfinite(tolerance_m) and tolerance_m > 0):
        raise ValueError(f"the tolerance must be positive, got {tolerance_m!r} m")
    n = math.ceil(length_m / tolerance_m) + 1
    return int(min(max(n, _N_MIN_RULE), _N_MAX_RULE))


@dataclass(frozen=True, eq=False)
class ContourProblem:
    """A contour to trace within a tolerance on the seed-002 stage (module docstring).

    Parameters
    ----------
    path : Path
        Target geometry ``Ξ(s)``, m.
    a_max : float
        Output acceleration bound per axis (12j, 14f), m/s², in (0, 40].
    tolerance_m : float
        ``μ`` (12h, 14c), m, in (0, 1e-3].
    limits : MachineLimits
        Table I by default.

    Raises
    ------
    ValueError
        A bad bound, an empty path, or a path outside the workspace (naming the axis, the
        coordinate and the bound).
    """

    path: Path
    a_max: float = 1.0
    tolerance_m: float = TOLERANCE_M
    limits: MachineLimits = field(default_factory=MachineLimits.seed002_stage)

    def __post_init__(self) -> None:
        a = self.a_max
        if not (isinstance(a, (int, float)) and math.isfinite(a) and 0 < a <= A_MAX_LIMIT):
            raise ValueError(
                f"a_max must lie in (0, {A_MAX_LIMIT:g}] m/s² (seed 002 Table I), got {a!r}"
            )
        mu = self.tolerance_m
        if not (isinstance(mu, (int, float)) and math.isfinite(mu) and 0 < mu <= 1e-3):
            raise ValueError(f"the tolerance must lie in (0, 1e-3] m, got {mu!r}")
        if not isinstance(self.path, Path) or len(self.path) == 0 or self.path.length <= 0:
            raise ValueError("no contour: the drawing has no path of positive length")
        if self.limits.workspace is None:
            return
        x0, y0, x1, y1 = self.path.bbox
        for axis, lo, hi, (wlo, whi) in (("x", x0, x1, self.limits.workspace[0]),
                                         ("y", y0, y1, self.limits.workspace[1])):  # fmt: skip
            if lo < wlo or hi > whi:
                bad = lo if lo < wlo else hi
                bound = wlo if lo < wlo else whi
                raise ValueError(
                    f"the drawing leaves the workspace: {axis} = {bad * 1e3:.3f} mm beyond "
                    f"{bound * 1e3:.3f} mm (Table I: [{wlo * 1e3:g}, {whi * 1e3:g}] mm); "
                    "move or scale the drawing"
                )

    @property
    def v_max(self) -> float:
        """Speed bound per axis (12i, 14e), m/s (the smaller of the axes' limits)."""
        return float(min(self.limits.velocity))

    @property
    def length(self) -> float:
        """``S``, m."""
        return float(self.path.length)

    @property
    def closed(self) -> bool:
        """Whether the contour ends where it starts (within 1 nm)."""
        return bool(np.linalg.norm(self.path.end - self.path.start) < 1e-9)
