"""The ``stage-identify`` job kind and the ``stage-models`` reproduction (seed 002 part 1).

Job file (``examples/blackbox_stage_identify.toml``)::

    [job]
    kind = "stage-identify"
    out = "report/stage_identify"

    [twin]      # noise seed, noise on/off, hold after each run
    [linear]    # random data (600 s, a <= 5 m/s²), order, decimation, order check
    [ann]       # networks: data, split, epochs, windows per epoch, threads
    [cases]     # letters and airfoil: Table II's a_max, Fig. 9's sweep, the sizing times
    [studies]   # coupling (both axes' commands) and PRBS/chirp-trained networks

Every key, its unit and its range is in `SCHEMA`; unknown keys are refused. The run
(`microfab.experiments.seed002_stage.study.run_study`) writes atomically, into ``out``:
``summary.json``, the linear model ``linear_model.json`` and each network model
directory (``ann/model``, ``ann_coupled/model``, ``ann_classic/model``), all readable by
``microfab identify validate``. Each training checkpoints under its ``checkpoints/`` every
epoch and a rerun resumes it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from microfab.experiments.kinds import JobKind, Progress, Reproduction, ReproductionResult
from microfab.experiments.seed002_stage.keys import (
    A_MAX,
    ANN_EPOCH_WINDOWS,
    ANN_MAX_EPOCHS,
    ANN_SEED,
    ANN_THREADS,
    ANN_VALIDATION,
    ANN_WHITEN,
    ANN_WORKERS,
    DECIMATE,
    EPOCH_WINDOWS,
    HOLD_S,
    MAX_EPOCHS,
    ORDER,
    RUNS_SEED,
    RUNS_TOTAL_S,
    TWIN_SEED,
    check_whiten_key,
)
from microfab.experiments.seed002_stage.study import (
    MODEL_FOLDERS,
    SWEEP_A_MAX,
    TABLE_A_MAX,
    CaseSettings,
    IdentifyStudy,
    StudySettings,
    run_study,
)
from microfab.experiments.seed002_stage.tables import comparison_tables
from microfab.io.atomic import atomic_write_json
from microfab.io.job import Key
from microfab.machines.xy_stage import cases as xy_stage_cases
from microfab.machines.xy_stage import machine as xy_stage
from microfab.machines.xy_stage.ann import AnnSettings
from microfab.machines.xy_stage.identify import LinearSettings
from microfab.machines.xy_stage.machine import TwinSettings
from microfab.report.tables import Table

__all__ = [
    "SCHEMA",
    "STAGE_IDENTIFY",
    "STAGE_MODELS_REPRODUCTION",
    "IdentifyResult",
    "config_from_sections",
    "reproduction_settings",
]

_F = "float"
#: Validation windows of the stopping loss: assumed, so that both networks train within
#: the 15 min of issue 17 on one CPU thread (`microfab.identify.ann.AnnConfig`); the
#: training windows per epoch (``EPOCH_WINDOWS``) and the most epochs (``MAX_EPOCHS``,
#: issue 34's schedule) are in `microfab.experiments.seed002_stage.keys`, which the CLI
#: shares.
VAL_WINDOWS = 131_072
#: The learning rate falls 5 % an epoch to 1/20 of Adam's 1e-3 by the last of
#: ``MAX_EPOCHS`` (0.95^60 = 0.046). Assumed, from the measurement in
#: ``benchmarks/bench_ann.py`` (issue 34's note).
LR_DECAY = 0.95
#: The networks' inputs: the seed's 200 (`microfab.identify.ann_data`). The position
#: features learn the twin's cogging on the validation runs (σ x / y 19.4 / 37.7 ->
#: 13.9 / 24.8 µm) but generalise worse to the letters (21.6 / 41.4 -> 27.3 / 61.3 µm at
#: 1 m/s², issue 34's note), the cases the optimisation is for: an option, not the default.
FEATURES = "none"

MAGNITUDES = ("calibrated", "assumed")

SCHEMA: dict[str, tuple[Key, ...]] = {
    "twin": (
        TWIN_SEED,
        Key(name="noise", type="bool", default=True, help="2 µm output noise (seed eq. 3)"),
        HOLD_S,
        Key(name="magnitudes", type="str", default="calibrated", choices=MAGNITUDES,
            help="the twin's disturbance magnitudes: 'calibrated' (the twin file's, fitted "
            "to Table II by `microfab calibrate xy-stage`) or 'assumed' (every magnitude as "
            "assumed before calibration)"),
    ),
    "linear": (
        RUNS_TOTAL_S,
        A_MAX,
        ORDER,
        DECIMATE,
        Key(name="feedthrough", type="bool", default=True, help="estimate D (eq. 6b)"),
        Key(name="orders", type="int_list", default=(2, 3, 4, 5, 6, 7, 8), low=1, high=30,
            allow_empty=True, help="order check (seed §III-A); [] for none"),
        RUNS_SEED,
    ),
    "ann": (
        Key(name="enabled", type="bool", default=True, help="train the per-axis networks"),
        Key(name="total_s", type=_F, default=525.0, low=1.0, high=6000.0, unit="s",
            help="data (about 34 training windows per weight, seed §III-C)"),
        Key(name="random_share", type=_F, default=0.6, low=0.0, high=1.0,
            help="share of random runs (seed: about 60 %)"),
        ANN_VALIDATION,
        ANN_MAX_EPOCHS,
        Key(name="lr_decay", type=_F, default=LR_DECAY, low=0.5, high=1.0,
            help="learning-rate factor per epoch (Adam from 1e-3)"),
        Key(name="features", type="str", default=FEATURES, choices=("none", "position"),
            help="'position': sin/cos of recent absolute positions as inputs too (learns "
                 "cogging); 'none': the seed's 200 inputs"),
        ANN_EPOCH_WINDOWS,
        Key(name="val_windows", type="int", default=VAL_WINDOWS, low=0,
            help="validation windows of the stopping loss (0: all)"),
        ANN_THREADS,
        ANN_WORKERS,
        ANN_SEED,
        ANN_WHITEN,
    ),
    "cases": (
        Key(name="table_a_max", type="float_list", default=TABLE_A_MAX, low=0.0, high=40.0,
            unit="m/s²", help="Table II's letters columns (seed Fig. 8: 1 and 3)"),
        Key(name="sweep_a_max", type="float_list", default=SWEEP_A_MAX, low=0.0, high=40.0,
            unit="m/s²", help="Fig. 9's points"),
        Key(name="r_time_s", type=_F, default=0.807, low=0.0, unit="s",
            help="letter height set so 'r' takes this at 1 m/s² (seed Table III)"),
        Key(name="airfoil_time_s", type=_F, default=1.322, low=0.0, unit="s",
            help="chord set so the airfoil takes this at 1 m/s² (seed Table III)"),
    ),
    "studies": (
        Key(name="coupling", type="bool", default=True,
            help="networks fed both axes' commands (seed §III-B)"),
        Key(name="classic", type="bool", default=True,
            help="networks trained on PRBS and chirp runs (seed §III-C)"),
    ),
}  # fmt: skip


def _magnitudes(tw: dict[str, Any]) -> tuple[tuple[str, Any], ...]:
    """Twin changes of the ``magnitudes`` choice (``"assumed"``: every magnitude as assumed)."""
    from microfab.machines.xy_stage.calibration import assumed_changes

    if tw["magnitudes"] not in MAGNITUDES:
        raise ValueError(
            f"[twin] magnitudes must be one of {', '.join(MAGNITUDES)}, got {tw['magnitudes']!r}"
        )
    return () if tw["magnitudes"] == "calibrated" else assumed_changes()


def config_from_sections(sec: dict[str, dict[str, Any]]) -> StudySettings:
    """`StudySettings` from checked job-file sections (`SCHEMA`).

    Raises
    ------
    ValueError
        Studies without the networks, unknown magnitudes, a non-positive a_max or sizing
        time.
    """
    tw, li, an, ca, st = (sec[k] for k in ("twin", "linear", "ann", "cases", "studies"))
    twin = TwinSettings(
        seed=tw["seed"], noise=tw["noise"], hold_s=tw["hold_s"], changes=_magnitudes(tw)
    )
    linear = LinearSettings(
        total_s=li["total_s"],
        a_max=li["a_max"],
        order=li["order"],
        decimate=li["decimate"],
        feedthrough=li["feedthrough"],
        seed=li["seed"],
        twin=twin,
    )
    ann = None
    if an["enabled"]:
        ann = AnnSettings(
            total_s=an["total_s"],
            random_share=an["random_share"],
            validation=an["validation"],
            max_epochs=an["max_epochs"],
            lr_decay=an["lr_decay"],
            features=an["features"],
            epoch_windows=an["epoch_windows"] or None,
            val_windows=an["val_windows"] or None,
            threads=an["threads"],
            workers=an["workers"],
            seed=an["seed"],
            whiten=check_whiten_key(an["whiten"], "[ann] whiten"),
            twin=twin,
        )
    elif st["coupling"] or st["classic"]:
        raise ValueError(
            "[studies] coupling and classic need the networks: set [ann] enabled = true, or "
            "[studies] coupling = false and classic = false"
        )
    if not ca["table_a_max"]:
        raise ValueError("[cases] table_a_max needs at least one acceleration")
    cases = CaseSettings(
        table_a_max=tuple(ca["table_a_max"]),
        sweep_a_max=tuple(ca["sweep_a_max"]),
        r_time_s=ca["r_time_s"],
        airfoil_time_s=ca["airfoil_time_s"],
    )
    return StudySettings(
        twin=twin,
        linear=linear,
        orders=tuple(li["orders"]),
        ann=ann,
        cases=cases,
        coupling=st["coupling"],
        classic=st["classic"],
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class IdentifyResult:
    """A finished ``stage-identify`` job."""

    study: IdentifyStudy

    def comparison(self) -> tuple[Table, ...]:
        """Table II, the order check, the cases' lengths, Fig. 9, the studies."""
        return comparison_tables(self.study)

    def failures(self) -> tuple[str, ...]:
        """Nothing is kept going past a failure here: a failed part raises."""
        return ()

    def summary(self) -> dict[str, Any]:
        """The numbers of the tables, JSON-ready."""
        from microfab.experiments.seed002_stage.tables import study_summary

        return study_summary(self.study)


