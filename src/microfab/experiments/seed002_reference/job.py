"""The ``stage-reference-opt`` job kind and the ``reference-opt`` reproduction (seed 002 §IV-V).

Job file (``examples/blackbox_stage_reference.toml``)::

    [job]
    kind = "stage-reference-opt"
    out = "report/stage_reference"

    [models]    # dir: a stage-identify job's output; "" (default): the shipped models
    [twin]      # the twin the models were identified on: noise seed, noise on/off
    [cases]     # shapes, Table III's a_max, the airfoil's extra a_max, μ, sizes
    [tradeoff]  # Figs. 16-17: a_max of the letters and the airfoil, longer baselines
    [stage2]    # Gauss-Newton iterations
    [generations]  # the networks' generations (seed 002 Fig. 7): count, shapes, epochs

Every key, its unit and its range is in `SCHEMA`; unknown keys are refused. The run
(`microfab.experiments.seed002_reference.study.run_reference`) writes every finished
point atomically under ``out/points/`` (a rerun skips it; stage 2 checkpoints there every
few iterations and resumes), ``sizes.json`` and ``summary.json``. With ``[generations]
count`` ≥ 2 the networks' generations run first under ``out/generations/``
(`microfab.machines.xy_stage.generations`), then Table III per generation
(``out/generation<g>/``) and the study with the last generation's models; the report adds
Table III per generation and the networks-against-twin table per generation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from microfab.experiments.kinds import JobKind, Progress, Reproduction, ReproductionResult
from microfab.experiments.seed002_reference.study import (
    ReferenceSettings,
    ReferenceStudy,
    run_reference,
)
from microfab.experiments.seed002_reference.tables import comparison_tables, study_warnings
from microfab.io.atomic import atomic_write_json
from microfab.io.job import Key
from microfab.machines.xy_stage import cases as xy_stage_cases
from microfab.machines.xy_stage import machine as xy_stage
from microfab.machines.xy_stage.cases import CASES, CaseSizes
from microfab.machines.xy_stage.generations import DEFAULT_SHAPES, SHAPES
from microfab.machines.xy_stage.machine import TwinSettings
from microfab.machines.xy_stage.reference import HOLD_S
from microfab.report.tables import Table

__all__ = [
    "REFERENCE_OPT_REPRODUCTION",
    "SCHEMA",
    "STAGE_REFERENCE_OPT",
    "ReferenceResult",
    "config_from_sections",
]

_F = "float"
#: The shipped models' folder in the package data (`microfab.optimize.models`): part of
#: a run's fingerprint, so a release with retrained models does not resume old points.
SHIPPED_MODELS = "xy_stage_models"

SCHEMA: dict[str, tuple[Key, ...]] = {
    "models": (
        Key(name="dir", type="str", default="builtin", path=True,
            help="output of a stage-identify job (linear_model.json and ann/model), "
                 "beside the job file or in the working directory; 'builtin' (default): the "
                 "models shipped with microfab (the built-in twin's)"),
    ),
    "twin": (
        Key(name="seed", type="int", default=0, low=0, help="noise seed (run k uses seed + k)"),
        Key(name="noise", type="bool", default=True, help="2 µm output noise (seed eq. 3)"),
    ),
    "cases": (
        Key(name="names", type="str", default=",".join(CASES),
            help="shapes, comma-separated, of u, r, c, h, airfoil"),
        Key(name="a_max", type="float_list", default=(1.0, 3.0), low=0.0, high=40.0,
            unit="m/s²", help="Table III's columns (seed: 1 and 3)"),
        Key(name="airfoil_a_max", type="float_list", default=(2.0,), low=0.0, high=40.0,
            unit="m/s²", allow_empty=True, help="more airfoil points (seed §V-A: 2)"),
        Key(name="tolerance_um", type=_F, default=20.0, low=0.0, high=1000.0, unit="µm",
            help="μ (seed: 20)"),
        Key(name="letter_height_mm", type=_F, default=0.0, low=0.0, high=200.0, unit="mm",
            help="letter size; 0: the sizing step (stage 1 gives 'r' 0.807 s at 1 m/s²)"),
        Key(name="airfoil_chord_mm", type=_F, default=0.0, low=0.0, high=370.0, unit="mm",
            help="airfoil chord; 0: the sizing step (1.322 s at 1 m/s²)"),
    ),
    "tradeoff": (
        Key(name="letters_a_max", type="float_list", default=(), low=0.0, high=40.0,
            unit="m/s²", allow_empty=True, help="Fig. 16's points (seed: 0.1-3.3)"),
        Key(name="airfoil_a_max", type="float_list", default=(), low=0.0, high=40.0,
            unit="m/s²", allow_empty=True, help="Fig. 17's points (seed: 0.1-10)"),
        Key(name="baseline_factors", type="float_list", default=(1.5, 2.0, 3.0, 4.0, 6.0),
            low=1.0, high=100.0, allow_empty=True,
            help="longer baseline runs, times the slowest optimised time"),
    ),
    "stage2": (
        Key(name="max_iter", type="int", default=30, low=1, high=1000,
            help="Gauss-Newton iterations"),
    ),
    "generations": (
        Key(name="count", type="int", default=1, low=1, high=10,
            help="the networks' generations (seed 002 Fig. 7: 3); 1: the given models only"),
        Key(name="shapes", type="str", default=",".join(DEFAULT_SHAPES),
            help=f"regular shapes the generations optimise, comma-separated, of "
                 f"{', '.join(SHAPES)} (seed §III-C.2: circles, polygons, spirals)"),
        Key(name="size_mm", type=_F, default=20.0, low=0.1, high=180.0, unit="mm",
            help="their size: radius, circumradius, the spiral's outer radius (assumed 20)"),
        Key(name="a_max", type="float_list", default=(1.0, 3.0), low=0.0, high=40.0,
            unit="m/s²", help="their a_max (assumed Table III's 1 and 3)"),
        Key(name="retrain_epochs", type="int", default=20, low=1, high=1000,
            help="most epochs of a retraining (warm start; early stopping decides first)"),
        Key(name="data_s", type=_F, default=0.0, low=0.0, high=3600.0, unit="s",
            help="generation 1's data length; 0: the seed's (about 525 s)"),
    ),
}  # fmt: skip


def _names(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in CASES]
    if not names or unknown:
        raise ValueError(
            f"[cases] names must be a comma-separated list of {', '.join(CASES)}, got {text!r}"
        )
    return names


def config_from_sections(sec: dict[str, dict[str, Any]]) -> ReferenceSettings:
    """`ReferenceSettings` from checked job-file sections (`SCHEMA`).

    Raises
    ------
    ValueError
        No model directory, unknown shapes, a zero a_max or tolerance, one size given
        without the other.
    """
    mo, tw, ca, tr, s2 = (sec[k] for k in ("models", "twin", "cases", "tradeoff", "stage2"))
    ge = sec["generations"]
    shapes = tuple(n.strip() for n in ge["shapes"].split(",") if n.strip())
    if not shapes or any(n not in SHAPES for n in shapes):
        raise ValueError(
            f"[generations] shapes must be a comma-separated list of {', '.join(SHAPES)}, "
            f"got {ge['shapes']!r}"
        )
    if any(v <= 0 for v in ge["a_max"]):
        raise ValueError(f"[generations] a_max must hold accelerations above 0 m/s², got "
                         f"{list(ge['a_max'])}")  # fmt: skip
    for key, vals in (("[cases] a_max", ca["a_max"]), ("[cases] airfoil_a_max",
                      ca["airfoil_a_max"]), ("[tradeoff] letters_a_max", tr["letters_a_max"]),
                      ("[tradeoff] airfoil_a_max", tr["airfoil_a_max"])):  # fmt: skip
        if any(v <= 0 for v in vals):
            raise ValueError(f"{key} must hold accelerations above 0 m/s², got {list(vals)}")
    if ca["tolerance_um"] <= 0:
        raise ValueError(f"[cases] tolerance_um must be above 0, got {ca['tolerance_um']:g}")
    h, c = ca["letter_height_mm"], ca["airfoil_chord_mm"]
    if (h > 0) != (c > 0):
        raise ValueError("[cases] give both letter_height_mm and airfoil_chord_mm, or neither")
    sizes = CaseSizes(h * 1e-3, c * 1e-3) if h > 0 else None
    return ReferenceSettings(
        models_dir=mo["dir"],
        twin=TwinSettings(seed=tw["seed"], noise=tw["noise"], hold_s=HOLD_S),
        cases=_names(ca["names"]),
        a_max=tuple(ca["a_max"]),
        airfoil_extra=tuple(ca["airfoil_a_max"]),
        tolerance_m=ca["tolerance_um"] / 1e6,
        sizes=sizes,
        tradeoff_letters=tuple(tr["letters_a_max"]),
        tradeoff_airfoil=tuple(tr["airfoil_a_max"]),
        baseline_factors=tuple(tr["baseline_factors"]),
        stage2_max_iter=s2["max_iter"],
        generations=ge["count"],
        generation_shapes=shapes,
        generation_size_m=ge["size_mm"] * 1e-3,
        generation_a_max=tuple(ge["a_max"]),
        retrain_epochs=ge["retrain_epochs"],
        generation_data_s=ge["data_s"] if ge["data_s"] > 0 else None,
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class ReferenceResult:
    """A finished ``stage-reference-opt`` job."""

    study: ReferenceStudy

    def comparison(self) -> tuple[Table, ...]:
        """Table III (twin and networks), times, trade-off, stages, every point."""
        return comparison_tables(self.study)

    def failures(self) -> tuple[str, ...]:
        """Points whose optimisation failed, with the reason.

        A point whose stage 2 ended infeasible is not a failure (it ran and returned its
        least violating iterate): it is in `warnings`, the report's notes and the table
        of what the optimisation reached.
        """
        return tuple(f"{c} at {a:g} m/s²: {p['error']}" for (c, a), p in
                     sorted(self.study.points.items()) if "error" in p)  # fmt: skip

    def warnings(self) -> tuple[str, ...]:
        """What the user should be told though nothing failed (issue 43).

        The networks' recorded σ above μ, stage 2 infeasible, the networks and the linear
        model apart by more than μ (`tables.study_warnings`).
        """
        return tuple(study_warnings(self.study))

    def summary(self) -> dict[str, Any]:
        """The numbers of the tables, JSON-ready."""
        from microfab.experiments.seed002_reference.tables import study_summary

        return study_summary(self.study)


def _run(config: ReferenceSettings, out: Path, progress: Progress) -> ReferenceResult:
    study = run_reference(config, out, progress)
    result = ReferenceResult(study=study)
    atomic_write_json(out / "summary.json", result.summary())
    return result


def _write_report(result: ReferenceResult, out: Path, title: str) -> Path:
    from microfab.experiments.seed002_reference.report import write_report

    return write_report(result.study, out, title)


def _preflight(settings: ReferenceSettings) -> None:
    """The models folder holds a stage-identify job's models (checked before any work)."""
    from microfab.optimize.models import check_models_dir

    check_models_dir(settings.models_dir)


