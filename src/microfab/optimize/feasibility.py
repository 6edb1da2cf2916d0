"""What an optimiser reached: its hard constraints measured on the answer it returns.

A solver's own flag (IPOPT's ``Solve_Succeeded``, a Gauss-Newton step below its
tolerance) says that it stopped, not that its answer meets the problem's constraints: an
exact-penalty method stops happily with the penalised rows broken (issue 43: stage 2
said "converged" with seed 002 eq. 14c exceeded by 23-752 µm). Both stages of seed 002
therefore measure every hard constraint on the solution they return
(`microfab.optimize.stage1`, `microfab.optimize.stage2`) as a `Residual` per constraint —
its largest left-hand side, the bound, the excess, where (sample or knot index and time)
and how many rows exceed it — gathered in a `Feasibility`; "converged" is said only when
every one holds within `FEASIBILITY_RTOL` of its bound.

The bounds are the seed's (seed 002 eqs. 12e-12j for stage 1, 14c-14f for stage 2, with
μ, ``v_max``, ``a_max`` and the workspace of the problem); the numerical slack with which
a row still "holds" is ours (`FEASIBILITY_RTOL`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

__all__ = ["FEASIBILITY_RTOL", "Feasibility", "Residual", "finite_or_none", "measure"]

#: A row holds when it exceeds its bound by at most this share of the bound (lengths: of
#: μ). Assumed 1e-3: 0.02 µm of μ = 20 µm, 1 mm/s² of a_max = 1 m/s², 1.5 mm/s of v_max;
#: far below what the stage resolves (its encoder noise is 2 µm, seed 002 eq. 3) and far
#: above the solvers' own precision (IPOPT's tolerance 1e-8 on the scaled stage-1 rows,
#: the stage-2 QP's rows to about 1e-4 µm, `microfab.optimize.stage2_qp`).
FEASIBILITY_RTOL = 1e-3


@dataclass(frozen=True)
class Residual:
    """One hard constraint measured on a solution.

    Attributes
    ----------
    constraint : str
        Its name: "tolerance", "along-track", "workspace", "velocity", "acceleration",
        "dynamics".
    equation : str
        The seed's equation, e.g. "14c" (seed 002).
    unit : str
        Unit of ``largest``, ``bound``, ``excess`` and ``allowed`` ("µm", "m/s", "m/s²").
    largest : float
        The largest left-hand side over the rows (e.g. the largest deviation), in ``unit``.
    bound : float
        The right-hand side (μ, ``v_max``, ``a_max``; 0 for the workspace's signed
        distance outside and for equalities), in ``unit``.
    excess : float
        ``largest - bound``; negative: the margin of the tightest row, in ``unit``.
    allowed : float
        The excess still counted as holding (`FEASIBILITY_RTOL` of the bound), in ``unit``.
    scale : float
        What ``excess`` is measured against when constraints are compared
        (`Feasibility.score`): the bound, or μ for the length rows of bound 0, in ``unit``.
    sample : int
        Index of the row's sample (stage 2: ``i`` of ``φ_i``; stage 1: the knot ``k``)
        where the excess is largest.
    time_s : float
        Its time from the start ``t_0``, s.
    axis : str or None
        "x" or "y" for per-axis rows, None for rows of both axes (the Euclidean 14c).
    rows : int
        Rows measured.
    rows_over : int
        Rows whose excess is above ``allowed``.
    violation : float
        The L1 violation: the sum of those rows' excesses in units of ``scale`` (0 when
        it holds), the measure of the seed's exact L1 penalty (seed 002 §IV-B).
    """

    constraint: str
    equation: str
    unit: str
    largest: float
    bound: float
    excess: float
    allowed: float
    scale: float
    sample: int
    time_s: float
    axis: str | None
    rows: int
    rows_over: int
    violation: float = 0.0

    @property
    def holds(self) -> bool:
        """Every row within ``allowed`` of its bound."""
        return self.excess <= self.allowed

    @property
    def relative(self) -> float:
        """The excess beyond ``allowed`` in units of ``scale`` (0 when it holds)."""
        return 0.0 if self.holds else self.excess / self.scale

    def describe(self) -> str:
        """One phrase: constraint, equation, excess with unit, where, share of rows."""
        where = f"sample {self.sample}" + (f" ({self.axis})" if self.axis else "")
        share = 100.0 * self.rows_over / max(self.rows, 1)
        if self.holds:
            return (f"eq. {self.equation} ({self.constraint}) holds: largest {self.largest:.4g} "
                    f"{self.unit} against {self.bound:.4g} {self.unit}")  # fmt: skip
        return (
            f"eq. {self.equation} ({self.constraint}) broken by {self.excess:.4g} {self.unit} "
            f"beyond {self.bound:.4g} {self.unit} at {where}, t = {self.time_s:.4g} s; "
            f"{self.rows_over} of {self.rows} rows ({share:.0f} %)"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, with ``holds``; a non-finite number (a NaN prediction) as None."""
        d = {k: finite_or_none(v) if isinstance(v, float) else v for k, v in asdict(self).items()}
        return {**d, "holds": self.holds}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Residual:
        """Inverse of `as_dict` (None read back as infinity)."""
        nums = ("largest", "bound", "excess", "allowed", "scale", "time_s", "violation")
        return cls(**{k: math.inf if v is None and k in nums else v for k, v in d.items()
                      if k != "holds"})  # fmt: skip


