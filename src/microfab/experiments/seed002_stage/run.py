"""Seed 002 part 1's networks on the XY stage twin: their data played, trained, scored.

The networks' data (§III-C.2: about 60 % random runs, the rest regular shapes at constant
speeds, `microfab.identify.excitation.ann_dataset`) is split 80/20 by whole runs and
played on the twin (`microfab.machines.xy_stage.play_runs`); one network per axis is
trained (`microfab.identify.ann_train.train_ann`) and scored on the validation runs
(Table II column 1 of the non-linear model). The linear model's runs and fit are the
machine's (`microfab.machines.xy_stage_identify`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microfab.identify import stage_data
from microfab.identify.excitation import ann_dataset, split_runs
from microfab.machines.xy_stage import CommandRun, Played, TwinSettings, play_runs

if TYPE_CHECKING:
    from microfab.identify.ann import AnnModel, ErrorStats

__all__ = [
    "AnnSettings",
    "AnnStudy",
    "ann_records",
    "ann_study",
    "play_split",
    "train_networks",
]


@dataclass(frozen=True, kw_only=True)
class AnnSettings:
    """The per-axis networks' data and training (seed 002 §III-B, §III-C.2).

    Parameters
    ----------
    total_s : float
        Data, s (default `microfab.identify.excitation.ANN_TOTAL_S`: about 34 training
        windows per weight, seed §III-C).
    random_share : float
        Share of random runs; the rest are shapes at constant speeds (seed: about 60 %).
    validation : float
        Share of whole runs kept for validation (seed: 20 %).
    max_epochs : int
        Most epochs per axis (early stopping on the validation loss decides first).
    epoch_windows, val_windows : int or None
        Training windows per epoch and validation windows of the stopping loss
        (`microfab.identify.ann.AnnConfig`; None: all).
    threads : int
        CPU threads of the training (per worker).
    workers : int
        Axes trained at once, each in its own process (`microfab.identify.ann.AnnConfig`).
    seed : int
        Seed of the runs, the split and the training.
    """

    total_s: float | None = None
    random_share: float = 0.6  # seed 002 §III-C: "about 60 %"
    validation: float = 0.2  # seed 002 §III-C: 80 % / 20 %
    max_epochs: int = 200
    epoch_windows: int | None = None
    val_windows: int | None = None
    threads: int = 1
    workers: int = 1
    seed: int = 0
    twin: TwinSettings = field(default_factory=TwinSettings)


@dataclass(frozen=True, eq=False)
class AnnStudy:
    """Trained networks and their error on the validation runs.

    Attributes
    ----------
    model : AnnModel
        One network per axis.
    validation : dict of str to ErrorStats
        μ, σ per axis on the validation runs (Table II, ANN, column 1), of the measured
        minus the predicted position, the sign of the linear model's errors
        (`microfab.identify.stage_ann.StageAnnModel.errors`).
    train_names, validation_names : tuple of str
        Which runs went where.
    errors : RunErrors or None
        The same errors with every sample kept (histograms, Fig. 8a).
    """

    model: AnnModel
    validation: dict[str, ErrorStats]
    train_names: tuple[str, ...]
    validation_names: tuple[str, ...]
    errors: stage_data.RunErrors | None = None


def ann_records(settings: AnnSettings | None = None) -> tuple[Played, Played]:
    """The networks' data (§III-C.2) split by whole runs and played on the twin.

    Returns ``(train, validation)``; the validation runs get noise seeds 10 000 above the
    training runs'.
    """
    from microfab.identify.excitation import ANN_TOTAL_S

    s = AnnSettings() if settings is None else settings
    total = ANN_TOTAL_S if s.total_s is None else s.total_s
    runs = ann_dataset(total, random_share=s.random_share, seed=s.seed)
    return play_split(*split_runs(runs, s.validation, seed=s.seed), s.twin)


def play_split(
    train: Sequence[CommandRun], val: Sequence[CommandRun], twin: TwinSettings
) -> tuple[Played, Played]:
    """`play_runs` of a train/validation split (validation noise seeds 10 000 higher)."""
    return play_runs(train, twin), play_runs(
        val, dataclasses.replace(twin, seed=twin.seed + 10_000)
    )


def train_networks(
    train: Played,
    val: Played,
    settings: AnnSettings | None = None,
    *,
    inputs: str = "own",
    checkpoint_dir: str | Path | None = None,
    progress: Any = None,
) -> AnnStudy:
    """One network per axis trained on ``train``, stopped and scored on ``val``.

    ``inputs`` "own" is the seed's (each axis's own command); "both" feeds both axes'
    commands to each network (the coupling study). ``checkpoint_dir`` makes the training
    resumable (`microfab.identify.ann_train.train_ann`); ``progress(record)`` is called
    after each epoch with an `microfab.identify.ann_train.EpochRecord`.
    """
    from microfab.identify.ann import ErrorStats
    from microfab.identify.ann_train import train_ann
    from microfab.identify.stage_ann import StageAnnModel, ann_config, runs_of

    s = AnnSettings() if settings is None else settings
    config = ann_config(
        1.0 / train.dt,
        stage_data.AXES,
        inputs=inputs,
        max_epochs=s.max_epochs,
        epoch_windows=s.epoch_windows,
        val_windows=s.val_windows,
        seed=s.seed,
        threads=s.threads,
        workers=s.workers,
    )
    model = train_ann(
        runs_of(train.records),
        runs_of(val.records),
        config,
        checkpoint_dir=checkpoint_dir,
        progress=progress,
    )
    err = StageAnnModel(model).errors(val.records, keep=True)
    return AnnStudy(
        model=model,
        validation={
            a: ErrorStats(float(err.mean[j]), float(err.std[j]), err.n_samples)
            for j, a in enumerate(err.axes)
        },
        train_names=tuple(r.name for r in train.records),
        validation_names=tuple(r.name for r in val.records),
        errors=err,
    )


def ann_study(
    settings: AnnSettings | None = None,
    *,
    checkpoint_dir: str | Path | None = None,
    progress: Any = None,
) -> AnnStudy:
    """`ann_records`, then `train_networks` on them (the seed's per-axis networks)."""
    train, val = ann_records(settings)
    return train_networks(train, val, settings, checkpoint_dir=checkpoint_dir, progress=progress)
