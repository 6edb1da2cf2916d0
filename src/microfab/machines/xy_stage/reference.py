"""Optimised references on the XY stage twin: one case optimised, played, scored (seed 002 §V).

What the ``stage-reference-opt`` job (``microfab run``, and ``microfab reproduce
reference-opt``) computes per point. `run_point` takes a contour and ``a_max`` through
both stages (`microfab.optimize.pipeline.optimize_reference`, the function ``microfab
optimize`` runs), then plays on the twin (the "experimental" output, seed 002 §V) and
predicts with the networks (the "simulated" one):

* the **optimised** command;
* the **baseline** of eq. (15), ``r(t) = Ξ(t S / T)`` at the optimised ``T``, through the
  twin's set-point guard (it breaks Table I's acceleration at sharp corners: the guard
  limits it, and the number of samples it changed is reported);
* a **stronger baseline**: the time-optimal command along the contour under Table I,
  stretched uniformly to the same ``T`` (`microfab.optimize.baseline`).

Deviations (eqs. 16-18, `microfab.optimize.metrics.DeviationNorms`) are taken at the
400 Hz instants ``t_1 … t_M`` of eq. (13), as the seed defines them over ``φ_1 … φ_M``;
the ``TAIL`` samples after ``T`` (the input held) are scored separately as the tail.

What each stage reached is in the summary, measured on its answer (issue 43): stage 1's
and stage 2's ``converged`` and ``feasibility`` (every hard constraint of seed 002 eqs.
12b-12j and 14c-14f: largest residual with unit, sample, time, rows beyond), stage 2's
``status`` ("converged", "infeasible": the least violating iterate returned, or "not
converged") and ``prediction`` (`microfab.optimize.pipeline.PredictionCheck`: the
networks against the linear model on stage 1's input, the recorded validation σ, the
warning when either exceeds μ). ``warnings`` lists what the user is told.

`saved_point` is the resumable form: a point's summary is written atomically
(`write_point`: ``<case>_a<a_max>.json`` and ``.npz``) with the fingerprint of the
settings that decide its numbers, and read back instead of rerun while it matches and is
of the current `POINT_FORMAT`; a failed stage is recorded with its message. `baseline_l2`
scores the eq. (15) baseline alone at a given time (the trade-off curves, Figs. 16-17).

The models are the linear model and the networks of a ``stage-identify`` output
(`microfab.optimize.models.load_models`).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.geometry.path import Path as Contour
from microfab.identify.stage_data import StageRecord
from microfab.machines.xy_stage.machine import Played, TwinSettings, play_runs
from microfab.optimize.command import LEAD
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.models import Models
from microfab.optimize.pipeline import (
    MODEL_RATE_HZ,
    ReferenceResult,
    at_model_rate,
    optimize_reference,
    training_warning,
)
from microfab.optimize.problem import ContourProblem
from microfab.optimize.stage1 import Stage1Error, Stage1Settings

__all__ = [
    "HOLD_S",
    "POINT_FORMAT",
    "RUN_RATE_HZ",
    "TAIL",
    "PointResult",
    "baseline_l2",
    "read_point_summary",
    "run_point",
    "saved_point",
    "write_point",
]

RUN_RATE_HZ = 1e4  # seed 002 Table I: the 10 kHz loop
TAIL = 200  # issue 18: after T the input is held for h = 200 samples (500 ms)
HOLD_S = TAIL / MODEL_RATE_HZ + 0.01  # the twin's hold: the tail and one 10 ms margin
#: A point summary's format: 2 since issue 43 (the stages' measured constraints, the
#: prediction check); a saved point of another format is run again.
POINT_FORMAT = 2


@dataclass(frozen=True, eq=False)
class PointResult:
    """A case at one ``a_max``: the optimised reference and the scores of every output.

    Attributes
    ----------
    case : str
    a_max : float
        m/s².
    reference : ReferenceResult
    scores : dict of str to DeviationNorms
        Keys ``"<input>_<output>"``: input "optimised", "baseline", "stretched"; output
        "twin" (experimental) or "ann" (simulated); with the tail's L∞.
    limited : dict of str to int
        Samples the twin's set-point guard changed, per input.
    outputs : dict of str to numpy.ndarray
        The outputs at ``t_1 … t_{M+TAIL}``, (M + TAIL, 2), m, per score key, and the
        inputs (``"<input>_input"``) at the same instants.
    wall_s : dict of str to float
    reference_networks : AnnModel or None
        The networks (the training-range warning of the summary).
    records : dict of str to StageRecord
        The 10 kHz runs on the twin per input ("optimised", "baseline", "stretched").
    """

    case: str
    a_max: float
    reference: ReferenceResult
    scores: dict[str, DeviationNorms]
    limited: dict[str, int]
    outputs: dict[str, np.ndarray] = field(default_factory=dict)
    wall_s: dict[str, float] = field(default_factory=dict)
    reference_networks: Any = None
    records: dict[str, StageRecord] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """``T``, s."""
        return self.reference.duration

    def improvement(self, output: str = "twin", baseline: str = "baseline") -> dict[str, float]:
        """Table III: ``100 (baseline - optimised) / baseline`` per norm, %."""
        ours = self.scores[f"optimised_{output}"]
        return ours.improvement_over(self.scores[f"{baseline}_{output}"])

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the user is told about this point, in order.

        The networks' training range (`training_warning`), then the reference's own
        (`microfab.optimize.pipeline.ReferenceResult.warnings`).
        """
        first = training_warning(self.reference_networks, self.a_max)
        return tuple(w for w in (first, *self.reference.warnings) if w)

    def summary(self) -> dict[str, Any]:
        """JSON-ready (module docstring)."""
        st2 = self.reference.stage2
        pred = self.reference.prediction
        return {
            "format": POINT_FORMAT,
            "case": self.case,
            "a_max": self.a_max,
            "duration_s": self.duration,
            "m": self.reference.m,
            "stage1": self.reference.stage1.summary(),
            "stage2": None if st2 is None else st2.summary(),
            "scores": {k: v.as_dict() for k, v in self.scores.items()},
            "improvement": {"twin": self.improvement("twin"), "ann": self.improvement("ann")},
            "limited": self.limited,
            "wall_s": self.wall_s,
            "prediction": None if pred is None else pred.as_dict(),
            "training_warning": training_warning(self.reference_networks, self.a_max),
            "warnings": list(self.warnings),
            "warning": "; ".join(self.warnings) or None,
        }


