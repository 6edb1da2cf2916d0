"""The models shipped with microfab for the built-in XY stage twin, and how they were made.

The reference optimisation of seed 002 (§IV) needs the linear model (eq. 6) and the
per-axis networks (eq. 7) of the stage. For the built-in twin they ship with the package
(``microfab/data/xy_stage_models``, `microfab.optimize.models.builtin_models_dir`), so that
``microfab run examples/blackbox_stage_reference.toml`` and ``microfab reproduce
reference-opt`` run straight after install.

They are the ``stage-identify`` job's models with the job's own defaults (`SECTIONS`: the
`microfab.experiments.seed002_stage.job.SCHEMA` defaults, the coupling and PRBS/chirp
studies off, Table II's letter columns only), made by::

    python -m microfab.experiments.seed002_stage.shipped [--out DIR] [--work DIR]

(``make shipped-models``). Besides ``linear_model.json`` and ``ann/model`` the folder
holds ``trained.json`` (`write_record`): the sections that made them, the data digests the
training recorded and a summary of those data that can be compared with a tolerance
(`microfab.identify.ann_data.data_summary`), the validation σ per axis and beside it the
calibration's proxy σ on the same data (`microfab.machines.xy_stage.proxy`: the issue asks
the two within 25 %), Table II's letter cells, the wall times and the versions. `recheck`
recomputes, without training, what can be recomputed: the networks' data from the recorded
settings and the networks' errors on the validation runs and the letters. The data are
floats made by a simulation, so their bytes (the digests) depend on the CPU's BLAS
kernels: the test suite (``tests/experiments/seed002_stage/test_shipped.py``) compares the
summaries and the errors within tolerances measured across kernels and thread counts,
never the digests.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from microfab.experiments.kinds import Progress, no_progress
from microfab.io.runstore import canonical_settings

__all__ = ["RECORD", "SECTIONS", "recheck", "shipped_settings", "train_shipped", "write_record"]

#: The record of how the shipped models were made, beside them.
RECORD = "trained.json"

#: Job-file sections that differ from the ``stage-identify`` defaults (all else default).
SECTIONS: dict[str, dict[str, Any]] = {
    "studies": {"coupling": False, "classic": False},  # two more trainings, not shipped
    "cases": {"sweep_a_max": [1.0, 3.0]},  # Table II's columns only; Fig. 9 is the job's
    "linear": {"orders": []},  # the order check is the job's, not a model
}


def _sections(overrides: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Checked ``stage-identify`` sections: the schema's defaults with ``overrides``."""
    from microfab.experiments.seed002_stage.job import SCHEMA
    from microfab.io.job import parse_section

    return {
        sec: parse_section(overrides.get(sec, {}), keys, "shipped models", sec)
        for sec, keys in SCHEMA.items()
    }


def shipped_settings(sections: dict[str, dict[str, Any]] | None = None) -> Any:
    """The `StudySettings` of the shipped models (`SECTIONS`, or recorded ``sections``)."""
    from microfab.experiments.seed002_stage.job import config_from_sections

    return config_from_sections(_sections(SECTIONS if sections is None else sections))


def _letters(study: Any) -> dict[str, dict[str, dict[str, float] | None]]:
    """Table II's letter cells of the networks and the linear model, µm."""
    out: dict[str, dict[str, dict[str, float] | None]] = {}
    for a in study.settings.cases.table_a_max:
        row: dict[str, dict[str, float] | None] = {}
        for model in ("ann", "linear"):
            e = study.letters(a, model)
            row[model] = None if e is None else _stats(e.mean, e.std, e.axes)
        out[f"{a:g}"] = row
    return out


def _stats(mean: Any, std: Any, axes: Any) -> dict[str, float]:
    """μ and σ per axis (m, one value per axis), as ``mu_<axis>_um``, ``sigma_<axis>_um``."""
    out: dict[str, float] = {}
    for j, a in enumerate(axes):
        out[f"mu_{a}_um"] = float(mean[j]) * 1e6
        out[f"sigma_{a}_um"] = float(std[j]) * 1e6
    return out


def write_record(
    folder: Path,
    study: Any,
    sections: dict[str, Any],
    wall_s: float,
    summaries: dict[str, Any] | None = None,
    proxy: dict[str, float] | None = None,
) -> Path:
    """Write ``trained.json`` (module docstring) into ``folder``, atomically.

    ``summaries`` holds ``"train_summary"`` and ``"val_summary"``
    (`microfab.identify.ann_data.data_summary` of the networks' data), which `recheck`
    compares with a tolerance; the digests only tell whether the bytes are the same.
    ``proxy`` holds the calibration's proxy σ per axis on the same data, µm
    (`microfab.machines.xy_stage.proxy.proxy_sigma`), recorded beside the networks' σ.
    """
    import torch

    import microfab
    from microfab.io.atomic import atomic_write_json

    ann = study.ann
    info = ann.model.info
    record = {
        "what": "models of the stage-identify job on the built-in twin (seed 002 eqs. 6, 7)",
        "made_by": "python -m microfab.experiments.seed002_stage.shipped",
        "sections": sections,
        "data": {
            "train_digest": info["train_digest"],
            "val_digest": info["val_digest"],
            "train_windows": info["train_windows"],
            **(summaries or {}),
        },
        "validation": {
            a: {"mu_um": ann.validation[a].mu * 1e6, "sigma_um": ann.validation[a].sigma * 1e6}
            for a in ann.model.axes
        },
        "proxy": {a: {"sigma_um": v} for a, v in (proxy or {}).items()},
        "epochs": {a: info["axes"][a]["epochs"] for a in ann.model.axes},
        "linear_on_training": _stats(study.linear.mu_m, study.linear.sigma_m, ("x", "y")),
        "letters": _letters(study),
        "seconds": {**study.seconds, "wall": wall_s},
        "versions": {
            "microfab": microfab.__version__,
            "torch": torch.__version__,
            "python": platform.python_version(),
        },
    }
    path = folder / RECORD
    atomic_write_json(path, record)
    return path