def _run(config: StudySettings, out: Path, progress: Progress) -> IdentifyResult:
    from microfab.identify.stage_ann import save_ann_model
    from microfab.identify.stage_data import write_stage_model

    study = run_study(config, out, progress)
    write_stage_model(out / "linear_model.json", study.linear.stage_model())
    for name, folder in MODEL_FOLDERS.items():
        st = getattr(study, name)
        if st is not None:
            save_ann_model(st.model, out / folder / "model")
    result = IdentifyResult(study=study)
    atomic_write_json(out / "summary.json", result.summary())
    return result


def _write_report(result: IdentifyResult, out: Path, title: str) -> Path:
    from microfab.experiments.seed002_stage.report import write_report

    return write_report(result.study, out, title)


def reproduction_settings(options: dict[str, Any]) -> StudySettings:
    """The study ``microfab reproduce stage-models`` runs: the seed's design, job defaults."""
    twin = TwinSettings(seed=options["seed"], noise=options["noise"], changes=_magnitudes(options))
    ann = AnnSettings(max_epochs=MAX_EPOCHS, lr_decay=LR_DECAY, features=FEATURES,
                      epoch_windows=EPOCH_WINDOWS, val_windows=VAL_WINDOWS, workers=2,
                      twin=twin)  # fmt: skip
    studies = options["networks"] and options["studies"]
    return StudySettings(
        twin=twin,
        linear=LinearSettings(twin=twin),
        ann=ann if options["networks"] else None,
        coupling=studies,
        classic=studies,
    )


