"""Seed 002 §V on the twin: Table III, the airfoil at 2 m/s², the trade-off curves.

`run_reference` does, in order, saving every finished point atomically under
``out/points/`` and skipping a point already there on a rerun (same settings: the
fingerprint is in the point's JSON):

1. the models: read from a ``stage-identify`` output
   (`microfab.optimize.models.load_models`);
2. the sizes: the documented step of `sizing` (stage 1's ``T`` of "r" and of the airfoil
   at 1 m/s²), or the sizes given;
3. every case at every ``a_max`` of `ReferenceSettings.a_max` (Table III: 1 and 3) and the
   airfoil at `ReferenceSettings.airfoil_extra` (§V-A: 2 m/s²), each through
   `microfab.machines.xy_stage.reference.run_point` (both stages, the twin, the networks,
   the baselines; saved and resumed by `microfab.machines.xy_stage.reference.saved_point`);
4. the trade-off (§V-B, Figs. 16-17): the letters at each of ``tradeoff_letters``
   (the four letters one after another, each from rest: times summed, deviations pooled)
   and the airfoil at each of ``tradeoff_airfoil``; the eq. (15) baseline also at longer
   times (``baseline_factors`` times the slowest optimised time) to find the baseline's
   time at a given L2 (`microfab.machines.xy_stage.reference.baseline_l2`).

Points are independent; a failed stage (infeasible, not converged) is recorded in the
point's JSON with its message and the study goes on. The points not yet saved run side by
side, one worker process each (`microfab.io.sweep.run_sweep` on a local cluster of
``ReferenceSettings.workers``; a single point, or one worker, runs in this process); each
process runs its BLAS/OpenMP/PyTorch pools on `microfab.core.threads.policy_threads`
threads, so a point's numbers do not depend on where it ran.

Generations (seed 002 §III-C.2, Fig. 7; ``generations`` ≥ 2): first the networks'
generations are run or resumed under ``out/generations/``
(`microfab.machines.xy_stage.generations.run_generations`: the regular shapes optimised
with each generation's models, played on the twin, added to the data, the networks
retrained warm), then Table III's points (``cases`` × ``a_max``, no trade-off) with each
earlier generation's models under ``out/generation<g>/``, and the whole study above with
the last generation's models (the seed's Table III uses the third), sized once with the
first generation's linear model (the linear model is not refitted, §III-C.2). Without
``out`` the generations live in a temporary folder removed at the end.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from microfab.core.threads import usable_cores
from microfab.geometry.text import SEED002_LETTERS
from microfab.machines.xy_stage.ann import AnnSettings
from microfab.machines.xy_stage.cases import CASES, CaseSizes, case_paths
from microfab.machines.xy_stage.generations import (
    DEFAULT_SHAPES,
    GenerationSettings,
    GenerationsResult,
    run_generations,
)
from microfab.machines.xy_stage.machine import TwinSettings
from microfab.machines.xy_stage.reference import baseline_l2, saved_point
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.models import Models, load_models, models_digest
from microfab.optimize.problem import ContourProblem

__all__ = ["ReferenceSettings", "ReferenceStudy", "run_reference"]

Progress = Callable[[str, int, int | None], None]


@dataclass(frozen=True, kw_only=True)
class ReferenceSettings:
    """What `run_reference` runs (module docstring).

    Parameters
    ----------
    models_dir : str
        Output of a ``stage-identify`` job (``linear_model.json``, ``ann/model``); ``""``
        (default) or ``"builtin"``: the shipped models
        (`microfab.optimize.models.resolve_models_dir`).
    twin : TwinSettings
        The twin the networks were trained on (its noise seed).
    cases : tuple of str
        Of `CASES`.
    a_max : tuple of float
        Table III's columns, m/s².
    airfoil_extra : tuple of float
        More airfoil points (§V-A: 2 m/s²).
    tolerance_m : float
        μ, m.
    sizes : CaseSizes or None
        Given sizes; None: the sizing step on stage 1.
    tradeoff_letters, tradeoff_airfoil : tuple of float
        The trade-off's a_max values (seed: 0.1-3.3 and 0.1-10 m/s²); empty: none.
    baseline_factors : tuple of float
        Longer baseline times for the trade-off, in units of the slowest optimised time.
    stage2_max_iter : int
        Stage 2's Gauss-Newton iterations.
    generations : int
        The networks' generations (seed 002 §III-C.2, Fig. 7); 1: the given models alone.
    generation_shapes : tuple of str
        The regular shapes the generations optimise
        (`microfab.machines.xy_stage.generations.SHAPES`).
    generation_size_m : float
        Their size, m (radius, circumradius, the spiral's outer radius).
    generation_a_max : tuple of float
        Their a_max, m/s².
    retrain_epochs : int
        Most epochs of a retraining.
    generation_data_s : float or None
        Generation 1's data length, s (`microfab.machines.xy_stage.ann.AnnSettings`
        ``total_s``; None: the seed's, about 525 s).
    retrain_workers : int
        Axes retrained at once, one process each (assumed 2, the ``stage-identify``
        job's: on 2 cores two processes halve the time; not fingerprinted).
    workers : int
        Points run at once, one process each; 0 (default): one per usable core
        (`microfab.core.threads.usable_cores`), never more than the points left to run.
        Not fingerprinted: where a point runs does not change its numbers.
    """

    models_dir: str = ""
    twin: TwinSettings = field(default_factory=TwinSettings)
    cases: tuple[str, ...] = CASES
    a_max: tuple[float, ...] = (1.0, 3.0)
    airfoil_extra: tuple[float, ...] = (2.0,)
    tolerance_m: float = 20e-6
    sizes: CaseSizes | None = None
    tradeoff_letters: tuple[float, ...] = ()
    tradeoff_airfoil: tuple[float, ...] = ()
    baseline_factors: tuple[float, ...] = (1.5, 2.0, 3.0, 4.0, 6.0)
    stage2_max_iter: int = 30
    generations: int = 1
    generation_shapes: tuple[str, ...] = DEFAULT_SHAPES
    generation_size_m: float = 20e-3  # assumed (machines.xy_stage.generations.GenerationSettings)
    generation_a_max: tuple[float, ...] = (1.0, 3.0)  # assumed: Table III's columns
    retrain_epochs: int = 20  # assumed (machines.xy_stage.generations.GenerationSettings)
    generation_data_s: float | None = None
    retrain_workers: int = 2  # assumed, see above
    workers: int = 0

    def generation_settings(self) -> GenerationSettings:
        """The generations' settings: these models, twin, tolerance and stage 2."""
        twin = TwinSettings(seed=self.twin.seed, noise=self.twin.noise,
                            changes=self.twin.changes)  # fmt: skip
        return GenerationSettings(
            models_dir=self.models_dir,
            ann=AnnSettings(
                total_s=self.generation_data_s, twin=twin, workers=self.retrain_workers
            ),
            shapes=self.generation_shapes,
            size_m=self.generation_size_m,
            a_max=self.generation_a_max,
            tolerance_m=self.tolerance_m,
            stage2_max_iter=self.stage2_max_iter,
            retrain_epochs=self.retrain_epochs,
            count=self.generations,
        )

    def fingerprint(self) -> str:
        """Hash of what decides a point's numbers (not the list of points)."""
        keep = {"models": models_digest(self.models_dir),  # the files, not their folder
                "twin": asdict(self.twin), "tolerance_m": self.tolerance_m,
                "sizes": None if self.sizes is None else asdict(self.sizes),
                "stage2_max_iter": self.stage2_max_iter}  # fmt: skip
        return hashlib.sha256(json.dumps(keep, sort_keys=True, default=str).encode()).hexdigest()


@dataclass(frozen=True, eq=False)
class ReferenceStudy:
    """What `run_reference` found.

    Attributes
    ----------
    settings : ReferenceSettings
    sizes : CaseSizes
    sizing_steps : dict
        The sizing's stage-1 solves (empty when sizes were given).
    points : dict of (str, float) to dict
        Every point's summary (`microfab.machines.xy_stage.reference.PointResult.summary`,
        or ``{"error": ...}``).
    tradeoff : dict of str to list of dict
        "letters" and "airfoil": one row per a_max (time, pooled norms per output).
    baseline_curve : dict of str to list of dict
        "letters" and "airfoil": the eq. (15) baseline on the twin at longer times.
    generations : GenerationsResult or None
        The networks' generations (``settings.generations`` ≥ 2), else None.
    earlier : tuple of ReferenceStudy
        Table III's points with each generation's models but the last (whose study this
        is), in order; empty without generations.
    """

    settings: ReferenceSettings
    sizes: CaseSizes
    sizing_steps: dict[str, Any]
    points: dict[tuple[str, float], dict[str, Any]]
    tradeoff: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    baseline_curve: dict[str, list[dict[str, float]]] = field(default_factory=dict)
    generations: GenerationsResult | None = None
    earlier: tuple[ReferenceStudy, ...] = ()

    def by_generation(self) -> list[tuple[int, ReferenceStudy]]:
        """``(generation, study)`` from the first; just ``[(1, self)]`` without generations."""
        return [*enumerate(self.earlier, start=1), (len(self.earlier) + 1, self)]


def _sizes(st: ReferenceSettings, models: Models, out: Path | None) -> tuple[CaseSizes, dict]:
    from microfab.experiments.seed002_reference.sizing import reference_sizes
    from microfab.io.atomic import atomic_write_json

    if st.sizes is not None:
        return st.sizes, {}
    path = None if out is None else out / "sizes.json"
    if path is not None and path.is_file():
        saved = json.loads(path.read_text())
        if saved.get("fingerprint") == st.fingerprint():
            return CaseSizes(**saved["sizes"]), saved["steps"]
    res = reference_sizes(models.linear, tolerance_m=st.tolerance_m,
                          workers=st.workers or usable_cores())  # fmt: skip
    if path is not None:
        atomic_write_json(path, {"fingerprint": st.fingerprint(), "sizes": asdict(res.sizes),
                                 "steps": res.steps})  # fmt: skip
    return res.sizes, res.steps


def _pooled(points: Sequence[dict[str, Any]]) -> dict[str, float]:
    """Letters one after another: times summed, deviations pooled over the samples."""
    out: dict[str, float] = {"time_s": float(sum(p["duration_s"] for p in points))}
    for key in points[0]["scores"]:
        n = DeviationNorms.pooled([DeviationNorms.from_dict(p["scores"][key]) for p in points])
        out.update({f"{key}_l1": n.l1, f"{key}_l2": n.l2, f"{key}_linf": n.linf})
    return out


def run_reference(
    settings: ReferenceSettings, out: Path | None = None, progress: Progress | None = None
) -> ReferenceStudy:
    """Run the study (module docstring); ``out`` keeps the points for a resume."""
    if settings.generations < 2:
        return _study(settings, out, progress)
    if out is None:
        with tempfile.TemporaryDirectory(prefix="microfab-generations-") as tmp:
            return _with_generations(settings, Path(tmp), progress, keep=False)
    return _with_generations(settings, out, progress, keep=True)


def _with_generations(
    st: ReferenceSettings, out: Path, progress: Progress | None, *, keep: bool
) -> ReferenceStudy:
    """The generations, Table III with each earlier one's models, the study with the last."""
    gens = run_generations(st.generation_settings(), out / "generations", progress)
    earlier: list[ReferenceStudy] = []
    sizes = st.sizes
    for g in gens.generations[:-1]:
        sub = dataclasses.replace(
            st, models_dir=g.models_dir, generations=1, sizes=sizes, airfoil_extra=(),
            tradeoff_letters=(), tradeoff_airfoil=(),
        )  # fmt: skip
        earlier.append(_study(sub, out / f"generation{g.index}" if keep else None, progress))
        sizes = earlier[-1].sizes  # the linear model is the same in every generation
    last = dataclasses.replace(st, models_dir=gens.generations[-1].models_dir, generations=1,
                               sizes=sizes)  # fmt: skip
    final = _study(last, out, progress)
    return dataclasses.replace(final, settings=st, generations=gens, earlier=tuple(earlier))


def _study(
    settings: ReferenceSettings, out: Path | None, progress: Progress | None
) -> ReferenceStudy:
    """The study of the module docstring with one set of models."""
    report = progress or (lambda task, done, total: None)
    st = settings
    models = load_models(st.models_dir)
    sizes, steps = _sizes(st, models, out)
    paths = case_paths(sizes, st.cases)
    folder = None if out is None else out / "points"
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    todo = [(c, a) for c in st.cases for a in st.a_max]
    if "airfoil" in st.cases:
        todo += [("airfoil", a) for a in st.airfoil_extra if a not in st.a_max]
    letters = [c for c in SEED002_LETTERS if c in st.cases] if st.tradeoff_letters else []
    todo += [(c, a) for a in st.tradeoff_letters for c in letters if (c, a) not in todo]
    if "airfoil" in st.cases:
        todo += [("airfoil", a) for a in st.tradeoff_airfoil if ("airfoil", a) not in todo]
    points = _run_points(st, todo, paths, models, folder, report)
    tradeoff: dict[str, list[dict[str, float]]] = {}
    if letters:
        rows = []
        for a in st.tradeoff_letters:
            pts = [points[(c, a)] for c in letters]
            if all("error" not in p for p in pts):
                rows.append({"a_max": a, **_pooled(pts)})
        tradeoff["letters"] = rows
    if st.tradeoff_airfoil and "airfoil" in st.cases:
        tradeoff["airfoil"] = [
            {"a_max": a, **_pooled([points[("airfoil", a)]])}
            for a in st.tradeoff_airfoil if "error" not in points[("airfoil", a)]
        ]  # fmt: skip
    curve = _baseline_curves(st, paths, tradeoff, letters)
    return ReferenceStudy(settings=st, sizes=sizes, sizing_steps=steps, points=points,
                          tradeoff=tradeoff, baseline_curve=curve)  # fmt: skip


@dataclass(frozen=True)
class _Point:
    """One point as the sweep sends it: a case at an ``a_max`` (m/s²)."""

    case: str
    a_max: float


@dataclass(frozen=True, eq=False)
class _PointTask:
    """`saved_point` of a `_Point`; pickled once for every worker process (models too).

    Returns ``{"summary": ...}``: the point's summary, kept apart from the sweep's row
    (whose point fields would otherwise mix with the summary's own).
    """

    settings: ReferenceSettings
    paths: dict[str, Any]
    models: Models
    folder: Path | None
    fingerprint: str

    def __call__(self, point: _Point) -> dict[str, Any]:
        st = self.settings
        problem = ContourProblem(self.paths[point.case], a_max=point.a_max,
                                 tolerance_m=st.tolerance_m)  # fmt: skip
        return {"summary": saved_point(
            point.case, problem, self.models, twin=st.twin,
            stage2_max_iter=st.stage2_max_iter, folder=self.folder,
            fingerprint=self.fingerprint,
        )}  # fmt: skip


def _run_points(
    st: ReferenceSettings, todo: list[tuple[str, float]], paths: dict[str, Any],
    models: Models, folder: Path | None, report: Progress,
) -> dict[tuple[str, float], dict[str, Any]]:  # fmt: skip
    """Every point's summary, in ``todo`` order: read back if saved, else run.

    The points left run side by side on worker processes (module docstring).
    """
    from microfab.io.sweep import run_sweep
    from microfab.machines.xy_stage.reference import read_point_summary

    fingerprint = st.fingerprint()
    done: dict[tuple[str, float], dict[str, Any]] = {}
    for case, a in todo if folder is not None else ():
        saved = read_point_summary(folder, case, a)
        if saved is not None and saved.get("fingerprint") == fingerprint:
            done[(case, a)] = saved
    left = [_Point(c, a) for c, a in todo if (c, a) not in done]
    workers = max(1, min(st.workers or usable_cores(), len(left)))
    report("points", len(done), len(todo))

    def finished(n: int, total: int, point: _Point, ok: bool) -> None:
        report("points", len(done) + n, len(todo))

    task = _PointTask(settings=st, paths=paths, models=models, folder=folder,
                      fingerprint=fingerprint)  # fmt: skip
    res = run_sweep(task, left, workers=workers, progress=finished)
    for point, row in zip(left, res.rows, strict=True):
        done[(point.case, point.a_max)] = row["summary"]
    return {key: done[key] for key in todo}


def _baseline_curves(
    st: ReferenceSettings, paths: dict[str, Any], tradeoff: dict[str, list[dict[str, float]]],
    letters: list[str],
) -> dict[str, list[dict[str, float]]]:  # fmt: skip
    """The eq. (15) baseline on the twin at longer times (pooled like the trade-off)."""
    out: dict[str, list[dict[str, float]]] = {}
    for name, cases in (("letters", letters), ("airfoil", ["airfoil"])):
        rows = tradeoff.get(name)
        if not rows:
            continue
        slowest = max(r["time_s"] for r in rows)
        out[name] = [
            {"time_s": f * slowest, "baseline_twin_l2": baseline_l2(
                [paths[c] for c in cases], f * slowest, st.twin)}
            for f in st.baseline_factors
        ]  # fmt: skip
    return out
