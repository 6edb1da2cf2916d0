"""One point of seed 002 §V: a case at one ``a_max``, optimised, played on the twin, scored.

`run_point` takes a contour and ``a_max`` through both stages
(`microfab.optimize.pipeline.optimize_reference`), then plays on the twin (the
"experimental" output, seed 002 §V) and predicts with the networks (the "simulated"
one):

* the **optimised** command;
* the **baseline** of eq. (15), ``r(t) = Ξ(t S / T)`` at the optimised ``T``, through the
  twin's set-point guard (it breaks Table I's acceleration at sharp corners: the guard
  limits it, and the number of samples it changed is reported);
* a **stronger baseline**: the time-optimal command along the contour under Table I,
  stretched uniformly to the same ``T`` (`microfab.optimize.baseline`).

Deviations (eqs. 16-18, exact foot-point projection) are taken at the 400 Hz instants
``t_1 … t_M`` of eq. (13), as the seed defines them over ``φ_1 … φ_M``; the ``h`` samples
after ``T`` (the input held) are scored separately as the tail.

The models are the linear model and the networks of a ``stage-identify`` output
(`microfab.optimize.models.load_models`).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.machines.xy_stage import Played, TwinSettings, play_runs
from microfab.optimize.command import LEAD
from microfab.optimize.models import Models
from microfab.optimize.pipeline import (
    MODEL_RATE_HZ,
    ReferenceResult,
    optimize_reference,
    training_warning,
)
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Settings

__all__ = [
    "PointResult",
    "Scored",
    "baseline_scores",
    "run_point",
]

RUN_RATE_HZ = 1e4  # seed 002 Table I: the 10 kHz loop
TAIL = 200  # issue 18: after T the input is held for h = 200 samples (500 ms)


@dataclass(frozen=True)
class Scored:
    """Deviations of one output (eqs. 16-18) at ``t_1 … t_M`` and in the tail, m.

    Attributes
    ----------
    l1, l2, linf : float
        Over ``t_1 … t_M``.
    tail_linf : float
        L∞ over the ``TAIL`` samples after ``T``.
    n : int
        ``M``.
    """

    l1: float
    l2: float
    linf: float
    tail_linf: float
    n: int

    def as_dict(self) -> dict[str, float]:
        """JSON form."""
        return {"l1": self.l1, "l2": self.l2, "linf": self.linf, "tail_linf": self.tail_linf,
                "n": self.n}  # fmt: skip


def score(problem: ContourProblem, points: np.ndarray, m: int) -> tuple[Scored, np.ndarray]:
    """`Scored` of an output sampled at ``t_1 …``, and the deviation of every row, m.

    Rows ``0 … m-1`` are the run, the rest the tail.
    """
    from microfab.optimize.metrics import deviations

    dev = deviations(problem.path, points)
    run, tail = dev[:m], dev[m:]
    return (
        Scored(
            l1=float(np.mean(run)),
            l2=float(np.sqrt(np.mean(run**2))),
            linf=float(np.max(run)),
            tail_linf=float(np.max(tail)) if tail.size else 0.0,
            n=m,
        ),
        dev,
    )


@dataclass(frozen=True, eq=False)
class PointResult:
    """A case at one ``a_max``: the optimised reference and the scores of every output.

    Attributes
    ----------
    case : str
    a_max : float
    reference : ReferenceResult
    scores : dict of str to Scored
        Keys ``"<input>_<output>"``: input "optimised", "baseline", "stretched"; output
        "twin" (experimental) or "ann" (simulated).
    limited : dict of str to int
        Samples the twin's set-point guard changed, per input.
    outputs : dict of str to numpy.ndarray
        The outputs at ``t_1 … t_{M+TAIL}``, (M + TAIL, 2), m, per score key, and the
        inputs (``"<input>_input"``) at the same instants.
    wall_s : dict of str to float
    """

    case: str
    a_max: float
    reference: ReferenceResult
    scores: dict[str, Scored]
    limited: dict[str, int]
    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    wall_s: dict[str, float] = field(default_factory=dict)
    reference_networks: Any = None

    @property
    def duration(self) -> float:
        """``T``, s."""
        return self.reference.duration

    def improvement(self, output: str = "twin", baseline: str = "baseline") -> dict[str, float]:
        """Table III: ``100 (baseline - optimised) / baseline`` per norm, %."""
        ours, base = self.scores[f"optimised_{output}"], self.scores[f"{baseline}_{output}"]
        return {k: 100.0 * (getattr(base, k) - getattr(ours, k)) / getattr(base, k)
                for k in ("l1", "l2", "linf")}  # fmt: skip

    def summary(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "case": self.case,
            "a_max": self.a_max,
            "duration_s": self.duration,
            "m": self.reference.m,
            "stage1": self.reference.stage1.summary(),
            "stage2": None if self.reference.stage2 is None else _stage2_summary(
                self.reference.stage2),
            "scores": {k: v.as_dict() for k, v in self.scores.items()},
            "improvement": {"twin": self.improvement("twin"), "ann": self.improvement("ann")},
            "limited": self.limited,
            "wall_s": self.wall_s,
            "warning": training_warning(self.reference_networks, self.a_max),
        }  # fmt: skip


def _stage2_summary(st2: Any) -> dict[str, Any]:
    return st2.summary()


@dataclass(frozen=True)
class _Command:
    name: str
    dt: float
    command: np.ndarray


def _at_model_rate(y: np.ndarray, m: int, lead: int = 0) -> np.ndarray:
    """Rows at ``t_1 … t_{m+TAIL}`` of a 10 kHz run whose sample ``lead q`` is ``t_0``."""
    step = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    idx = (np.arange(1, m + TAIL + 1) + lead) * step
    idx = np.minimum(idx, y.shape[0] - 1)
    return y[idx]


def run_point(
    case: str,
    problem: ContourProblem,
    models: Models,
    *,
    twin: TwinSettings | None = None,
    stage1: Stage1Settings | None = None,
    stage2: Any = None,
    checkpoint: str | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> PointResult:
    """Optimise, play and score one case at one ``a_max`` (module docstring)."""
    from microfab.optimize.baseline import constant_progress, stretched_time_optimal

    tw = TwinSettings(hold_s=TAIL / MODEL_RATE_HZ + 0.01) if twin is None else twin
    wall: dict[str, float] = {}
    t0 = time.perf_counter()
    ref = optimize_reference(problem, models.linear, models.networks, stage1=stage1,
                             stage2=stage2, checkpoint=checkpoint, progress=progress)  # fmt: skip
    wall["optimise"] = time.perf_counter() - t0
    m = ref.m
    base = constant_progress(problem.path, ref.duration, RUN_RATE_HZ)  # eq. (15)
    stretched = stretched_time_optimal(problem.path, ref.duration, problem.limits, RUN_RATE_HZ)
    commands = {"optimised": ref.command.position, "baseline": base, "stretched": stretched}
    t0 = time.perf_counter()
    played: Played = play_runs(
        [_Command(f"{case}_a{problem.a_max:g}_{k}", 1.0 / RUN_RATE_HZ, np.asarray(c))
         for k, c in commands.items()],
        tw,
    )  # fmt: skip
    wall["twin"] = time.perf_counter() - t0
    scores: dict[str, Scored] = {}
    outputs: dict[str, np.ndarray] = {}
    limited = {}
    from microfab.optimize.ann_torch import NetworkMap

    net = NetworkMap(models.networks)
    step = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    t0 = time.perf_counter()
    for (name, cmd), rec, lim in zip(commands.items(), played.records, played.limited, strict=True):
        lead = LEAD if name == "optimised" else 0  # the optimised command starts 2 Δt early
        y = _at_model_rate(rec.y, m, lead)
        scores[f"{name}_twin"], _ = score(problem, y, m)
        outputs[f"{name}_twin"] = y
        outputs[f"{name}_input"] = _at_model_rate(rec.u, m, lead)
        limited[name] = int(lim)
        # simulated: the networks on the command's 400 Hz samples from rest (the seed's φ)
        r400 = np.asarray(cmd)[lead * step :: step][:m]
        if r400.shape[0] < m:
            r400 = np.vstack([r400, np.repeat(r400[-1:], m - r400.shape[0], axis=0)])
        phi = net.predict(r400, ref.rest)[: m + TAIL]
        scores[f"{name}_ann"], _ = score(problem, phi, m)
        outputs[f"{name}_ann"] = phi
    wall["score"] = time.perf_counter() - t0
    return PointResult(case=case, a_max=problem.a_max, reference=ref, scores=scores,
                       limited=limited, outputs=outputs, wall_s=wall,
                       reference_networks=models.networks)  # fmt: skip


def baseline_scores(path: Any, duration_s: float, twin: TwinSettings | None = None) -> Scored:
    """The eq. (15) baseline at ``duration_s`` on the twin, scored at the 400 Hz instants."""
    from microfab.optimize.baseline import constant_progress

    tw = TwinSettings(hold_s=TAIL / MODEL_RATE_HZ + 0.01) if twin is None else twin
    cmd = constant_progress(path, duration_s, RUN_RATE_HZ)
    played = play_runs([_Command("baseline", 1.0 / RUN_RATE_HZ, np.asarray(cmd))], tw)
    m = math.ceil(duration_s * MODEL_RATE_HZ - 1e-9)
    problem = ContourProblem(path, a_max=1.0)
    return score(problem, _at_model_rate(played.records[0].y, m), m)[0]


def write_point(result: PointResult, directory: Path) -> None:
    """Write ``<case>_a<a_max>.json`` and ``.npz`` (outputs, target, inputs), atomically.

    The JSON last, so a reader that finds it finds the arrays too.
    """
    from microfab.io.atomic import atomic_save_npz, atomic_write_json

    stem = directory / f"{result.case}_a{result.a_max:g}"
    ref = result.reference
    atomic_save_npz(stem.with_suffix(".npz"), t=ref.t, target=ref.target, r=ref.r,
                    r_init=ref.r_init, command=ref.command.position,
                    **{f"out_{k}": v for k, v in result.outputs.items()})  # fmt: skip
    atomic_write_json(stem.with_suffix(".json"), result.summary())


def read_point_summary(directory: Path, case: str, a_max: float) -> dict[str, Any] | None:
    """The saved summary of a point, or None."""
    p = directory / f"{case}_a{a_max:g}.json"
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, json.JSONDecodeError):
        return None
