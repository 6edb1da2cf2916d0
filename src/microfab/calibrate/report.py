"""A calibration's results as data: targets, parameters, sensitivity, conflicts.

No drawing and no printing here (python-control's split: results as data, plotting
apart): `CalibrationResult.as_table` gives plain rows that `microfab.report.tables` can
print, `CalibrationResult.to_dict` / `to_json` a JSON document.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.calibrate.problem import CalibrationProblem

__all__ = [
    "AT_BOUND",
    "PIN_SHARE",
    "CalibrationResult",
    "Conflict",
    "ParameterRow",
    "TargetRow",
    "build_result",
    "pareto_filter",
]

#: A parameter within this distance of either end of its normalised range [0, 1] is
#: flagged at its bound (assumed: 0.1 % of the range, the search's resolution).
AT_BOUND = 1.0e-3
#: A target is pinned by the parameters whose |sensitivity| is at least this share of the
#: largest in the target's row (assumed: an order of magnitude below the strongest).
PIN_SHARE = 0.1


@dataclass(frozen=True)
class TargetRow:
    """One target at the answer: its value, the model's, the residual, met or not."""

    name: str
    role: str
    value: float
    tolerance: float
    unit: str
    model: float
    residual: float
    met: bool
    pinned_by: tuple[str, ...]
    source: str
    side: str = "both"

    @property
    def shown(self) -> str:
        """The paper's value as the table shows it (``>= 0.95`` for a floor)."""
        prefix = {"both": "", "at least": ">= ", "at most": "<= "}.get(self.side, "")
        return f"{prefix}{self.value:g}"


@dataclass(frozen=True)
class ParameterRow:
    """One free parameter at the answer; ``at_bound`` is ``"low"``, ``"high"`` or None."""

    name: str
    value: float
    unit: str
    low: float
    high: float
    normalised: float
    at_bound: str | None
    source: str


def pareto_filter(points: Sequence[Sequence[float]]) -> np.ndarray:
    """The points no other beats on both ``|r_a|`` and ``|r_b|``, by rising ``|r_a|``.

    Parameters
    ----------
    points : sequence of (r_a, r_b)
        Signed residual pairs.

    Returns
    -------
    ndarray, shape (k, 2)
        The non-dominated pairs (signs kept), ``|r_a|`` rising and ``|r_b|`` falling.
    """
    arr = np.asarray(points, dtype=float).reshape(-1, 2)
    arr = arr[np.all(np.isfinite(arr), axis=1)]
    order = np.lexsort((np.abs(arr[:, 1]), np.abs(arr[:, 0])))
    kept = []
    least_b = np.inf
    for i in order:
        if abs(arr[i, 1]) < least_b:
            kept.append(arr[i])
            least_b = abs(arr[i, 1])
    return np.array(kept).reshape(-1, 2)


@dataclass(frozen=True)
class Conflict:
    """Two fit targets the model cannot meet together: their Pareto front and the finding.

    Attributes
    ----------
    target_a, target_b : str
        The two worst fit targets at the answer.
    front : tuple of (r_a, r_b)
        The front sampled by the epsilon-constraint sweep: ``|r_a|`` rising, ``|r_b|``
        falling.
    finding : str
        One line: whether both can be met, and the best of one with the other met.
    """

    target_a: str
    target_b: str
    front: tuple[tuple[float, float], ...]
    finding: str

    @classmethod
    def from_front(
        cls, a: str, b: str, sampled: np.ndarray, front: np.ndarray, requested: int
    ) -> Conflict:
        """Build the finding from the non-dominated ``front`` (k, 2) of every evaluation.

        The sweep bounds ``|r_b|`` and minimises ``|r_a|``, so the finding states the best
        ``a`` with ``b`` met (the other direction is not swept).
        """
        absf = np.abs(front)
        both = front[np.all(absf <= 1.0, axis=1)]
        if len(both):
            ra, rb = both[0]
            finding = (
                f"targets {a} and {b} can both be met (r_{a} = {ra:.3g}, r_{b} = {rb:.3g}): "
                "the unmet targets pull against others"
            )
        else:
            parts = []
            with_b = front[absf[:, 1] <= 1.0]
            if len(with_b):
                ra, rb = with_b[np.argmin(np.abs(with_b[:, 0]))]
                parts.append(f"the best {a} with {b} met is r_{a} = {ra:.3g} (r_{b} = {rb:.3g})")
            else:
                parts.append(f"{b} is never met (least |r_{b}| = {absf[:, 1].min():.3g})")
            finding = f"targets {a} and {b} cannot both be met: " + "; ".join(parts)
        # a sampled front, not a proof: a larger budget may still find the point
        finding += (
            f" (in {requested} evaluations: a conflict in the model, or a budget too small "
            "to find the point; a larger budget tells them apart)"
        )
        pts = tuple((float(x), float(y)) for x, y in sampled)
        return cls(a, b, pts, finding)


