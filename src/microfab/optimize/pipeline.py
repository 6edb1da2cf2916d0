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
   otherwise, nothing returned);
5. for stage 1 alone, `Stage1Check`: the command and the time-optimal command stretched
   to the same ``T`` (`microfab.optimize.baseline.stretched_time_optimal`), both run on
   the linear model from rest. Eq. (12) leaves the end free: stage 1's input ends moving
   (0.34 m/s on a 30 mm star at 3 m/s²) and the command must come to rest into the held
   end (`feasible_input`), which moves the last samples by up to 2.4 mm and the output's
   end by 0.5 mm (stage 2 refines that end on the networks; stage 1 alone cannot). When
   the linear model predicts stage 1's command worse (L2 or L∞) than the stretched one,
   the result says so (`ReferenceResult.warning`) and, with ``fallback`` (default), the
   stretched command is returned instead (issue 34 item 6: on the twin, that star's L∞
   550 µm against the stretched command's 279).

Before stage 2 (issue 43), `PredictionCheck` says what the networks' prediction is worth on
this contour: the RMS difference per axis between the networks' and the linear model's
outputs for stage 1's input, and the networks' recorded validation σ
(`microfab.optimize.models.recorded_validation_sigma`). When either exceeds μ a warning is
given (``warn``, and `ReferenceResult.warning`): stage 2 meets its constraints on the
networks' prediction (`microfab.optimize.stage2.Stage2Result.feasibility`), and a
prediction that is not good to μ cannot tell whether the machine will meet them.

The result keeps each stage's output and its wall time (the seed reports about 1 min and
1-4 h, §IV-C).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.identify.subspace_model import ContinuousModel
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Result, Stage1Settings, solve_stage1
from microfab.trajectory.base import Trajectory

__all__ = [
    "MODEL_RATE_HZ",
    "PredictionCheck",
    "ReferenceResult",
    "Stage1Check",
    "at_model_rate",
    "linear_output",
    "optimize_reference",
    "prediction_check",
    "training_warning",
]

MODEL_RATE_HZ = 400.0  # seed 002 §III-B: the networks run at 400 Hz
RUN_RATE_HZ = 1e4  # seed 002 Table I: the 10 kHz loop the command is played at
STAGES = ("1", "both")


@dataclass(frozen=True)
class Stage1Check:
    """Stage 1's command and the stretched time-optimal one on the linear model (step 5).

    Attributes
    ----------
    stage1, stretched : DeviationNorms
        Eqs. (16)-(18) of the linear model's output at ``t_1 … t_M``, m.
    worst_at_s : float
        Time of stage 1's largest deviation, s (from ``t_0``).
    duration_s : float
        ``T``, s.
    fell_back : bool
        Whether the stretched command was returned instead.
    """

    stage1: DeviationNorms
    stretched: DeviationNorms
    worst_at_s: float
    duration_s: float
    fell_back: bool

    @property
    def worse(self) -> bool:
        """Stage 1 predicted worse than the stretched command in L2 or L∞."""
        return self.stage1.l2 > self.stretched.l2 or self.stage1.linf > self.stretched.linf

    @property
    def warning(self) -> str | None:
        """What to tell the user when stage 1 is predicted worse; None otherwise."""
        if not self.worse:
            return None
        um = 1e6
        then = (
            "the time-optimal command stretched to T is used instead"
            if self.fell_back
            else "run stage 2 or use the stretched command"
        )
        return (
            f"stage 1's command is predicted worse on the linear model than the time-optimal "
            f"command stretched to the same T = {self.duration_s:.4g} s (L2 "
            f"{self.stage1.l2 * um:.1f} vs {self.stretched.l2 * um:.1f} µm, L∞ "
            f"{self.stage1.linf * um:.1f} vs {self.stretched.linf * um:.1f} µm, largest at "
            f"t = {self.worst_at_s:.3g} s): eq. (12) leaves the end free, so its input ends "
            f"moving and bringing it to rest moves the end; {then}"
        )