def _reproduce_preflight(options: dict[str, Any]) -> None:
    """The ``models`` option names models (shipped by default; checked before any work)."""
    from microfab.optimize.models import check_models_dir

    check_models_dir(options["models"])


def _reproduce(options: dict[str, Any], progress: Progress) -> ReproductionResult:
    from microfab.experiments.seed002_reference.tables import NOTES, study_summary

    _reproduce_preflight(options)  # also when called as a library, not only by the CLI
    folder = options["checkpoints"]
    settings = ReferenceSettings(
        models_dir=options["models"],
        twin=TwinSettings(seed=options["seed"], noise=options["noise"], hold_s=HOLD_S),
        tradeoff_letters=(0.1, 0.3, 1.0, 2.0, 3.3) if options["tradeoff"] else (),
        tradeoff_airfoil=(0.1, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0) if options["tradeoff"] else (),
        generations=options["generations"],
    )
    study = run_reference(settings, Path(folder) if folder else None, progress)
    return ReproductionResult(
        tables=comparison_tables(study), notes=NOTES, data=study_summary(study)
    )


STAGE_REFERENCE_OPT = JobKind(
    name="stage-reference-opt",
    schema=SCHEMA,
    make_config=config_from_sections,
    run=_run,
    write_report=_write_report,
    default_title="Black-box XY stage: optimised references",
    data_files=xy_stage.DATA_FILES + xy_stage_cases.DATA_FILES + (SHIPPED_MODELS,),
    preflight=_preflight,
)

REFERENCE_OPT_REPRODUCTION = Reproduction(
    name="reference-opt",
    run=_reproduce,
    options=(
        Key(name="models", type="str", default="builtin", path=True,
            help="output folder of a stage-identify job; 'builtin' (default): the shipped "
                 "models"),
        Key(name="seed", type="int", default=0, low=0, help="noise seed"),
        Key(name="noise", type="bool", default=True, help="2 µm output noise on"),
        Key(name="tradeoff", type="bool", default=True,
            help="also the trade-off points (about 30 more optimisations)"),
        Key(name="checkpoints", type="str", default="",
            help="folder for the points and stage-2 checkpoints, so a rerun resumes"),
        Key(name="generations", type="int", default=1, low=1, high=10,
            help="the networks' generations first (seed 002 Fig. 7: 3), Table III per "
                 "generation; 1: the models as given"),
    ),
    data_files=xy_stage.DATA_FILES + xy_stage_cases.DATA_FILES + (SHIPPED_MODELS,),
    run_folder_option="checkpoints",
    preflight=_reproduce_preflight,
)  # fmt: skip
