"""The per-axis networks of seed 002 (eq. 7) on the XY stage twin: data played, trained, scored.

What the ``stage-identify`` job (and ``microfab reproduce stage-models``) runs for the
networks; the training itself is `microfab.identify.stage_ann.train_stage_ann`, the
function ``microfab identify ann`` runs on measured files:

* `ann_records`: the networks' data (§III-C.2: about 60 % random runs, the rest regular
  shapes at constant speeds, `microfab.identify.excitation.ann_dataset`) split 80/20 by
  whole runs (`microfab.identify.excitation.split_runs`) and played on the twin
  (`microfab.machines.xy_stage.play_runs`, `play_split`);
* `classic_records`: the same for the PRBS and chirp runs of the same total length
  (`microfab.identify.excitation_signals.classic_runs`, §III-C's classic signals);
* `train_networks`: one network per axis trained on the training runs, stopped early and
  scored on the validation runs (Table II column 1 of the non-linear model); ``inputs``
  "both" feeds both axes' commands to each network (the coupling study of §III-B).

The validation runs are played with noise seeds 10 000 above the training runs'.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from microfab.identify import stage_data
from microfab.identify.excitation import ANN_TOTAL_S, ann_dataset, split_runs
from microfab.identify.excitation_signals import classic_runs
from microfab.machines.xy_stage.machine import CommandRun, Played, TwinSettings, play_runs

if TYPE_CHECKING:
    from microfab.identify.ann_train import EpochRecord
    from microfab.identify.stage_ann import StageAnnFit

__all__ = [
    "VALIDATION_SEED_OFFSET",
    "AnnSettings",
    "ann_records",
    "ann_study",
    "classic_records",
    "play_split",
    "train_networks",
]

#: Noise seeds of the validation runs sit this far above the training runs' (assumed).
VALIDATION_SEED_OFFSET = 10_000


@dataclass(frozen=True, kw_only=True)
class AnnSettings:
    """The per-axis networks' data and training (seed 002 §III-B, §III-C.2).

    Parameters
    ----------
    total_s : float or None
        Data, s (None: `microfab.identify.excitation.ANN_TOTAL_S`, about 34 training
        windows per weight, seed §III-C).
    random_share : float
        Share of random runs; the rest are shapes at constant speeds (seed: about 60 %).
    validation : float
        Share of whole runs kept for validation (seed: 20 %).
    max_epochs : int
        Most epochs per axis (early stopping on the validation loss decides first).
    lr_decay : float
        Learning-rate factor per epoch (`microfab.identify.ann.AnnConfig`).
    features : {"none", "position"}
        The seed's inputs, or also the position features (`microfab.identify.ann_data`).
    epoch_windows, val_windows : int or None
        Training windows per epoch and validation windows of the stopping loss
        (`microfab.identify.ann.AnnConfig`; None: all).
    threads : int
        CPU threads of the training (per worker).
    workers : int
        Axes trained at once, each in its own process (`microfab.identify.ann.AnnConfig`).
    seed : int
        Seed of the runs, the split and the training.
    whiten : float or None
        Shrinkage of the whitened inputs (`microfab.identify.ann.AnnConfig.whiten`; None:
        not whitened).
    twin : TwinSettings
        The twin the runs are played on.
    """

    total_s: float | None = None
    random_share: float = 0.6  # seed 002 §III-C: "about 60 %"
    validation: float = 0.2  # seed 002 §III-C: 80 % / 20 %
    max_epochs: int = 200
    lr_decay: float = 0.97  # AnnConfig's default before issue 34; the job sets its own
    features: str = "none"  # the seed's 200 inputs; the job sets its own
    epoch_windows: int | None = None
    val_windows: int | None = None
    threads: int = 1
    workers: int = 1
    seed: int = 0
    whiten: float | None = 1e-3  # AnnConfig's default (microfab.identify.ann)
    twin: TwinSettings = field(default_factory=TwinSettings)

    @property
    def data_s(self) -> float:
        """The data's total length, s (`total_s`, or the default)."""
        return ANN_TOTAL_S if self.total_s is None else self.total_s


def play_split(
    train: Sequence[CommandRun], val: Sequence[CommandRun], twin: TwinSettings
) -> tuple[Played, Played]:
    """`play_runs` of a train/validation split (validation noise seeds 10 000 higher)."""
    val_twin = dataclasses.replace(twin, seed=twin.seed + VALIDATION_SEED_OFFSET)
    return play_runs(train, twin), play_runs(val, val_twin)


def ann_records(settings: AnnSettings | None = None) -> tuple[Played, Played]:
    """The networks' data (§III-C.2) split by whole runs and played: ``(train, validation)``."""
    s = AnnSettings() if settings is None else settings
    runs = ann_dataset(s.data_s, random_share=s.random_share, seed=s.seed)
    return play_split(*split_runs(runs, s.validation, seed=s.seed), s.twin)


def classic_records(settings: AnnSettings | None = None) -> tuple[Played, Played]:
    """PRBS and chirp runs of the same total length, split and played like `ann_records`."""
    s = AnnSettings() if settings is None else settings
    runs = classic_runs(s.data_s, s.seed)
    return play_split(*split_runs(runs, s.validation, seed=s.seed), s.twin)


def train_networks(
    train: Played,
    val: Played,
    settings: AnnSettings | None = None,
    *,
    inputs: str = "own",
    checkpoint_dir: str | Path | None = None,
    progress: Callable[[EpochRecord], None] | None = None,
) -> StageAnnFit:
    """One network per axis trained on ``train``, stopped and scored on ``val``.

    Parameters
    ----------
    train, val : Played
        Runs played on the twin (`ann_records`), 10 kHz.
    settings : AnnSettings, optional
        Epochs, windows, threads, workers, seed.
    inputs : {"own", "both"}
        "own" is the seed's (each axis's own command); "both" feeds both axes' commands
        to each network (the coupling study).
    checkpoint_dir : path, optional
        Makes the training resumable (`microfab.identify.ann_train.train_ann`).
    progress : callable, optional
        Called after each epoch with an `microfab.identify.ann_train.EpochRecord`.

    Returns
    -------
    StageAnnFit
        The networks and their validation errors, every sample kept (Fig. 8a).
    """
    from microfab.identify.stage_ann import ann_config, train_stage_ann

    s = AnnSettings() if settings is None else settings
    config = ann_config(
        1.0 / train.dt,
        stage_data.AXES,
        inputs=inputs,
        features=s.features,
        max_epochs=s.max_epochs,
        lr_decay=s.lr_decay,
        epoch_windows=s.epoch_windows,
        val_windows=s.val_windows,
        seed=s.seed,
        threads=s.threads,
        workers=s.workers,
        whiten=s.whiten,
    )
    return train_stage_ann(
        train.records, val.records, config, checkpoint_dir=checkpoint_dir, progress=progress,
        keep=True,
    )  # fmt: skip


def ann_study(
    settings: AnnSettings | None = None,
    *,
    checkpoint_dir: str | Path | None = None,
    progress: Callable[[EpochRecord], None] | None = None,
) -> StageAnnFit:
    """`ann_records`, then `train_networks` on them (the seed's per-axis networks)."""
    train, val = ann_records(settings)
    return train_networks(train, val, settings, checkpoint_dir=checkpoint_dir, progress=progress)