@dataclass(frozen=True)
class _Command:
    name: str
    dt: float
    command: np.ndarray


def _twin(twin: TwinSettings | None) -> TwinSettings:
    return TwinSettings(hold_s=HOLD_S) if twin is None else twin


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
    warn: Callable[[str], None] | None = None,
) -> PointResult:
    """Optimise, play and score one case at one ``a_max`` (module docstring).

    Parameters
    ----------
    case : str
        Its name (the twin runs' names).
    problem : ContourProblem
        Contour, ``a_max`` and tolerance.
    models : Models
        Linear model and networks.
    twin : TwinSettings, optional
        Default: noise seed 0 and `HOLD_S`.
    stage1, stage2 : settings, optional
        Of `microfab.optimize.pipeline.optimize_reference`.
    checkpoint : str, optional
        Stage 2's checkpoint file (a rerun resumes).
    progress : callable, optional
        Stage 2's ``progress(iteration, cost)``.
    warn : callable, optional
        ``warn(text)`` before stage 2 when the networks' prediction is not good to μ
        (`microfab.optimize.pipeline.PredictionCheck`; also in the summary).

    Raises
    ------
    microfab.optimize.stage1.Stage1Error, ValueError
        A stage failed (infeasible, not converged, a command outside Table I).
    """
    from microfab.optimize.ann_torch import NetworkMap
    from microfab.optimize.baseline import constant_progress, stretched_time_optimal

    wall: dict[str, float] = {}
    t0 = time.perf_counter()
    ref = optimize_reference(problem, models.linear, models.networks, stage1=stage1,
                             stage2=stage2, checkpoint=checkpoint, progress=progress,
                             validation_sigma_m=models.validation_sigma_m, warn=warn)  # fmt: skip
    wall["optimise"] = time.perf_counter() - t0
    m = ref.m
    base = constant_progress(problem.path, ref.duration, RUN_RATE_HZ)  # eq. (15)
    stretched = stretched_time_optimal(problem.path, ref.duration, problem.limits, RUN_RATE_HZ)
    commands = {"optimised": ref.command.position, "baseline": base, "stretched": stretched}
    t0 = time.perf_counter()
    played: Played = play_runs(
        [_Command(f"{case}_a{problem.a_max:g}_{k}", 1.0 / RUN_RATE_HZ, np.asarray(c))
         for k, c in commands.items()],
        _twin(twin),
    )  # fmt: skip
    wall["twin"] = time.perf_counter() - t0
    scores: dict[str, DeviationNorms] = {}
    outputs: dict[str, np.ndarray] = {}
    limited = {}
    records = {}
    net = NetworkMap(models.networks)
    step = round(RUN_RATE_HZ / MODEL_RATE_HZ)
    t0 = time.perf_counter()
    for (name, cmd), rec, lim in zip(commands.items(), played.records, played.limited, strict=True):
        lead = LEAD if name == "optimised" else 0  # the optimised command starts 2 Δt early
        y = at_model_rate(rec.y, m, lead, TAIL)
        scores[f"{name}_twin"] = DeviationNorms.of(problem.path, y, tail_from=m)
        outputs[f"{name}_twin"] = y
        outputs[f"{name}_input"] = at_model_rate(rec.u, m, lead, TAIL)
        limited[name] = int(lim)
        records[name] = rec
        # simulated: the networks on the command's 400 Hz samples from rest (the seed's φ)
        r400 = np.asarray(cmd)[lead * step :: step][:m]
        if r400.shape[0] < m:
            r400 = np.vstack([r400, np.repeat(r400[-1:], m - r400.shape[0], axis=0)])
        phi = net.predict(r400, ref.rest)[: m + TAIL]
        scores[f"{name}_ann"] = DeviationNorms.of(problem.path, phi, tail_from=m)
        outputs[f"{name}_ann"] = phi
    wall["score"] = time.perf_counter() - t0
    return PointResult(case=case, a_max=problem.a_max, reference=ref, scores=scores,
                       limited=limited, outputs=outputs, wall_s=wall,
                       reference_networks=models.networks, records=records)  # fmt: skip


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
    """The saved summary of a point, or None (none there, or unreadable)."""
    p = directory / f"{case}_a{a_max:g}.json"
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def saved_point(
    case: str,
    problem: ContourProblem,
    models: Models,
    *,
    twin: TwinSettings,
    stage2_max_iter: int,
    folder: Path | None,
    fingerprint: str,
) -> dict[str, Any]:
    """`run_point`'s summary, saved under ``folder`` and read back on a rerun.

    A summary saved there with the same ``fingerprint`` (the hash of what decides the
    point's numbers) is returned as it is; otherwise the point is run (stage 2 checkpoints
    to ``<case>_a<a_max>_stage2.ckpt.npz`` in ``folder``) and written (`write_point`). A
    stage that fails (`Stage1Error`, ValueError) gives ``{"case", "a_max", "error"}``
    instead, saved too (with ``"stage1"``, the measured summary of stage 1's last iterate,
    when stage 1 failed). ``folder`` None: nothing is read or written.
    """
    from microfab.io.atomic import atomic_write_json
    from microfab.optimize.stage2 import Stage2Settings

    a = problem.a_max
    if folder is not None:
        saved = read_point_summary(folder, case, a)
        if (saved is not None and saved.get("fingerprint") == fingerprint
                and saved.get("format") == POINT_FORMAT):  # fmt: skip
            return saved
    ckpt = None if folder is None else str(folder / f"{case}_a{a:g}_stage2.ckpt.npz")
    try:
        s2 = Stage2Settings(max_iter=stage2_max_iter)
        res = run_point(case, problem, models, twin=twin, stage1=Stage1Settings(), stage2=s2,
                        checkpoint=ckpt)  # fmt: skip
    except (Stage1Error, ValueError) as exc:
        summary = {"format": POINT_FORMAT, "case": case, "a_max": a,
                   "error": f"{type(exc).__name__}: {exc}"}  # fmt: skip
        if isinstance(exc, Stage1Error) and exc.result is not None:
            summary["stage1"] = exc.result.summary()  # what it reached, measured
    else:
        summary = res.summary()
        if folder is not None:
            write_point(res, folder)
    summary["fingerprint"] = fingerprint
    if folder is not None:
        atomic_write_json(folder / f"{case}_a{a:g}.json", summary)
    return summary


def baseline_l2(
    paths: Sequence[Contour], total_s: float, twin: TwinSettings | None = None
) -> float:
    """L2 of the eq. (15) baseline on the twin over ``paths`` traced in turn, m.

    Each contour gets its share of ``total_s`` by its length (one path speed), is played
    from rest and scored at the 400 Hz instants; the deviations are pooled
    (`DeviationNorms.pooled`).
    """
    length = sum(p.length for p in paths)
    parts = [_baseline_norms(p, total_s * p.length / length, twin) for p in paths]
    return DeviationNorms.pooled(parts).l2


def _baseline_norms(path: Contour, duration_s: float, twin: TwinSettings | None) -> DeviationNorms:
    """The eq. (15) baseline at ``duration_s`` on the twin, scored at the 400 Hz instants."""
    from microfab.optimize.baseline import constant_progress

    cmd = constant_progress(path, duration_s, RUN_RATE_HZ)
    played = play_runs([_Command("baseline", 1.0 / RUN_RATE_HZ, np.asarray(cmd))], _twin(twin))
    m = math.ceil(duration_s * MODEL_RATE_HZ - 1e-9)
    return DeviationNorms.of(path, at_model_rate(played.records[0].y, m, tail=TAIL), tail_from=m)