@dataclass(frozen=True)
class CalibrationResult:
    """What a calibration found, as data.

    Attributes
    ----------
    targets : tuple of TargetRow
        Every target, fit and check, at the answer.
    parameters : tuple of ParameterRow
        Every free parameter at the answer.
    sensitivity : ndarray, shape (m, n)
        ``d r_i / d u_j`` at the answer: target ``i``'s residual per unit of parameter
        ``j``'s normalised coordinate (central differences, one-sided at a bound).
    conflict : Conflict or None
        When a fit target is not met and there are two fit targets or more.
    converged : bool
        Every fit target met (``|r| <= 1``) at the answer: measured, not an optimiser flag.
    requested, evaluated : int
        Points asked for (memo hits included) and points the model computed, this run.
    search_requested : int
        Points the search (global and polish) asked for.
    first_met : int or None
        Points the search had asked for when every fit target was first met.
    seed, budget : int
        The search's settings.
    """

    targets: tuple[TargetRow, ...]
    parameters: tuple[ParameterRow, ...]
    sensitivity: np.ndarray
    conflict: Conflict | None
    converged: bool
    requested: int
    evaluated: int
    search_requested: int
    first_met: int | None
    seed: int
    budget: int

    @property
    def values(self) -> dict[str, float]:
        """The calibrated parameter values, name -> value in its unit."""
        return {p.name: p.value for p in self.parameters}

    @property
    def pins(self) -> dict[str, tuple[str, ...]]:
        """Target name -> the parameters that pin it (|sensitivity| >= 10 % of its row's max)."""
        return {t.name: t.pinned_by for t in self.targets}

    @property
    def worst_fit(self) -> float:
        """The largest fit ``|r|`` at the answer."""
        return max(abs(t.residual) for t in self.targets if t.role == "fit")

    def as_table(self) -> tuple[tuple[str, ...], list[tuple[object, ...]]]:
        """Header and rows of the per-target table (plain tuples, for any table printer)."""
        header = ("target", "role", "paper", "model", "unit", "r", "met", "pinned by", "source")
        rows: list[tuple[object, ...]] = [
            (
                t.name,
                t.role,
                t.shown,
                t.model,
                t.unit,
                round(t.residual, 3),
                "yes" if t.met else "NO",
                ", ".join(t.pinned_by) or "-",
                t.source,
            )
            for t in self.targets
        ]
        return header, rows

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready document (non-finite numbers as None)."""

        def num(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "converged": self.converged,
            "worst_fit_residual": num(self.worst_fit),
            "targets": [
                {
                    **t.__dict__,
                    "model": num(t.model),
                    "residual": num(t.residual),
                    "pinned_by": list(t.pinned_by),
                }
                for t in self.targets
            ],
            "parameters": [p.__dict__ for p in self.parameters],
            "sensitivity": [[num(x) for x in row] for row in self.sensitivity.tolist()],
            "conflict": None
            if self.conflict is None
            else {
                "targets": [self.conflict.target_a, self.conflict.target_b],
                "front": [list(p) for p in self.conflict.front],
                "finding": self.conflict.finding,
            },
            "requested": self.requested,
            "evaluated": self.evaluated,
            "search_requested": self.search_requested,
            "first_met": self.first_met,
            "seed": self.seed,
            "budget": self.budget,
        }

    def to_json(self) -> str:
        """`to_dict` as indented JSON text."""
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)


def _pins(row: np.ndarray, names: Sequence[str]) -> tuple[str, ...]:
    mag = np.abs(row)
    if not np.any(np.isfinite(mag)) or np.nanmax(mag) <= 0.0:
        return ()
    top = np.nanmax(mag)
    return tuple(
        n for n, s in zip(names, mag, strict=True) if np.isfinite(s) and s >= PIN_SHARE * top
    )


def build_result(
    problem: CalibrationProblem,
    u: Sequence[float],
    model: np.ndarray,
    sensitivity: np.ndarray,
    conflict: Conflict | None,
    *,
    requested: int,
    evaluated: int,
    search_requested: int,
    first_met: int | None,
    seed: int,
    budget: int,
) -> CalibrationResult:
    """Assemble a `CalibrationResult` from the answer ``u`` (n,) and its model vector (m,)."""
    r = problem.residuals(model)
    names = problem.parameter_names
    targets = tuple(
        TargetRow(
            name=t.name,
            role=t.role,
            value=t.value,
            tolerance=t.tolerance,
            unit=t.unit,
            model=float(model[i]),
            residual=float(r[i]),
            met=bool(np.isfinite(r[i]) and abs(r[i]) <= 1.0),
            pinned_by=_pins(sensitivity[i], names),
            source=t.source,
            side=t.side,
        )
        for i, t in enumerate(problem.targets)
    )
    params = tuple(
        ParameterRow(
            name=p.name,
            value=p.value(x),
            unit=p.unit,
            low=p.low,
            high=p.high,
            normalised=float(x),
            at_bound="low" if x <= AT_BOUND else "high" if x >= 1.0 - AT_BOUND else None,
            source=p.source,
        )
        for p, x in zip(problem.parameters, u, strict=True)
    )
    converged = all(targets[i].met for i in problem.fit_index)
    return CalibrationResult(
        targets,
        params,
        np.asarray(sensitivity, dtype=float),
        conflict,
        converged,
        requested,
        evaluated,
        search_requested,
        first_met,
        seed,
        budget,
    )
