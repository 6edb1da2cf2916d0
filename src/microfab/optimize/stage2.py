"""Stage 2 of seed 002: the 400 Hz input refined on the networks (eqs. 13-14).

The timing is stage 1's (eq. 13: the target ``Ξ̄_i = Ξ(s(t_i))`` at ``t_i = iΔt``); the
variables are the inputs ``r_0 … r_{M-1}`` (``r_{i-1}`` is the newest input of ``φ_i``,
eq. 7); before the start the stage rests on ``rest`` and after the end ``r_{M-1}`` is
held (the tail, `NetworkMap`). Problem (14), in µm:

* cost (14a): ``Σ_{i=1..M} ‖φ_i - Ξ̄_i‖²``;
* tolerance (14c) as an exact L1 penalty with slacks (seed §IV-B): ``‖φ_i - Ξ̄_i‖ ≤ μ +
  s_i``, ``s ≥ 0``, ``w Σ s_i``. 14c writes ``|·|`` of a vector: the Euclidean norm
  (default; inside the subproblem an inscribed octagon, so a step that meets it meets the
  circle) or, with ``norm="axis"``, each axis's absolute value;
* 14d-14f (workspace, ``|Δφ|∞ ≤ v_max Δt``, ``|Δ²φ|∞ ≤ a_max Δt²``, a_max bounding the
  *output* as the equations read) as L1 penalties too, with a larger weight: a network's
  output is not exactly smooth, so these can be infeasible at the start;
* the machine's limits on the *command* (Table I, through the 10 kHz spline of
  `microfab.optimize.command`) as hard bounds on ``Δr`` and ``Δ²r`` (`input_bounds`),
  including the steps from rest and into the held end.

**Gauss-Newton with a trust region.** Each iteration linearises ``φ(r + δ) ≈ φ + J δ``
(`NetworkMap.linearize`: the Jacobian from one backward pass, banded, per axis), and
solves the convex QP in ``δ`` and the residuals ``e = φ + J δ - Ξ̄`` (so the Hessian is
diagonal and ``J`` only appears in equality rows) with PIQP (`stage2_qp`: the solver
built once for the matrix's pattern, its values passed per step; IPOPT, the solver before
issue 34, with ``qp="ipopt"``: 10-20x slower, the same steps). The step's Jacobian keeps the
band of recent inputs that holds 99 % of its mass (`Stage2Settings.band_mass`). A step
is taken only if the true merit (cost + penalties, through the networks) decreases; the
trust region grows after a good step and shrinks after a bad one. The merit therefore
never rises above its start (the input made feasible for the command's bounds first, by
the nearest such input). Exact Hessians through the network are avoided: one took about
72 s per evaluation in a trial (issue 18).

**What it reached** (issue 43). The stop (a step below ``tol``, a zero step, a collapsed
trust region) is not convergence: 14c-14f are measured on the networks' prediction of the
returned input (`_Problem.feasibility`, `microfab.optimize.feasibility`), and the result
is "converged" only when the solver stopped by itself and every one holds. Otherwise the
least violating accepted iterate (smallest `Feasibility.score`) is returned, marked
"infeasible", with the constraint, its largest residual and its sample
(`Stage2Result.describe`).

Checkpoints (`microfab.optimize.stage2_state`): with ``checkpoint`` a file path, the
iterate, the trust radius, the iteration count, the history and the least violating
iterate are saved atomically every ``checkpoint_every`` accepted iterations, keyed by a
fingerprint of the inputs and settings; a rerun with the same ones resumes (another
fingerprint is refused, naming the file). A Ctrl-C inside the QP's solver is a
KeyboardInterrupt, not a failed QP (`microfab.optimize.stage2_qp`), so the last checkpoint
stays as it was and a rerun resumes from it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from microfab.core.limits import MachineLimits
from microfab.optimize.ann_torch import NetworkMap
from microfab.optimize.command import input_bounds
from microfab.optimize.feasibility import Feasibility, finite_or_none, measure
from microfab.optimize.stage2_state import Best, fingerprint, load_state, save_iterate

__all__ = ["STOPS", "Stage2Result", "Stage2Settings", "feasible_input", "solve_stage2"]

_UM = 1e6  # scaled unit: µm per m
NORMS = ("euclidean", "axis")
#: The step's QP solvers (`microfab.optimize.stage2_qp`).
QP_SOLVERS = ("piqp", "ipopt")
#: Why stage 2's iterations end (`Stage2Result.stop`); all but "max_iter" are the solver
#: stopping by itself (`Stage2Result.stopped`).
STOPS = ("small gain", "zero step", "no step", "trust region", "max_iter")
#: Settings that stop or pace the iterations but do not change their course: a rerun with
#: more iterations resumes the checkpoint.
_NOT_FINGERPRINTED = frozenset({"max_iter", "tol", "checkpoint_every", "qp", "threads"})


@dataclass(frozen=True)
class Stage2Settings:
    """Settings of stage 2 (module docstring).

    Parameters
    ----------
    norm : {"euclidean", "axis"}
        The norm of 14c.
    penalty : float
        Weight of the tolerance slacks, µm (µm² of cost per µm of violation). Assumed
        1e3: the cost's gradient at the bound is ``2 μ`` = 40 µm for μ = 20 µm, so the
        penalty is exact with a wide margin.
    limit_penalty : float
        Weight of the slacks of 14d-14f, µm. Assumed 1: the networks' predicted output
        has 400 Hz second differences far above ``a_max Δt²`` (6.25 µm at 1 m/s²) where
        it turns (their σ on this twin is 20-40 µm, the seed's 3-6 µm), so 14f as a hard
        constraint was infeasible, and a weight like the tolerance's made the refinement
        chase the prediction's jitter instead of the contour (letter r at 1 m/s²: the
        merit rose on every step); the violations are reported.
    max_iter : int
        Gauss-Newton iterations (accepted or not).
    tol : float
        Stop when an accepted step lowers the merit by less than this share of it.
    trust_um : float
        Initial trust radius, max-norm of the step, µm (assumed 50 µm).
    checkpoint_every : int
        Accepted iterations between checkpoints.
    band_mass : float
        The step's Jacobian keeps the most recent inputs that hold this share of
        ``Σ|∂φ/∂r|`` at the start (the band is then fixed), in (0, 1]; 1 keeps all ``h``.
        Assumed 0.99: on the twin's networks 99 % lies within the last ~30 of 200 inputs,
        and the QP's factorisation cost falls with the square of the band. Steps are
        still accepted on the true merit, so the result stays monotone.
    rate_hz : float
        The networks' rate, Hz.
    qp : {"piqp", "ipopt"}
        The solver of the step's QP (`microfab.optimize.stage2_qp`): PIQP (default) or
        IPOPT (the solver before issue 34, kept for comparison). Both solve the same QP; the
        steps agree to about 1e-4 µm, so the setting is not part of the checkpoint's key.
    threads : int or None
        Torch threads of the networks' evaluations (`NetworkMap`); None: torch's count as
        it stands (the setting before issue 34). Default 1 (`microfab.optimize.ann_torch`).
    """

    norm: str = "euclidean"
    penalty: float = 1e3
    limit_penalty: float = 1.0
    max_iter: int = 20
    tol: float = 1e-3
    trust_um: float = 50.0
    checkpoint_every: int = 3
    band_mass: float = 0.99
    rate_hz: float = 400.0
    qp: str = "piqp"
    threads: int | None = 1

    def __post_init__(self) -> None:
        if self.norm not in NORMS:
            raise ValueError(f"norm must be one of {', '.join(NORMS)}, got {self.norm!r}")
        if self.qp not in QP_SOLVERS:
            raise ValueError(f"qp must be one of {', '.join(QP_SOLVERS)}, got {self.qp!r}")
        for name in ("penalty", "limit_penalty", "trust_um", "rate_hz"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        for name in ("max_iter", "checkpoint_every"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        t = self.threads
        if t is not None and (isinstance(t, bool) or not isinstance(t, int) or t < 1):
            raise ValueError(f"threads must be an integer >= 1 or None, got {t!r}")
        if not (isinstance(self.band_mass, (int, float)) and 0 < self.band_mass <= 1):
            raise ValueError(f"band_mass must lie in (0, 1], got {self.band_mass!r}")
        if not (math.isfinite(self.tol) and self.tol >= 0):
            raise ValueError(f"tol must be >= 0, got {self.tol!r}")


@dataclass(frozen=True, eq=False)
class Stage2Result:
    """The refined input.

    Attributes
    ----------
    r : numpy.ndarray
        ``r_0 … r_{M-1}``, (M, 2), m.
    phi : numpy.ndarray
        Predicted ``φ_1 … φ_M``, (M, 2), m.
    phi_tail : numpy.ndarray
        Predicted output in the tail (input held), (tail, 2), m.
    target : numpy.ndarray
        ``Ξ̄_1 … Ξ̄_M``, (M, 2), m.
    cost_history : list of float
        The merit (cost 14a + penalties, µm²) at the start and after every accepted step.
    cost_start, cost_end : float
        Cost 14a alone (µm²) at the start (stage 1's input made feasible) and of the
        returned iterate.
    violation : dict of str to float
        Largest violation of the returned iterate: "tolerance" (µm beyond μ), "velocity"
        (m/s beyond v_max), "acceleration" (m/s² beyond a_max).
    iterations : int
        Gauss-Newton iterations.
    converged : bool
        True only when the solver stopped by itself (``tol``, a zero step or a collapsed
        trust region, not ``max_iter``) *and* every hard constraint 14c-14f holds on the
        networks' predicted output of the returned input (`feasibility`,
        `microfab.optimize.feasibility.FEASIBILITY_RTOL`); never from the stop alone.
    wall_s : float
    resumed_from : int
        Iterations done before a resume (0: fresh).
    info : dict
        ``norm``, ``penalty``, ``band`` (the Jacobian's kept lags, None: all) and ``qp``
        (the solver); in `summary`.
    phase_s : dict of str to float
        Wall time per phase, s (not in `summary`: bookkeeping): ``project_s`` (the start
        made feasible), ``networks_s`` (predictions and Jacobians), ``qp_s`` (the steps'
        QPs).
    feasibility : Feasibility or None
        14c-14f measured on ``phi`` (`_Problem.feasibility`): per constraint the largest
        residual, its sample and time, the rows beyond.
    stop : str
        Why the iterations ended (`STOPS`): "small gain" (an accepted step gained less
        than ``tol`` of the merit), "zero step" (the QP's step below 1e-9 µm), "no step"
        (the QP gave none), "trust region" (the radius fell below 1e-4 µm after rejected
        steps) or "max_iter". All but "max_iter" are the solver stopping by itself
        (`stopped`).
    score_history : list of float
        `Feasibility.score` of each iterate of ``cost_history`` (0: every constraint holds);
        NaN for the iterates before a resume from a checkpoint written before issue 43.
    returned : int
        Index in ``cost_history`` of the returned iterate: the last one, unless the last
        breaks a constraint; then the least violating accepted iterate (smallest
        `Feasibility.score`, the later one on a tie), which may be the start.
    """

    r: np.ndarray
    phi: np.ndarray
    phi_tail: np.ndarray
    target: np.ndarray
    cost_history: list[float]
    cost_start: float
    cost_end: float
    violation: dict[str, float]
    iterations: int
    converged: bool
    wall_s: float
    resumed_from: int = 0
    info: dict[str, Any] = field(default_factory=dict)
    phase_s: dict[str, float] = field(default_factory=dict)
    feasibility: Feasibility | None = None
    stop: str = "max_iter"
    returned: int = -1
    score_history: list[float] = field(default_factory=list)

    @property
    def stopped(self) -> bool:
        """The solver stopped by itself (`stop` is not "max_iter"; see ``converged``)."""
        return self.stop != "max_iter"

    @property
    def feasible(self) -> bool:
        """Every hard constraint 14c-14f holds on the returned input's prediction."""
        return self.feasibility is not None and self.feasibility.feasible

    @property
    def status(self) -> str:
        """The outcome: "converged", "infeasible" or "not converged".

        "infeasible": a hard constraint is broken on the returned iterate; "not converged":
        every one holds, but ``max_iter`` was reached or an earlier iterate is returned.
        """
        if not self.feasible:
            return "infeasible"
        return "converged" if self.converged else "not converged"

    def describe(self) -> str:
        """One line: the status and, when infeasible, each broken constraint."""
        if self.feasibility is None:
            return self.status
        last = len(self.cost_history) - 1
        which = (
            ""
            if self.returned in (-1, last)
            else (f" (returned: accepted iterate {self.returned} of {last}, the least violating)")
        )
        return f"stage 2 {self.status}{which}: {self.feasibility.describe()}"

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the stop, the status, 14c-14f measured (``feasibility``), costs."""
        return {
            "iterations": self.iterations,
            "converged": self.converged,
            "status": self.status,
            "stopped": self.stopped,
            "stop": self.stop,
            "returned_iterate": self.returned,
            "score_history": [finite_or_none(x) for x in self.score_history],
            "least_violating": self.returned not in (-1, len(self.cost_history) - 1),
            "feasibility": None if self.feasibility is None else self.feasibility.as_dict(),
            "merit_start": self.cost_history[0],
            "merit_end": self.cost_history[-1],
            "cost_start": self.cost_start,
            "cost_end": self.cost_end,
            "violation": self.violation,
            "wall_s": self.wall_s,
            "resumed_from": self.resumed_from,
            **self.info,
        }


class _Problem:
    """The scaled data of one stage-2 problem and its merit."""

    def __init__(self, target: np.ndarray, rest: np.ndarray, mu: float, v_max: float,
                 a_max: float, limits: MachineLimits, st: Stage2Settings) -> None:  # fmt: skip
        self.m = target.shape[0]
        self.dt = 1.0 / st.rate_hz
        self.tgt = target.T.ravel() * _UM  # [x…, y…], µm
        self.rest = np.asarray(rest, dtype=float) * _UM
        self.mu = mu * _UM
        self.v_step = v_max * self.dt * _UM
        self.a_step = a_max * self.dt**2 * _UM
        self.ws = np.array(limits.workspace, dtype=float) * _UM  # (2, 2)
        dv, d2 = input_bounds(limits, st.rate_hz)
        self.dv, self.d2 = dv * _UM, d2 * _UM
        self.st = st

    def violations(self, phi: np.ndarray) -> dict[str, np.ndarray]:
        """Per-row violations (µm) of 14c-14f for ``phi`` (2, M) µm."""
        e = phi - self.tgt.reshape(2, self.m)
        if self.st.norm == "euclidean":
            tol = np.maximum(np.hypot(e[0], e[1]) - self.mu, 0.0)
        else:
            tol = np.maximum(np.abs(e) - self.mu, 0.0).ravel()
        # φ_0 = φ_{-1} = rest: at rest before the start
        full = np.hstack([self.rest[:, None], self.rest[:, None], phi])
        vel = np.maximum(np.abs(np.diff(full[:, 1:], axis=1)) - self.v_step, 0.0)
        acc = np.maximum(np.abs(np.diff(full, 2, axis=1)) - self.a_step, 0.0)
        ws = np.maximum(self.ws[:, :1] - phi, 0.0) + np.maximum(phi - self.ws[:, 1:], 0.0)
        return {"tolerance": tol, "velocity": vel, "acceleration": acc, "workspace": ws}

    def feasibility(self, phi: np.ndarray) -> Feasibility:
        """14c-14f measured on ``phi`` (2, M) µm: per constraint its largest residual.

        Rows and units: 14c the deviation ``|φ_i - Ξ̄_i|`` (µm, the norm of the settings)
        against μ; 14d the signed distance outside the workspace (µm) against 0; 14e
        ``|Δφ_i| / Δt`` per axis (m/s) against ``v_max``; 14f ``|Δ²φ_i| / Δt²`` per axis
        (m/s²) against ``a_max``, both from rest (``φ_0 = φ_{-1}`` = rest). A row's sample
        is the newest ``i`` it holds, its time ``t_i = i Δt``.
        """
        m, dt = self.m, self.dt
        e = phi - self.tgt.reshape(2, m)
        idx = np.arange(1, m + 1)
        both = np.concatenate([idx, idx])
        ax = np.repeat(np.array(["x", "y"]), m)
        if self.st.norm == "euclidean":
            dev, dev_i, dev_ax = np.hypot(e[0], e[1]), idx, None
        else:
            dev, dev_i, dev_ax = np.abs(e).ravel(), both, ax
        full = np.hstack([self.rest[:, None], self.rest[:, None], phi])
        vel = np.abs(np.diff(full[:, 1:], axis=1)) / _UM / dt
        acc = np.abs(np.diff(full, 2, axis=1)) / _UM / dt**2
        out = np.maximum(self.ws[:, :1] - phi, phi - self.ws[:, 1:])
        v_max, a_max = self.v_step / _UM / dt, self.a_step / _UM / dt**2
        return Feasibility((
            measure("tolerance", "14c", "µm", dev, self.mu, samples=dev_i, times=dev_i * dt,
                    axes=dev_ax),
            measure("workspace", "14d", "µm", out.ravel(), 0.0, samples=both,
                    times=both * dt, scale=self.mu, axes=ax),
            measure("velocity", "14e", "m/s", vel.ravel(), v_max, samples=both,
                    times=both * dt, axes=ax),
            measure("acceleration", "14f", "m/s²", acc.ravel(), a_max, samples=both,
                    times=both * dt, axes=ax),
        ))  # fmt: skip

    def merit(self, phi: np.ndarray) -> tuple[float, float]:
        """(merit, cost 14a) of ``phi`` (2, M), µm²."""
        e = phi - self.tgt.reshape(2, self.m)
        cost = float(np.sum(e**2))
        v = self.violations(phi)
        pen = self.st.penalty * float(v["tolerance"].sum()) + self.st.limit_penalty * float(
            v["velocity"].sum() + v["acceleration"].sum() + v["workspace"].sum())  # fmt: skip
        return cost + pen, cost


def _diff_ops(m: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """The command's differences as maps of ``x``: shapes (m + 1, m) and (m + 2, m).

    First and second differences of ``[rest, rest, x_0 … x_{m-1}, x_{m-1}, x_{m-1}]``; the
    constant rest parts go to the bounds (`_rest_terms`).
    """
    held = sp.csr_matrix(([1.0, 1.0], ([0, 1], [m - 1, m - 1])), shape=(2, m))
    ext = sp.vstack([sp.csr_matrix((2, m)), sp.eye(m, format="csr"), held])
    d1 = sp.diags([-1.0, 1.0], [0, 1], shape=(m + 3, m + 4)) @ ext
    d2 = sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(m + 2, m + 4)) @ ext
    return sp.csr_matrix(d1[1:-1]), sp.csr_matrix(d2)


def _rest_terms(m: int, rest: float) -> tuple[np.ndarray, np.ndarray]:
    """The constant (rest) parts of `_diff_ops`' differences for one axis, µm."""
    x = np.zeros(m + 4)
    x[:2] = rest
    d1 = np.diff(x)[1:-1]
    d2 = np.diff(x, 2)
    return d1, d2


def feasible_input(
    r: np.ndarray, rest: np.ndarray, limits: MachineLimits, settings: Stage2Settings | None = None
) -> np.ndarray:
    """The input nearest to ``r`` (M, 2), m, whose command stays within ``limits``.

    The bounds of `microfab.optimize.command.input_bounds` on ``Δr`` and ``Δ²r`` from rest
    and into the held end; ``r`` itself when it meets them already.
    """
    from microfab.optimize.stage2_qp import Subproblem

    st = Stage2Settings() if settings is None else settings
    r = np.asarray(r, dtype=float)
    pb = _Problem(r, np.asarray(rest, dtype=float), 1e-6, 1.0, 1.0, limits, st)
    qp = Subproblem(pb, st, _diff_ops(pb.m), [_rest_terms(pb.m, float(x)) for x in pb.rest])
    return (qp.project(r.T.ravel() * _UM) / _UM).reshape(2, pb.m).T


def solve_stage2(
    target: np.ndarray,
    r_init: np.ndarray,
    model: Any,
    *,
    rest: np.ndarray,
    tolerance_m: float,
    v_max: float,
    a_max: float,
    limits: MachineLimits,
    settings: Stage2Settings | None = None,
    checkpoint: str | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> Stage2Result:
    """Refine ``r_init`` on the networks (module docstring).

    Parameters
    ----------
    target : numpy.ndarray
        ``Ξ̄_1 … Ξ̄_M``, (M, 2), m.
    r_init : numpy.ndarray
        ``r_0 … r_{M-1}`` to start from (stage 1's input), (M, 2), m.
    model : microfab.identify.ann.AnnModel
        The per-axis networks.
    rest : numpy.ndarray
        Rest position before the start, (2,), m.
    tolerance_m, v_max, a_max : float
        μ (m), the output's speed (m/s) and acceleration (m/s²) bounds.
    limits : MachineLimits
        The machine's limits (the command's bounds and the workspace).
    settings : Stage2Settings, optional
    checkpoint : str, optional
        Checkpoint file (``.npz``); resumed when it matches.
    progress : callable, optional
        ``progress(iteration, merit)`` after every iteration.

    Returns
    -------
    Stage2Result

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C, also inside the QP's solver (`microfab.core.interrupt.interruptible`).
    ValueError
        Mismatched shapes, non-finite values, or a checkpoint of other inputs.
    """
    st = Stage2Settings() if settings is None else settings
    t_start = time.perf_counter()
    target = np.asarray(target, dtype=float)
    r_init = np.asarray(r_init, dtype=float)
    if target.shape != r_init.shape or target.ndim != 2 or target.shape[1] != 2:
        raise ValueError(f"target and r_init must both be (M, 2), got {target.shape} and "
                         f"{r_init.shape}")  # fmt: skip
    if target.shape[0] < 3 or not (np.all(np.isfinite(target)) and np.all(np.isfinite(r_init))):
        raise ValueError("target and r_init must be finite with M >= 3 samples")
    nm = NetworkMap(model, threads=st.threads)
    pb = _Problem(target, np.asarray(rest, dtype=float), tolerance_m, v_max, a_max, limits, st)
    from microfab.optimize.stage2_qp import Subproblem

    qp = Subproblem(pb, st, _diff_ops(pb.m), [_rest_terms(pb.m, float(x)) for x in pb.rest])
    key = {"inputs": fingerprint(target, r_init, np.asarray(rest, dtype=float), {}),
           **{k: v for k, v in asdict(st).items() if k not in _NOT_FINGERPRINTED},
           "tolerance_m": tolerance_m, "v_max": v_max, "a_max": a_max,
           "limits.workspace": limits.workspace, "limits.acceleration": limits.acceleration,
           "limits.velocity": limits.velocity}  # fmt: skip
    state = load_state(checkpoint, key)
    # wall time per phase (s), `Stage2Result.phase_s`
    spent = {"project_s": 0.0, "networks_s": 0.0, "qp_s": 0.0}
    best: Best | None = None
    if state is None:
        t0 = time.perf_counter()
        r = qp.project(r_init.T.ravel() * _UM)  # the nearest input within the command bounds
        spent["project_s"] += time.perf_counter() - t0
        trust, it0, history = st.trust_um, 0, []
        t0 = time.perf_counter()
        phi, jac = _linearize(nm, r, pb)
        spent["networks_s"] += time.perf_counter() - t0
        band = jacobian_band(jac, pb.m, st.band_mass) if st.band_mass < 1 else None
    else:  # the band chosen at the start, not at the resumed iterate: bit-identical resume
        r, trust, it0, history, band, best = state
    if band is not None or state is not None:
        t0 = time.perf_counter()
        phi, jac = _linearize(nm, r, pb, band)
        spent["networks_s"] += time.perf_counter() - t0
    merit, cost = pb.merit(phi)
    score = pb.feasibility(phi).score
    cost_start = cost if not history else float(history[0][1])
    if not history:  # rows (merit, cost, feasibility score) per accepted iterate
        history = [(merit, cost, score)]
    best = Best.better(best, score, merit, cost, r, len(history) - 1)
    stop = "max_iter"
    accepted = 0
    it = it0
    while it < st.max_iter:
        it += 1
        t0 = time.perf_counter()
        step = qp.solve(r, phi, jac, trust)
        spent["qp_s"] += time.perf_counter() - t0
        if step is None or np.max(np.abs(step)) < 1e-9:
            stop = "no step" if step is None else "zero step"
            break
        r_new = r + step
        t0 = time.perf_counter()
        phi_new = nm.predict((r_new / _UM).reshape(2, pb.m).T, pb.rest / _UM)[: pb.m].T * _UM
        spent["networks_s"] += time.perf_counter() - t0
        m_new, c_new = pb.merit(phi_new)
        predicted = merit - qp.model_merit
        if m_new < merit:
            gain = merit - m_new
            ratio = gain / predicted if predicted > 0 else 0.0
            r, merit, cost = r_new, m_new, c_new
            score = pb.feasibility(phi_new).score
            history.append((merit, cost, score))
            best = Best.better(best, score, merit, cost, r, len(history) - 1)
            t0 = time.perf_counter()
            phi, jac = _linearize(nm, r, pb, band)
            spent["networks_s"] += time.perf_counter() - t0
            accepted += 1
            trust = min(trust * 2.0, 1e4) if ratio > 0.75 else trust
            if accepted % st.checkpoint_every == 0:
                save_iterate(checkpoint, key, r, trust, it, history, band, best)
            if gain < st.tol * max(merit, 1e-12):
                stop = "small gain"
                break
        else:
            trust *= 0.25
            if trust < 1e-4:
                stop = "trust region"
                break
        if progress is not None:
            progress(it, merit)
    save_iterate(checkpoint, key, r, trust, it, history, band, best)
    last = len(history) - 1
    full = nm.predict((r / _UM).reshape(2, pb.m).T, pb.rest / _UM)
    feas = pb.feasibility(full[: pb.m].T * _UM)
    returned, cost_end = last, cost
    if not feas.feasible and best is not None and best.index != last:
        # the last iterate breaks a hard constraint: return the least violating one
        r, returned, cost_end = best.r, best.index, best.cost
        full = nm.predict((r / _UM).reshape(2, pb.m).T, pb.rest / _UM)
        feas = pb.feasibility(full[: pb.m].T * _UM)
    viol = pb.violations(full[: pb.m].T * _UM)
    return Stage2Result(
        r=(r / _UM).reshape(2, pb.m).T,
        phi=full[: pb.m],
        phi_tail=full[pb.m :],
        target=target,
        cost_history=[float(row[0]) for row in history],
        cost_start=float(cost_start),
        cost_end=float(cost_end),
        violation={
            "tolerance": float(viol["tolerance"].max(initial=0.0)),
            "velocity": float(viol["velocity"].max(initial=0.0)) / _UM / pb.dt,
            "acceleration": float(viol["acceleration"].max(initial=0.0)) / _UM / pb.dt**2,
        },
        iterations=it,
        converged=stop != "max_iter" and feas.feasible and returned == last,
        wall_s=time.perf_counter() - t_start,
        resumed_from=it0,
        info={"norm": st.norm, "penalty": st.penalty, "band": band, "qp": st.qp},
        phase_s=spent,
        feasibility=feas,
        stop=stop,
        returned=returned,
        score_history=[float(row[2]) for row in history],
    )


def _linearize(
    nm: NetworkMap, r: np.ndarray, pb: _Problem, band: int | None = None
) -> tuple[np.ndarray, sp.csr_matrix]:
    """``φ_1 … φ_M`` (2, M) and ``∂φ/∂r`` (2M, 2M), µm; lags ≥ ``band`` dropped."""
    m = pb.m
    phi, jac = nm.linearize((r / _UM).reshape(2, m).T, pb.rest / _UM)
    n_out = phi.shape[0]
    rows = np.concatenate([np.arange(m), n_out + np.arange(m)])
    jac = sp.coo_matrix(jac[rows])
    if band is not None:
        keep = (jac.row % m) - (jac.col % m) < band
        jac = sp.coo_matrix((jac.data[keep], (jac.row[keep], jac.col[keep])), shape=jac.shape)
    return phi[:m].T * _UM, sp.csr_matrix(jac)


def jacobian_band(jac: sp.spmatrix, m: int, mass: float) -> int:
    """The fewest recent inputs (lags) holding ``mass`` of the Jacobian's ``Σ|∂φ/∂r|``."""
    coo = sp.coo_matrix(jac)
    lag = (coo.row % m) - (coo.col % m)
    prof = np.bincount(lag[lag >= 0], weights=np.abs(coo.data[lag >= 0]))
    cum = np.cumsum(prof) / max(prof.sum(), 1e-300)
    return int(np.searchsorted(cum, mass) + 1)
