"""Both stages of seed 002 (Fig. 4) on one contour: from the drawing to a checked command.

`optimize_reference` runs

1. stage 1 (`solve_stage1`, eqs. 8-12) on the linear model: ``T``, ``s(t)`` and ``ρ``;
2. eq. (13): ``t_i = i Δt`` at the network rate (400 Hz), ``i = 0 … M``,
   ``M = ceil(T / Δt)``; the target ``Ξ̄_i = Ξ(s(t_i))`` and stage 1's input ``ρ(t_i)``;
3. stage 2 (`solve_stage2`, eqs. 13-14) on the networks from ``r_i = ρ(t_i)``,
   ``i = 0 … M-1`` (``r_i`` moves the output at ``i + 1``), the stage at rest on ``Ξ_0``
   before the start; skipped for ``stage="1"``;
4. the 10 kHz command through `microfab.optimize.command.checked_command`, checked
   against Table I before it is returned (a `microfab.core.limits.LimitViolation`
   otherwise, nothing returned).

The result keeps each stage's output and its wall time (the seed reports about 1 min and
1-4 h, §IV-C).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Result, Stage1Settings, solve_stage1
from microfab.trajectory.base import Trajectory

__all__ = ["MODEL_RATE_HZ", "ReferenceResult", "optimize_reference", "training_warning"]

MODEL_RATE_HZ = 400.0  # seed 002 §III-B: the networks run at 400 Hz
STAGES = ("1", "both")


@dataclass(frozen=True, eq=False)
class ReferenceResult:
    """The optimised reference of one contour.

    Attributes
    ----------
    problem : ContourProblem
    stage1 : Stage1Result
    t : numpy.ndarray
        ``t_i``, shape (M + 1,), s (eq. 13).
    target : numpy.ndarray
        ``Ξ̄_i``, shape (M + 1, 2), m; row 0 is the start ``Ξ_0``.
    r_init : numpy.ndarray
        Stage 1's input at ``t_0 … t_{M-1}``, shape (M, 2), m.
    r : numpy.ndarray
        The final 400 Hz input, (M, 2), m: stage 2's, or for stage 1 only ``r_init`` made
        a valid command (the nearest input within the command's bounds: it comes to rest
        into the held end).
    rest : numpy.ndarray
        Where the stage rests before the start, (2,), m.
    command : Trajectory
        The 10 kHz command (checked against the problem's limits).
    stage2 : object or None
        `microfab.optimize.stage2.Stage2Result` when stage 2 ran.
    predicted : numpy.ndarray or None
        The networks' output at ``t_1 … t_M`` for ``r``, (M, 2), m, when networks were given.
    wall_s : dict of str to float
        "stage1", "stage2", "command".
    """

    problem: ContourProblem
    stage1: Stage1Result
    t: np.ndarray
    target: np.ndarray
    r_init: np.ndarray
    r: np.ndarray
    rest: np.ndarray
    command: Trajectory
    stage2: Any = None
    predicted: np.ndarray | None = None
    wall_s: dict[str, float] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """``T`` of stage 1, s."""
        return self.stage1.duration

    @property
    def m(self) -> int:
        """``M``."""
        return int(self.r.shape[0])


def training_warning(networks: Any, a_max: float) -> str | None:
    """A warning when ``a_max`` exceeds the largest command acceleration the networks saw.

    Seed 002 §V-B: beyond its training data the model "over exploits" and the simulated
    deviation is "overly optimistic". Not an error (issue 18).
    """
    seen = (getattr(networks, "info", {}) or {}).get("command_accel_max_m_s2")
    if not seen:
        return None
    top = max(float(v) for v in seen.values())
    if a_max <= top:
        return None
    return (
        f"a_max {a_max:g} m/s² is beyond the networks' training data (commands up to "
        f"{top:.2g} m/s²): the predicted deviation is likely optimistic (seed 002 §V-B)"
    )


def optimize_reference(
    problem: ContourProblem,
    linear: ContinuousModel,
    networks: Any = None,
    *,
    stage: str = "both",
    stage1: Stage1Settings | Stage1Result | None = None,
    stage2: Any = None,
    checkpoint: str | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> ReferenceResult:
    """Run the stages on ``problem`` (module docstring).

    Parameters
    ----------
    problem : ContourProblem
    linear : ContinuousModel
        Eq. (6), m.
    networks : microfab.identify.ann.AnnModel, optional
        The per-axis networks (eq. 7); required for ``stage="both"``.
    stage : {"both", "1"}
    stage1 : Stage1Settings or Stage1Result, optional
        Settings, or a stage-1 result to reuse (its problem must be this one).
    stage2 : microfab.optimize.stage2.Stage2Settings, optional
    checkpoint : str, optional
        Stage 2's checkpoint file (resumed when it matches).
    progress : callable, optional
        ``progress(iteration, cost)`` of stage 2.

    Returns
    -------
    ReferenceResult

    Raises
    ------
    ValueError
        An unknown stage, or stage 2 without networks.
    microfab.optimize.stage1.Stage1Error
        Stage 1 infeasible or not converged.
    microfab.core.limits.LimitViolation
        The command would break the problem's limits.
    """
    if stage not in STAGES:
        raise ValueError(f"stage must be one of {', '.join(STAGES)}, got {stage!r}")
    if stage == "both" and networks is None:
        raise ValueError("stage 2 needs the networks: give a model directory with ann/model")
    from microfab.optimize.command import checked_command

    wall: dict[str, float] = {}
    t0 = time.perf_counter()
    if isinstance(stage1, Stage1Result):
        st1 = stage1
    else:
        st1 = solve_stage1(problem, linear, stage1)
    wall["stage1"] = time.perf_counter() - t0
    t, s, rho = st1.sample(MODEL_RATE_HZ)
    target = problem.path.point(s)
    rest = np.asarray(problem.path.start, dtype=float)
    r_init = rho[:-1]
    r = r_init
    st2 = None
    predicted = None
    if stage == "both":
        from microfab.optimize.stage2 import solve_stage2

        t0 = time.perf_counter()
        st2 = solve_stage2(
            target[1:],
            r_init,
            networks,
            rest=rest,
            tolerance_m=problem.tolerance_m,
            v_max=problem.v_max,
            a_max=problem.a_max,
            limits=problem.limits,
            settings=stage2,
            checkpoint=checkpoint,
            progress=progress,
        )
        wall["stage2"] = time.perf_counter() - t0
        r = np.asarray(st2.r, dtype=float)
        predicted = np.asarray(st2.phi, dtype=float)
    else:
        from microfab.optimize.stage2 import feasible_input

        r = feasible_input(r_init, rest, problem.limits)
        if networks is not None:
            from microfab.optimize.ann_torch import NetworkMap

            predicted = NetworkMap(networks).predict(r, rest)[: r.shape[0]]
    t0 = time.perf_counter()
    command = checked_command(r, rest=rest, limits=problem.limits)
    wall["command"] = time.perf_counter() - t0
    return ReferenceResult(
        problem=problem,
        stage1=st1,
        t=t,
        target=target,
        r_init=r_init,
        r=r,
        rest=rest,
        command=command,
        stage2=st2,
        predicted=predicted,
        wall_s=wall,
    )
