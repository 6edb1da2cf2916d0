"""The networks' generations of seed 002 (§III-C.2, Fig. 7): optimise, play, add, retrain.

Seed 002 §III-C.2: a first-generation network is trained on random runs and regular
shapes at constant speeds (`microfab.machines.xy_stage.ann.ann_records`); it is "used in
the optimization methodology of Section IV applied to the same regular geometries"; the
optimised inputs are applied to the machine, the data added, and the network "trained
further", giving the second generation; the cycle repeats (Table II/III use the third).
The linear model is not refitted ("no added benefit in refitting the linear model").

`run_generations` does that on the twin, resumable through a folder:

1. generation ``g`` (from 1) reads its models (generation 1: the given models folder,
   `microfab.optimize.models.load_models`; later ones: ``gen<g>/models``, the linear model
   copied from generation 1 and the retrained networks);
2. each regular shape at each ``a_max`` (`GenerationSettings`) goes through both stages
   and is played on the twin (`microfab.machines.xy_stage.reference.run_point`, whose
   10 kHz record of the optimised command is kept);
3. scored: the networks' prediction from rest against the twin's output for those inputs,
   μ and σ per axis in µm (``predicted - measured``, pooled over the generation's runs:
   what Table II columns 2-3 measure on the letters), and the twin's contour error of the
   optimised references (L2 pooled, largest L∞, m; eqs. 16-18 at the 400 Hz instants);
4. unless ``g`` is the last: the runs are split 80/20 by whole runs
   (`microfab.identify.stage_ann.split_records`, seeded ``ann.seed + g``; a single run
   goes to training) and added to generation 1's training and validation runs
   (`ann_records` with ``settings.ann``: its validation runs stay as they were); the
   networks of generation ``g + 1`` are trained warm from generation ``g``'s weights and
   scaling (`microfab.identify.ann_train.train_ann` ``init``) for at most
   ``retrain_epochs`` epochs, early-stopped on the grown validation set, the learning
   rate continuing where generation ``g``'s training left it (`continued_rate`).

Folder layout (every file written atomically, `microfab.io.atomic`)::

    generations.json          the settings (a folder of other settings is refused)
    gen<g>/runs.npz           the played optimised runs (u_<k>, y_<k>, m, 10 kHz)
    gen<g>/generation.json    points, scores, the split (written last: a generation is
                              finished when this file is there)
    gen<g>/models/            linear_model.json and ann/model (g >= 2)
    gen<g>/training.json      the retraining's summary (written after the models)
    gen<g>/checkpoints/       the retraining's checkpoints (an interrupted one resumes)

A rerun skips finished generations and finished retrainings; raising the count extends a
finished folder. Noise seeds of the optimised plays: ``twin.seed + 20 000 + 1 000 g + k``
for point ``k`` (assumed: fresh noise for every run on the "machine", apart from the
training runs' seeds and the validation runs' 10 000 above them).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.geometry.path import Path as Contour
from microfab.geometry.shapes import circle, regular_polygon, spiral
from microfab.identify.stage_data import StageRecord
from microfab.io.atomic import atomic_save_npz, atomic_write_bytes, atomic_write_json
from microfab.io.runstore import RunRefusedError, canonical_settings, settings_difference
from microfab.machines.xy_stage import reference as xy_stage_reference
from microfab.machines.xy_stage.ann import AnnSettings, ann_records
from microfab.machines.xy_stage.machine import Played, TwinSettings
from microfab.optimize.metrics import DeviationNorms
from microfab.optimize.models import Models, load_models, models_digest, resolve_models_dir
from microfab.optimize.problem import ContourProblem

__all__ = [
    "DEFAULT_SHAPES",
    "PLAY_SEED_OFFSET",
    "SHAPES",
    "Generation",
    "GenerationSettings",
    "GenerationsResult",
    "continued_rate",
    "regular_shapes",
    "run_generations",
]

#: Noise seeds of the optimised plays sit this far above the twin's seed (assumed).
PLAY_SEED_OFFSET = 20_000
_FORMAT = 1
_MANIFEST = "generations.json"


def _spiral(size_m: float) -> Contour:
    # two turns out to ``size_m``: r = b θ, θ in [0, 4π] as Fig. 1's, b = size / 4π
    return spiral(size_m / (4 * math.pi), 0.0, 4 * math.pi)


#: The regular shapes of §III-C.2 ("circles, polygons, and spirals"), of size ``s`` m
#: (radius, circumradius, outer radius), centred on the origin (inside Table I's workspace).
SHAPES: dict[str, Callable[[float], Contour]] = {
    "circle": circle,
    "square": lambda s: regular_polygon(4, s),
    "hexagon": lambda s: regular_polygon(6, s),
    "spiral": _spiral,
}
#: Assumed: one of each kind the seed names (with a sharp-cornered and a blunt polygon).
DEFAULT_SHAPES = ("circle", "square", "hexagon", "spiral")


def regular_shapes(names: Sequence[str], size_m: float) -> dict[str, Contour]:
    """The named shapes of `SHAPES` at ``size_m`` (m), refusing unknown names."""
    unknown = [n for n in names if n not in SHAPES]
    if not names or unknown:
        raise ValueError(f"shapes must be names of {', '.join(SHAPES)}, got {list(names)}")
    if not 0 < size_m <= 0.18:  # seed 002 Table I: the workspace is ±0.19 m
        raise ValueError(f"size must lie in (0, 0.18] m (Table I's ±0.19 m), got {size_m}")
    return {n: SHAPES[n](size_m) for n in names}


@dataclass(frozen=True, kw_only=True)
class GenerationSettings:
    """What `run_generations` runs (module docstring).

    Parameters
    ----------
    models_dir : str
        Generation 1's models (a ``stage-identify`` output; ``""``: the shipped models).
    ann : AnnSettings
        Generation 1's data (`ann_records`: length, shares, seed, twin) and the
        retraining's threads and workers. Generation 1's networks should have been
        trained on these data; whether they were is recorded (``start_data_matches``).
    shapes : tuple of str
        Of `SHAPES`.
    size_m : float
        Their size, m (assumed 20 mm: a circle then takes about 0.9 s at 1 m/s², near
        Table III's letter r, 0.807 s, so M stays within the seed's 200-1000).
    a_max : tuple of float
        m/s² (assumed Table III's 1 and 3).
    tolerance_m : float
        μ, m (seed 002 §V: 20 µm).
    stage2_max_iter : int
        Stage 2's Gauss-Newton iterations.
    retrain_epochs : int
        Most epochs of a retraining (assumed 20: the start is already trained; early
        stopping on the validation runs decides first).
    count : int
        Generations (seed: 3, i.e. two retrainings); not fingerprinted, so a finished
        folder can be extended.
    """

    models_dir: str = ""
    ann: AnnSettings = field(default_factory=AnnSettings)
    shapes: tuple[str, ...] = DEFAULT_SHAPES
    size_m: float = 20e-3  # assumed, see above
    a_max: tuple[float, ...] = (1.0, 3.0)  # assumed: Table III's columns
    tolerance_m: float = 20e-6  # seed 002 §V: μ = 20 µm
    stage2_max_iter: int = 30
    retrain_epochs: int = 20  # assumed, see above
    count: int = 3  # seed 002 §III-D: the third generation

    def __post_init__(self) -> None:
        regular_shapes(self.shapes, self.size_m)
        if not self.a_max or any(not 0 < a <= 40 for a in self.a_max):
            raise ValueError(f"a_max must hold values in (0, 40] m/s², got {list(self.a_max)}")
        for name in ("stage2_max_iter", "retrain_epochs", "count"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")

    def fingerprint(self) -> dict[str, Any]:
        """What decides the generations' numbers (JSON; not the count, threads, workers)."""
        ann = {k: v for k, v in dataclasses.asdict(self.ann).items()
               if k not in ("threads", "workers")}  # fmt: skip
        return canonical_settings({
            "models": models_digest(self.models_dir), "ann": ann, "shapes": self.shapes,
            "size_m": self.size_m, "a_max": self.a_max, "tolerance_m": self.tolerance_m,
            "stage2_max_iter": self.stage2_max_iter, "retrain_epochs": self.retrain_epochs,
        })  # fmt: skip

    def play_twin(self, generation: int, k: int) -> TwinSettings:
        """The twin point ``k`` of ``generation`` is played on (module docstring)."""
        seed = self.ann.twin.seed + PLAY_SEED_OFFSET + 1000 * generation + k
        return dataclasses.replace(self.ann.twin, seed=seed, hold_s=xy_stage_reference.HOLD_S)


@dataclass(frozen=True, eq=False)
class Generation:
    """One generation: its models and how they did on the references they optimised.

    Attributes
    ----------
    index : int
        From 1.
    models_dir : str
        Its models folder (`load_models`).
    points : list of dict
        Per shape and a_max: ``shape``, ``a_max``, ``duration_s``, ``m``, ``twin`` and
        ``ann`` (norms, m), ``improvement`` (Table III, %), ``network_error`` (per axis
        ``mu_um``, ``sigma_um``, ``n``); or ``error`` (a stage failed).
    network_error : dict of str to dict
        Per axis ``mu_um``, ``sigma_um``, ``n``: networks minus twin, pooled over the
        generation's optimised runs at 10 kHz (hold included).
    twin : dict of str to float
        ``l2_m`` (pooled) and ``linf_m`` (largest) of the optimised references on the twin.
    split : dict of str to list of str
        Which runs went to ``train`` and ``validation`` of the next generation.
    training : dict or None
        The retraining that made this generation (None for generation 1): ``epochs``,
        ``best_epoch`` per axis, ``validation`` σ/μ per axis (µm), ``train_runs``,
        ``validation_runs``, ``start_data_matches``.
    """

    index: int
    models_dir: str
    points: list[dict[str, Any]]
    network_error: dict[str, dict[str, float]]
    twin: dict[str, float]
    split: dict[str, list[str]]
    training: dict[str, Any] | None = None


@dataclass(frozen=True, eq=False)
class GenerationsResult:
    """What `run_generations` found: one `Generation` per generation, in order."""

    settings: GenerationSettings
    generations: tuple[Generation, ...]


Progress = Callable[[str, int, int | None], None]


def _check_folder(folder: Path, fp: dict[str, Any]) -> None:
    """Refuse a folder written with other settings (naming them); record them if new."""
    path = folder / _MANIFEST
    if path.is_file():
        saved = json.loads(path.read_text())
        diff = settings_difference(saved.get("settings", {}), fp)
        if saved.get("format") != _FORMAT or diff:
            what = "; ".join(diff) or f"format {saved.get('format')} -> {_FORMAT}"
            raise RunRefusedError(
                f"{folder}: generations written with other settings ({what}); use another "
                "folder or the same settings"
            )
        return
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_json(path, {"format": _FORMAT, "settings": fp})


def _stats(errors: dict[str, Any]) -> dict[str, dict[str, float]]:
    """`ErrorStats` per axis (m) as JSON in µm."""
    return {a: {"mu_um": e.mu * 1e6, "sigma_um": e.sigma * 1e6, "n": e.n}
            for a, e in errors.items()}  # fmt: skip


def _read_runs(gdir: Path, names: Sequence[str]) -> list[StageRecord]:
    with np.load(gdir / "runs.npz") as z:
        return [StageRecord(name=n, u=z[f"u_{k}"], y=z[f"y_{k}"]) for k, n in enumerate(names)]


def _play_generation(
    g: int, st: GenerationSettings, models: Models, gdir: Path, report: Progress
) -> dict[str, Any]:
    """Optimise every shape at every a_max with ``models``, play, score; write, return."""
    from microfab.identify.stage_ann import split_records
    from microfab.optimize.stage1 import Stage1Error, Stage1Settings
    from microfab.optimize.stage2 import Stage2Settings

    paths = regular_shapes(st.shapes, st.size_m)
    todo = [(s, a) for s in st.shapes for a in st.a_max]
    points: list[dict[str, Any]] = []
    records: list[StageRecord] = []
    norms: list[DeviationNorms] = []
    for k, (shape, a) in enumerate(todo):
        report(f"generation {g}: points", k, len(todo))
        problem = ContourProblem(paths[shape], a_max=a, tolerance_m=st.tolerance_m)
        twin = st.play_twin(g, k)
        name = f"gen{g}_{shape}_a{a:g}"
        try:
            res = xy_stage_reference.run_point(
                name, problem, models, twin=twin, stage1=Stage1Settings(),
                stage2=Stage2Settings(max_iter=st.stage2_max_iter),
            )  # fmt: skip
        except (Stage1Error, ValueError) as exc:
            points.append({"shape": shape, "a_max": a, "error": f"{type(exc).__name__}: {exc}"})
            continue
        rec = dataclasses.replace(res.records["optimised"], name=name)  # the 10 kHz run
        records.append(rec)
        norms.append(res.scores["optimised_twin"])
        err = models.networks.metrics([(rec.u, rec.y)])
        points.append({
            "shape": shape, "a_max": a, "run": name, "duration_s": res.duration,
            "m": res.reference.m, "twin": res.scores["optimised_twin"].as_dict(),
            "ann": res.scores["optimised_ann"].as_dict(), "improvement": res.improvement(),
            "network_error": _stats(err), "limited": res.limited["optimised"],
        })  # fmt: skip
    report(f"generation {g}: points", len(todo), len(todo))
    if len(records) >= 2:
        train, val = split_records(records, st.ann.validation, seed=st.ann.seed + g)
    else:  # one run cannot be split by whole runs: it trains
        train, val = list(records), []
    pooled = None if not norms else DeviationNorms.pooled(norms)
    summary = {
        "format": _FORMAT,
        "settings": st.fingerprint(),
        "generation": g,
        "points": points,
        "runs": [r.name for r in records],
        "network_error": _stats(models.networks.metrics([(r.u, r.y) for r in records]))
        if records else {},
        "twin": {} if pooled is None else {"l2_m": pooled.l2, "linf_m": pooled.linf},
        "split": {"train": [r.name for r in train], "validation": [r.name for r in val]},
    }  # fmt: skip
    gdir.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {}
    for i, r in enumerate(records):
        arrays[f"u_{i}"], arrays[f"y_{i}"] = r.u, r.y
    atomic_save_npz(gdir / "runs.npz", **arrays)
    atomic_write_json(gdir / "generation.json", summary)  # last: the generation is done
    return summary


def _saved(path: Path, fp: dict[str, Any]) -> dict[str, Any] | None:
    """A generation's or training's JSON written with these settings, else None."""
    if not path.is_file():
        return None
    try:
        saved = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return saved if saved.get("settings") == fp else None


def continued_rate(model: Any) -> float:
    """The learning rate a retraining of ``model`` starts at: where its training ended.

    ``learning_rate · lr_decay^epochs`` of its configuration, with the fewest epochs of
    its axes (the higher rate). Assumed: "trained further" (§III-C.2) read as the same
    decaying schedule continued; restarting at the first rate moves the trained weights
    by steps sized for untrained ones.
    """
    epochs = [v.get("epochs", 0) for v in model.info.get("axes", {}).values()]
    n = min(epochs) if epochs else 0
    return float(model.config.learning_rate * model.config.lr_decay**n)


class _Data:
    """Generation 1's played data, made on first use (about 75 s at the seed's length)."""

    def __init__(self, ann: AnnSettings) -> None:
        self.ann = ann
        self._played: tuple[Played, Played] | None = None

    def get(self) -> tuple[Played, Played]:
        if self._played is None:
            self._played = ann_records(self.ann)
        return self._played


def _retrain(
    g: int, st: GenerationSettings, folder: Path, prev: Models, data: _Data,
    report: Progress,
) -> dict[str, Any]:  # fmt: skip
    """Generation ``g``'s models: generation ``g - 1``'s networks trained further."""
    from microfab.identify.ann_data import data_digest
    from microfab.identify.stage_ann import runs_of, save_ann_model, train_stage_ann

    gdir = folder / f"gen{g}"
    train0, val0 = data.get()
    train, val = list(train0.records), list(val0.records)
    for k in range(1, g):
        done = json.loads((folder / f"gen{k}" / "generation.json").read_text())
        by_name = {r.name: r for r in _read_runs(folder / f"gen{k}", done["runs"])}
        train += [by_name[n] for n in done["split"]["train"]]
        val += [by_name[n] for n in done["split"]["validation"]]
    start = prev.networks
    config = dataclasses.replace(start.config, max_epochs=st.retrain_epochs,
                                 learning_rate=continued_rate(start),
                                 threads=st.ann.threads, workers=st.ann.workers)  # fmt: skip

    def epoch(rec: Any) -> None:
        report(f"generation {g}: retraining {rec.axis}", rec.epoch, st.retrain_epochs)

    fit = train_stage_ann(train, val, config, checkpoint_dir=gdir / "checkpoints",
                          progress=epoch, init=start)  # fmt: skip
    mdir = gdir / "models"
    save_ann_model(fit.model, mdir / "ann" / "model")
    lin = resolve_models_dir(st.models_dir) / "linear_model.json"  # not refitted (§III-C.2)
    atomic_write_bytes(mdir / "linear_model.json", lin.read_bytes())
    axes = fit.model.info.get("axes", {})
    summary = {
        "settings": st.fingerprint(),
        "generation": g,
        "epochs": {a: v.get("epochs") for a, v in axes.items()},
        "best_epoch": {a: v.get("best_epoch") for a, v in axes.items()},
        "validation": _stats(fit.validation),
        "train_runs": len(train),
        "validation_runs": len(val),
        "start_data_matches": start.info.get("train_digest")
        == data_digest(runs_of(train0.records)),
    }  # fmt: skip
    atomic_write_json(gdir / "training.json", summary)  # after the models: done
    return summary


def run_generations(
    settings: GenerationSettings, folder: str | Path, progress: Progress | None = None
) -> GenerationsResult:
    """Run (or resume) ``settings.count`` generations in ``folder`` (module docstring).

    Parameters
    ----------
    settings : GenerationSettings
    folder : path
        Where everything is kept; a rerun resumes there.
    progress : callable, optional
        ``progress(task, done, total)``.

    Returns
    -------
    GenerationsResult

    Raises
    ------
    microfab.io.runstore.RunRefusedError
        ``folder`` holds generations of other settings (nothing is written then).
    ValueError
        Unreadable models (`load_models`).
    """
    report = progress or (lambda task, done, total: None)
    st = settings
    root = Path(folder)
    fp = st.fingerprint()
    _check_folder(root, fp)
    data = _Data(st.ann)
    out: list[Generation] = []
    models = load_models(st.models_dir)
    for g in range(1, st.count + 1):
        gdir = root / f"gen{g}"
        training = None
        mdir = str(resolve_models_dir(st.models_dir))
        if g > 1:
            training = _saved(gdir / "training.json", fp)
            if training is None or not (gdir / "models" / "ann" / "model" / "model.json").is_file():
                training = _retrain(g, st, root, models, data, report)
            mdir = str(gdir / "models")
            models = load_models(mdir)
        summary = _saved(gdir / "generation.json", fp)
        if summary is None:
            summary = _play_generation(g, st, models, gdir, report)
        out.append(Generation(index=g, models_dir=mdir, points=summary["points"],
                              network_error=summary["network_error"], twin=summary["twin"],
                              split=summary["split"], training=training))  # fmt: skip
    return GenerationsResult(settings=st, generations=tuple(out))