def finite_or_none(x: float) -> float | None:
    """``x``, or None when it is not finite (strict JSON has no NaN or infinity)."""
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True)
class Feasibility:
    """Every hard constraint of one solution (module docstring)."""

    residuals: tuple[Residual, ...]

    @property
    def feasible(self) -> bool:
        """Every constraint holds within its allowed excess."""
        return all(r.holds for r in self.residuals)

    @property
    def worst(self) -> Residual | None:
        """The broken constraint of the largest relative excess; None when feasible."""
        broken = [r for r in self.residuals if not r.holds]
        return max(broken, key=lambda r: r.relative) if broken else None

    @property
    def score(self) -> float:
        """The total L1 violation (`Residual.violation` summed); 0 when feasible.

        The "least violating" of several solutions is the one of the smallest score: the
        violation the exact L1 penalty measures (seed 002 §IV-B), each row in units of its
        bound. Not the largest single excess: on the twin's networks that is one row at the
        held end, and it preferred a start broken on 93 % of its rows to an iterate broken
        on a few (letter u at 3 m/s²).
        """
        return float(sum(r.violation for r in self.residuals))

    def describe(self) -> str:
        """The broken constraints, the worst first, or "every hard constraint holds"."""
        broken = sorted((r for r in self.residuals if not r.holds), key=lambda r: -r.relative)
        if not broken:
            return "every hard constraint holds"
        return "; ".join(r.describe() for r in broken)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: ``feasible``, ``worst`` (or None) and every residual by name."""
        worst = self.worst
        return {
            "feasible": self.feasible,
            "worst": None if worst is None else worst.as_dict(),
            "residuals": {r.constraint: r.as_dict() for r in self.residuals},
        }


def measure(
    constraint: str,
    equation: str,
    unit: str,
    values: np.ndarray,
    bound: float,
    *,
    samples: np.ndarray,
    times: np.ndarray,
    scale: float | None = None,
    axes: np.ndarray | None = None,
) -> Residual:
    """A `Residual` from the left-hand sides of a constraint's rows.

    Parameters
    ----------
    constraint, equation, unit : str
        As `Residual`.
    values : numpy.ndarray
        Left-hand side per row, shape (n,), in ``unit`` (``value ≤ bound`` holds).
    bound : float
        Right-hand side, in ``unit``.
    samples : numpy.ndarray
        Sample (or knot) index per row, shape (n,).
    times : numpy.ndarray
        Time per row, shape (n,), s.
    scale : float, optional
        `Residual.scale`; default ``bound``. Needed (positive) when ``bound`` is 0.
    axes : numpy.ndarray, optional
        "x" / "y" per row, shape (n,); None: rows of both axes.

    Returns
    -------
    Residual
        The allowed excess is `FEASIBILITY_RTOL` × ``scale``.
    """
    v = np.asarray(values, dtype=float).ravel()
    sc = float(bound if scale is None else scale)
    if not sc > 0:
        raise ValueError(f"the scale of {constraint} must be positive, got {sc!r}")
    allowed = FEASIBILITY_RTOL * sc
    if v.size == 0:
        return Residual(constraint, equation, unit, float(bound), float(bound), 0.0, allowed,
                        sc, 0, 0.0, None, 0, 0)  # fmt: skip
    bad = ~np.isfinite(v)
    k = int(np.argmax(bad)) if bad.any() else int(np.argmax(v))
    largest = float("inf") if bad.any() else float(v[k])
    beyond = bad | (v - bound > allowed)
    over = int(np.count_nonzero(beyond))
    l1 = math.inf if bad.any() else float(np.sum(v[beyond] - bound) / sc)
    return Residual(
        constraint=constraint,
        equation=equation,
        unit=unit,
        largest=largest,
        bound=float(bound),
        excess=largest - float(bound),
        allowed=allowed,
        scale=sc,
        sample=int(np.asarray(samples).ravel()[k]),
        time_s=float(np.asarray(times).ravel()[k]),
        axis=None if axes is None else str(np.asarray(axes).ravel()[k]),
        rows=int(v.size),
        rows_over=over,
        violation=l1,
    )