def train_shipped(
    out: str | Path, work: str | Path | None = None, progress: Progress = no_progress
) -> Path:
    """Train the shipped models and write them, with ``trained.json``, into ``out``.

    ``work`` keeps the trainings' checkpoints (a rerun resumes); default a temporary
    folder. The models are written to a folder beside ``out`` first and moved in at the
    end, so an interrupted run leaves the old models as they were.
    """
    from microfab.experiments.seed002_stage.study import run_study
    from microfab.identify.ann_data import data_summary
    from microfab.identify.stage_ann import runs_of, save_ann_model
    from microfab.identify.stage_data import write_stage_model
    from microfab.machines.xy_stage.ann import ann_records
    from microfab.machines.xy_stage.proxy import proxy_sigma

    out = Path(out)
    settings = shipped_settings()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="shipped-work-") as tmp:
        study = run_study(settings, Path(work) if work else Path(tmp), progress)
    wall = time.perf_counter() - t0
    # the networks' data again (deterministic, this process): their comparable summary
    train, val = ann_records(dataclasses.replace(settings.ann, twin=settings.twin))
    summaries = {
        "train_summary": data_summary(runs_of(train.records)),
        "val_summary": data_summary(runs_of(val.records)),
    }
    px = proxy_sigma(train.records, val.records, train.dt)  # the calibration's proxy
    proxy = {"x": px[0] * 1e6, "y": px[1] * 1e6}
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    try:
        write_stage_model(stage / "linear_model.json", study.linear.stage_model())
        save_ann_model(study.ann.model, stage / "ann" / "model")
        write_record(stage, study, canonical_settings(_sections(SECTIONS)), wall, summaries, proxy)
        old = out.with_name(f".{out.name}-old")
        if old.exists():
            shutil.rmtree(old)
        if out.exists():
            out.rename(old)
        stage.rename(out)
        if old.exists():
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return out


def recheck(folder: str | Path) -> dict[str, Any]:
    """Recompute, without training, what ``trained.json`` records (module docstring).

    Returns
    -------
    dict
        ``"recorded"`` (the record), ``"train_digest"`` and ``"val_digest"`` (of the data
        made again from the recorded settings: equal to the record's only on a CPU that
        computes the same bits), ``"train_summary"`` and ``"val_summary"`` (their
        `data_summary`), ``"validation"`` (the shipped networks'
        μ, σ per axis on those validation runs, µm), ``"letters"`` (Table II's letter
        cells of the shipped networks, per a_max, µm), ``"model"`` and ``"settings"``.
    """
    from microfab.identify.ann_data import data_digest, data_summary
    from microfab.identify.stage_ann import read_ann_stage_model, runs_of
    from microfab.machines.xy_stage.ann import ann_records

    folder = Path(folder)
    record = json.loads((folder / RECORD).read_text(encoding="utf-8"))
    settings = shipped_settings(record["sections"])
    ann = dataclasses.replace(settings.ann, twin=settings.twin)
    train, val = ann_records(ann)
    model = read_ann_stage_model(folder / "ann" / "model")
    errors = model.errors(val.records)
    letters = _letter_cells(settings, model)
    return {
        "recorded": record,
        "train_digest": data_digest(runs_of(train.records)),
        "val_digest": data_digest(runs_of(val.records)),
        "train_summary": data_summary(runs_of(train.records)),
        "val_summary": data_summary(runs_of(val.records)),
        "validation": {
            a: {"mu_um": float(errors.mean[j]) * 1e6, "sigma_um": float(errors.std[j]) * 1e6}
            for j, a in enumerate(errors.axes)
        },
        "letters": letters,
        "model": model,
        "settings": settings,
    }


def _letter_cells(settings: Any, model: Any) -> dict[str, dict[str, float]]:
    """Table II's letter cells of ``model`` (µm), the cases played as the job plays them."""
    from microfab.experiments.seed002_stage.study import pooled_letters, study_cases

    # every case, as the job plays them: each run's noise seed is its place in the list
    _, cases = study_cases(settings, {"ann": model}, settings.cases.a_max_values)
    out = {}
    for a in settings.cases.table_a_max:
        e = pooled_letters(cases, a, "ann")
        out[f"{a:g}"] = _stats(e.mean, e.std, e.axes)
    return out


def main(argv: list[str] | None = None) -> None:
    """``python -m microfab.experiments.seed002_stage.shipped``: train and write the models."""
    from microfab.optimize.models import builtin_models_dir

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=builtin_models_dir(), help="models folder")
    p.add_argument("--work", type=Path, default=None, help="checkpoints (a rerun resumes)")
    args = p.parse_args(argv)

    def show(task: str, done: int, total: int | None) -> None:
        print(f"{task}: {done}/{total}" if total else task, flush=True)

    path = train_shipped(args.out, args.work, show)
    print(json.dumps(json.loads((path / RECORD).read_text())["validation"], indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