@dataclass(frozen=True)
class PredictionCheck:
    """What the networks' prediction is worth on one contour, checked before stage 2.

    Attributes
    ----------
    tolerance_m : float
        μ, m.
    rms_m : dict of str to float
        Per axis, the RMS of the networks' minus the linear model's output at ``t_1 …
        t_M`` for stage 1's input ``r_init``, played from rest like the command, m.
    validation_sigma_m : dict of str to float or None
        The networks' recorded validation σ per axis, m; None: none recorded.
    """

    tolerance_m: float
    rms_m: dict[str, float]
    validation_sigma_m: dict[str, float] | None = None

    def _over(self, values: dict[str, float] | None) -> dict[str, float]:
        return {a: v for a, v in (values or {}).items() if v > self.tolerance_m}

    @staticmethod
    def _axes(d: dict[str, float]) -> str:
        return ", ".join(f"{a} {v * 1e6:.1f} µm" for a, v in d.items())

    @property
    def sigma_warning(self) -> str | None:
        """The recorded σ part of `warning` alone (the same on every contour); or None."""
        sig = self._over(self.validation_sigma_m)
        if not sig:
            return None
        return (f"the networks' recorded validation σ {self._axes(sig)} exceeds the tolerance "
                f"μ = {self.tolerance_m * 1e6:g} µm: their prediction is good to about "
                f"{max(sig.values()) * 1e6:.0f} µm, and stage 2 meets eq. 14c on that "
                "prediction only")  # fmt: skip

    @property
    def rms_over_tolerance(self) -> bool:
        """An axis's RMS difference between the networks and the linear model exceeds μ."""
        return bool(self._over(self.rms_m))

    @property
    def warning(self) -> str | None:
        """The warning when an RMS difference or a recorded σ exceeds μ; None otherwise."""
        sig, rms = self._over(self.validation_sigma_m), self._over(self.rms_m)
        if not sig and not rms:
            return None
        mu = self.tolerance_m * 1e6
        why = []
        if sig:
            why.append(f"their recorded validation σ {self._axes(sig)} exceeds μ = {mu:g} µm")
        if rms:
            why.append(f"on stage 1's input they and the linear model differ by RMS "
                       f"{self._axes(rms)} (> μ = {mu:g} µm)")  # fmt: skip
        worth = max([*sig.values(), *rms.values()]) * 1e6
        return (
            f"the networks' prediction is good to about {worth:.0f} µm, not to the tolerance: "
            + "; ".join(why)
            + ". Stage 2 meets eq. 14c on the prediction only: the machine's deviation may "
            "differ from the predicted one by that much"
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, with the warnings and ``rms_over_tolerance``."""
        return {"tolerance_m": self.tolerance_m, "rms_m": dict(self.rms_m),
                "validation_sigma_m": self.validation_sigma_m,
                "rms_over_tolerance": self.rms_over_tolerance, "warning": self.warning,
                "sigma_warning": self.sigma_warning}  # fmt: skip


def prediction_check(
    linear: ContinuousModel,
    networks: Any,
    r: np.ndarray,
    rest: np.ndarray,
    tolerance_m: float,
    validation_sigma_m: dict[str, float] | None = None,
) -> PredictionCheck:
    """`PredictionCheck` of the 400 Hz input ``r`` (M, 2), m, from ``rest`` (2,), m.

    Both models see the same input: the networks its 400 Hz samples from rest
    (`microfab.optimize.ann_torch.NetworkMap.predict`), the linear model the 10 kHz command
    through them (`microfab.optimize.command.command_from_input`, not checked against the
    limits: stage 1's raw input), held, sampled at ``t_1 … t_M``.
    """
    from microfab.optimize.ann_torch import NetworkMap
    from microfab.optimize.command import LEAD, command_from_input

    r = np.asarray(r, dtype=float)
    m = r.shape[0]
    q = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    pos = command_from_input(r, rest=rest, rate_hz=MODEL_RATE_HZ, run_rate_hz=RUN_RATE_HZ)
    pos = np.vstack([pos, np.repeat(pos[-1:], (m + LEAD + 1) * q, axis=0)])  # held
    lin = at_model_rate(linear_output(linear, pos), m, LEAD)
    net = np.asarray(NetworkMap(networks).predict(r, rest), dtype=float)[:m]
    rms = np.sqrt(np.mean((net - lin) ** 2, axis=0))
    return PredictionCheck(tolerance_m=tolerance_m, rms_m={"x": float(rms[0]), "y": float(rms[1])},
                           validation_sigma_m=validation_sigma_m)  # fmt: skip


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
    stage1_check : Stage1Check or None
        Stage 1 alone: its command against the stretched one on the linear model (when
        ``fell_back``, ``r`` and ``command`` are the stretched command's).
    prediction : PredictionCheck or None
        What the networks' prediction is worth on this contour (when networks were given).
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
    stage1_check: Stage1Check | None = None
    prediction: PredictionCheck | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the user should be told, in order.

        Stage 1 alone predicted worse than the stretched command (`Stage1Check`); the
        networks' prediction not good to μ (`PredictionCheck`); stage 2 infeasible
        (`microfab.optimize.stage2.Stage2Result.describe`).
        """
        out = [
            None if self.stage1_check is None else self.stage1_check.warning,
            None if self.prediction is None else self.prediction.warning,
            None if self.stage2 is None or self.stage2.feasible else self.stage2.describe(),
        ]
        return tuple(w for w in out if w)

    @property
    def warning(self) -> str | None:
        """`warnings` joined by "; ", or None."""
        return "; ".join(self.warnings) or None

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
    fallback: bool = True,
    validation_sigma_m: dict[str, float] | None = None,
    warn: Callable[[str], None] | None = None,
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
    fallback : bool
        Stage 1 alone: return the stretched time-optimal command when the linear model
        predicts it better (step 5); else only warn.
    validation_sigma_m : dict of str to float, optional
        The networks' recorded validation σ per axis, m (`PredictionCheck`).
    warn : callable, optional
        ``warn(text)``: the prediction's warning, given before stage 2 runs.

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
    pred = None
    if networks is not None:
        pred = prediction_check(linear, networks, r_init, rest, problem.tolerance_m,
                                validation_sigma_m)  # fmt: skip
        if pred.warning is not None and warn is not None:
            warn(pred.warning)
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
    t0 = time.perf_counter()
    command = checked_command(r, rest=rest, limits=problem.limits)
    wall["command"] = time.perf_counter() - t0
    check = None
    if stage == "1":
        t0 = time.perf_counter()
        check, alt = _check_stage1(problem, linear, command, rest, st1.duration, r.shape[0])
        if check is not None and check.worse and fallback:
            r, command = alt
            check = dataclasses.replace(check, fell_back=True)
        wall["check"] = time.perf_counter() - t0
        if networks is not None:
            from microfab.optimize.ann_torch import NetworkMap

            predicted = NetworkMap(networks).predict(r, rest)[: r.shape[0]]
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
        stage1_check=check,
        prediction=pred,
    )


def linear_output(
    linear: ContinuousModel, command: np.ndarray, rate_hz: float = RUN_RATE_HZ
) -> np.ndarray:
    """The linear model's output for a command played from rest at its first sample.

    Parameters
    ----------
    linear : ContinuousModel
        Eq. (6), m.
    command : numpy.ndarray
        Set-points, shape (n, 2), m, held for each sample (the machine's loop).
    rate_hz : float
        The command's rate, Hz.

    Returns
    -------
    numpy.ndarray
        Shape (n, 2), m: eq. (6) sampled with a zero-order hold at ``1 / rate_hz``.
    """
    import scipy.linalg

    from microfab.identify.subspace_fit import simulate_ss

    a, b = np.asarray(linear.a), np.asarray(linear.b)
    n, m = a.shape[0], b.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = a, b
    e = scipy.linalg.expm(big / rate_hz)
    u = np.asarray(command, dtype=float)
    x0 = -np.linalg.solve(a, b @ u[0])  # at rest under the first set-point
    return simulate_ss(e[:n, :n], e[:n, n:], linear.c, linear.d, u, x0)


def at_model_rate(y: np.ndarray, m: int, lead: int = 0, tail: int = 0) -> np.ndarray:
    """Rows at ``t_1 … t_{M+tail}`` of a run at `RUN_RATE_HZ` whose sample ``lead q`` is ``t_0``.

    The one row selection of eqs. (13)-(18) (``q`` = 25 run samples per 400 Hz instant):
    the pipeline's checks on the linear model, the reference job's scores on the twin
    (``tail`` = `microfab.machines.xy_stage.reference.TAIL`) and ``stage score``. Rows
    past the run's end repeat its last sample.
    """
    q = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    idx = (np.arange(1, m + tail + 1) + lead) * q
    return y[np.minimum(idx, y.shape[0] - 1)]


def _check_stage1(
    problem: ContourProblem,
    linear: ContinuousModel,
    command: Trajectory,
    rest: np.ndarray,
    duration: float,
    m: int,
) -> tuple[Stage1Check | None, tuple[np.ndarray, Trajectory] | None]:
    """Step 5: the norms of both commands on the linear model, and the stretched one.

    None for both when no stretched command fits (``T`` below the time-optimal one under
    Table I, or its input outside the command's bounds).
    """
    from microfab.core.limits import LimitViolation
    from microfab.optimize.baseline import stretched_time_optimal
    from microfab.optimize.command import LEAD, checked_command
    from microfab.optimize.stage2 import feasible_input

    q = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    try:
        stretched = stretched_time_optimal(problem.path, duration, problem.limits, RUN_RATE_HZ)
        r_alt = np.asarray(stretched, dtype=float)[::q][:m]
        if r_alt.shape[0] < m:
            r_alt = np.vstack([r_alt, np.repeat(r_alt[-1:], m - r_alt.shape[0], axis=0)])
        r_alt = feasible_input(r_alt, rest, problem.limits)
        alt = checked_command(r_alt, rest=rest, limits=problem.limits)
    except (ValueError, LimitViolation):
        return None, None
    norms = []
    worst = 0.0
    for k, cmd in enumerate((command, alt)):
        pos = np.asarray(cmd.position, dtype=float)
        pos = np.vstack([pos, np.repeat(pos[-1:], (m + LEAD + 1) * q, axis=0)])  # held
        y = at_model_rate(linear_output(linear, pos), m, LEAD)
        norms.append(DeviationNorms.of(problem.path, y))
        if k == 0:
            from microfab.optimize.metrics import deviations

            worst = float(np.argmax(deviations(problem.path, y)) + 1) / MODEL_RATE_HZ
    check = Stage1Check(
        stage1=norms[0], stretched=norms[1], worst_at_s=worst, duration_s=duration,
        fell_back=False,
    )  # fmt: skip
    return check, (r_alt, alt)
