"""Seed 002 part 1 on the XY stage twin: excite, record, fit the linear model, evaluate.

The twin (`microfab.plants.xy_stage`) stands in for the ETEL stage: a command record at
10 kHz (`microfab.identify.excitation.ExcitationRun`) is played from rest at its first
sample through the compiled loop (`microfab.sim.loop.simulate` with
`microfab.control.setpoint.SetPoint`: the black box's input is the set-point ρ), then held
for ``hold_s`` so that the stage settles; the measured position gets the twin's 2 µm
noise (seed 002 eq. 3) drawn from a seed per run. What comes back is a `StageRecord` per
run, the same shape as a measured run read from a file.

The linear model (eq. 6) is fitted by `microfab.identify.stage_data.fit_linear`, the same
function ``microfab identify linear`` runs on measured files:

* **Decimation.** At 10 kHz the slowest modes (≈20 ms, §III-B) sit at ``z ≈ 0.995`` and a
  four-state subspace fit is ill-conditioned on this data (its ``A`` came out unstable).
  Input and output are both decimated by ``decimate`` (default 10, to 1 kHz) with the
  same zero-phase FIR anti-alias filter (`scipy.signal.decimate`, ``ftype="fir"``); the
  same linear filter on both sides keeps the input-output relation of an LTI model.
* **Feedthrough.** Eq. (6b) writes ``γ = C z + D ρ``. On the twin, whose built-in loop
  tracks within microns, ``D = 0`` (MATLAB ``n4sid``'s default) gave σ ≈ 210 µm per axis
  at order 4, while ``D`` free gives σ near the nonlinear floor; so ``D`` is estimated.

Prediction errors are the measured output minus the model's, on the decimated records,
each run simulated from the model's rest state under its first input
(`stage_data.run_errors`); μ and σ are their mean and standard deviation per axis
(Table II).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from microfab.identify import stage_data
from microfab.identify.excitation import ann_dataset, random_runs, split_runs
from microfab.identify.subspace import SubspaceModel
from microfab.machines.xy_stage import CommandRun, Played, TwinSettings, play_runs

if TYPE_CHECKING:
    from microfab.identify.ann import AnnModel, ErrorStats

__all__ = [
    "AnnSettings",
    "AnnStudy",
    "LinearFit",
    "LinearSettings",
    "ann_records",
    "ann_study",
    "fit_linear",
    "linear_study",
    "play_split",
    "train_networks",
]


@dataclass(frozen=True, kw_only=True)
class LinearSettings:
    """The linear model's data and fit (seed 002 §III-A, §III-C.1).

    Parameters
    ----------
    total_s : float
        Random-run data, s (seed §III-C.1: 6×10⁶ samples, 600 s at 10 kHz).
    a_max : float
        Largest acceleration of the runs, m/s² (seed §III-D: up to 5).
    order : int
        States (seed §III-A: 4).
    decimate : int
        Decimation before the fit (module doc; 10: to 1 kHz).
    feedthrough : bool
        Estimate ``D`` (module doc).
    block_rows : int, optional
        Hankel block rows (default `SubspaceConfig`'s).
    seed : int
        Seed of the random runs.
    """

    total_s: float = 600.0  # seed 002 §III-C.1
    a_max: float = 5.0  # seed 002 §III-D
    order: int = 4  # seed 002 §III-A
    decimate: int = 10  # assumed, module doc
    feedthrough: bool = True  # module doc
    block_rows: int | None = None
    seed: int = 0
    twin: TwinSettings = field(default_factory=TwinSettings)

    def __post_init__(self) -> None:
        if not self.total_s > 0:
            raise ValueError(f"total_s must be positive, got {self.total_s!r} s")
        if not isinstance(self.decimate, int) or self.decimate < 1:
            raise ValueError(f"decimate must be an integer >= 1, got {self.decimate!r}")


@dataclass(frozen=True, eq=False)
class LinearFit:
    """The linear model and its errors on its own training data.

    Attributes
    ----------
    model : SubspaceModel
        At the decimated rate.
    mu_m, sigma_m : numpy.ndarray
        Mean and standard deviation of the prediction error per axis (x, y), m.
    n_samples : int
        Samples of training data at 10 kHz.
    decimate : int
        Decimation factor used.
    """

    model: SubspaceModel
    mu_m: np.ndarray
    sigma_m: np.ndarray
    n_samples: int
    decimate: int


def fit_linear(played: Played, settings: LinearSettings | None = None) -> LinearFit:
    """Fit eq. (6) to the played runs and measure it on them (module doc).

    Raises
    ------
    ValueError
        From the subspace fit: too little excitation, an order above the block rows, an
        unstable ``A``.
    """
    s = LinearSettings() if settings is None else settings
    model = stage_data.fit_linear(
        played.records,
        played.dt,
        order=s.order,
        decimate=s.decimate,
        feedthrough=s.feedthrough,
        block_rows=s.block_rows,
    )
    err = stage_data.run_errors(model, played.records, s.decimate)
    return LinearFit(
        model=model,
        mu_m=err.mean,
        sigma_m=err.std,
        n_samples=int(sum(r.n_samples for r in played.records)),
        decimate=s.decimate,
    )


def linear_study(settings: LinearSettings | None = None) -> tuple[Played, LinearFit]:
    """Random runs (§III-C.1), played on the twin, and the linear model fitted to them."""
    s = LinearSettings() if settings is None else settings
    runs = random_runs(s.total_s, a_max=s.a_max, seed=s.seed)
    played = play_runs(runs, s.twin)
    return played, fit_linear(played, s)


# ---------------------------------------------------------------------------- ANN
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