def _reproduce(options: dict[str, Any], progress: Progress) -> ReproductionResult:
    from microfab.experiments.seed002_stage.tables import NOTES, study_summary

    folder = options["checkpoints"]
    study = run_study(reproduction_settings(options), Path(folder) if folder else None, progress)
    return ReproductionResult(
        tables=comparison_tables(study), notes=NOTES, data=study_summary(study)
    )


STAGE_IDENTIFY = JobKind(
    name="stage-identify",
    schema=SCHEMA,
    make_config=config_from_sections,
    run=_run,
    write_report=_write_report,
    default_title="Black-box XY stage: linear and neural-network models",
    data_files=xy_stage.DATA_FILES + xy_stage_cases.DATA_FILES,
)

STAGE_MODELS_REPRODUCTION = Reproduction(
    name="stage-models",
    run=_reproduce,
    options=(
        Key(name="seed", type="int", default=0, low=0, help="noise seed"),
        Key(name="noise", type="bool", default=True, help="2 µm output noise on"),
        Key(name="magnitudes", type="str", default="calibrated", choices=MAGNITUDES,
            help="twin friction and cogging: 'calibrated' or 'assumed'"),
        Key(name="networks", type="bool", default=True,
            help="train the networks (about 10 min per training on one CPU thread)"),
        Key(name="studies", type="bool", default=True,
            help="also the coupling and PRBS/chirp networks (two more trainings)"),
        Key(name="checkpoints", type="str", default="",
            help="folder for training checkpoints, so a rerun resumes (default: none)"),
    ),
    data_files=xy_stage.DATA_FILES + xy_stage_cases.DATA_FILES,
    run_folder_option="checkpoints",
)  # fmt: skip
