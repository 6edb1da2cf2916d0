"""The per-axis networks of seed 002 (eq. 7) on measured stage runs: train, save, validate.

What ``microfab identify ann`` and ``identify validate`` (`cli/identify_ann.py`,
`cli/identify.py`) do with the networks, as a library, on `StageRecord` runs
(`microfab.identify.stage_runs`):

* `split_records`: the seed's 80/20 split by whole runs (§III-C), seeded; one run, or a
  share that leaves either side empty, is refused.
* `ann_config`: the `AnnConfig` for runs at a given rate (the window's run rate is the
  runs' own; 400 Hz and h = 200 as the seed).
* `train_stage_ann`: the networks trained on training runs (resumable checkpoints,
  `microfab.identify.ann_train.train_ann`) and scored on the validation runs, as a
  `StageAnnFit`; what ``microfab identify ann`` runs on measured files and the
  ``stage-identify`` job on the twin's runs (`microfab.machines.xy_stage.ann`).
* `StageAnnModel`: an `AnnModel` as a stage model for ``identify validate`` (``kind``,
  ``input_rate_hz``, ``errors(records) -> RunErrors``); the errors are ``y - y_model``
  (the sign of the linear model's `run_errors`) at every run sample (10 kHz for the
  seed's runs), each 400 Hz start offset predicted and interleaved
  (`AnnModel.predict` ``at="10khz"``).
* `read_ann_stage_model`: `AnnModel.load` of a model directory, refusing another format
  version, model rate (400 Hz) or history (h = 200), and unreadable files, as ValueError
  naming the directory; registered in `stage_data.MODEL_KINDS` as kind ``"ann"``.
* `save_ann_model`: `AnnModel.save` made safe against an interruption: the files are
  written to a temporary directory beside the model first, the old ``model.json`` (the
  marker `AnnModel.load` reads first) is removed, ``weights.npz`` moved in, then
  ``model.json``: a reader finds the old model, no model, or the new one, never a mix.

PyTorch is imported through `microfab.identify.ann` (extra ``ann``): `stage_data` imports
this module only when an ANN model is read.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from microfab.core.validate import check_int
from microfab.identify.ann import AnnConfig, AnnModel, ErrorStats
from microfab.identify.ann_data import HISTORY, MODEL_RATE_HZ, WindowSpec
from microfab.identify.ann_train import EpochRecord, train_ann
from microfab.identify.stage_runs import AXES, RunErrors, StageRecord

__all__ = [
    "StageAnnFit",
    "StageAnnModel",
    "ann_config",
    "read_ann_stage_model",
    "save_ann_model",
    "split_records",
    "train_stage_ann",
]

_WEIGHTS, _META = "weights.npz", "model.json"  # what `AnnModel.save` writes


def split_records(
    records: Sequence[StageRecord], validation: float, seed: int
) -> tuple[list[StageRecord], list[StageRecord]]:
    """Split runs into training and validation by whole runs (seed 002 §III-C: 80/20).

    Parameters
    ----------
    records : sequence of StageRecord
        At least two runs.
    validation : float
        Share of the runs for validation, in (0, 1); ``round(validation n)`` runs, at
        least one, and at least one left for training.
    seed : int
        Seeds the permutation (``numpy.random.default_rng(seed)``).

    Returns
    -------
    (list of StageRecord, list of StageRecord)
        Training and validation runs, each in the order given.

    Raises
    ------
    ValueError
        Fewer than two runs, or a share outside (0, 1).
    """
    n = len(records)
    if not 0.0 < validation < 1.0:
        raise ValueError(f"validation must lie in (0, 1) (a share of the runs), got {validation}")
    check_int("seed", seed, 0)
    if n < 2:
        raise ValueError(
            f"{n} run given: the networks are validated on whole runs that they were not "
            "trained on (seed 002 §III-C: 80/20 by run); give at least two runs, e.g. cut "
            "a long recording into several files, each from rest"
        )
    n_val = min(max(1, round(validation * n)), n - 1)
    chosen = set(np.random.default_rng(seed).permutation(n)[:n_val].tolist())
    train = [r for i, r in enumerate(records) if i not in chosen]
    val = [r for i, r in enumerate(records) if i in chosen]
    return train, val


def ann_config(
    run_rate_hz: float,
    axes: Sequence[str],
    *,
    inputs: str = "own",
    features: str = "none",
    **kwargs: Any,
) -> AnnConfig:
    """`AnnConfig` for runs at ``run_rate_hz``: 400 Hz, h = 200 (seed 002 §III-B).

    ``inputs`` is "own" (the seed's: each network reads its own axis's command) or
    "both" (the coupling study); ``features`` "none" (the seed's 200 inputs) or
    "position" (`microfab.identify.ann_data`); ``kwargs`` go to `AnnConfig`
    (``max_epochs``, ``seed``, ``device``, ``threads``, ...).
    """
    spec = WindowSpec(run_rate_hz=run_rate_hz, rate_hz=MODEL_RATE_HZ, h=HISTORY,
                      inputs=inputs, features=features)  # fmt: skip
    return AnnConfig(window=spec, axes=tuple(axes), **kwargs)


def runs_of(records: Sequence[StageRecord]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(command, measured)`` pairs of `train_ann` from stage records."""
    return [(r.u, r.y) for r in records]


@dataclass(frozen=True, eq=False)
class StageAnnModel:
    """An `AnnModel` read as a stage model (what ``identify validate`` needs).

    Attributes
    ----------
    model : AnnModel
        The networks, one per modelled axis.
    path : str
        Where it was read from (messages), or ``""``.
    """

    model: AnnModel
    path: str = ""
    kind: ClassVar[str] = "ann"

    @property
    def input_rate_hz(self) -> float:
        """Rate of the runs the networks read, Hz (the window's run rate)."""
        return self.model.spec.run_rate_hz

    @property
    def axes(self) -> tuple[str, ...]:
        """Modelled axes."""
        return self.model.axes

    def errors(self, records: Any, *, keep: bool = False) -> RunErrors:
        """``y - y_model`` per modelled axis at every run sample, each run from rest.

        Parameters
        ----------
        records : sequence of StageRecord
            At `input_rate_hz`.
        keep : bool
            Keep every error sample (`RunErrors.samples`).

        Returns
        -------
        RunErrors
            ``axes`` the modelled ones; ``rate_hz`` the runs' rate.
        """
        recs = [records] if isinstance(records, StageRecord) else list(records)
        if not recs:
            raise ValueError("no runs given: at least one measured run is needed")
        cols = [AXES.index(a) for a in self.axes]

        def error(rec: StageRecord) -> np.ndarray:
            e = rec.y[:, cols] - self.model.predict(rec.u, at="10khz")
            return e[np.all(np.isfinite(e), axis=1)]  # an unpadded model's first h samples

        return RunErrors.of(
            ((r.name, error(r)) for r in recs), self.input_rate_hz, self.axes, keep=keep
        )


@dataclass(frozen=True, eq=False)
class StageAnnFit:
    """Networks trained on stage runs and their errors on the validation runs.

    Attributes
    ----------
    model : AnnModel
        One network per modelled axis.
    errors : RunErrors
        ``y - y_model`` on the validation runs at every run sample (`StageAnnModel.errors`;
        every sample kept when asked: histograms, seed 002 Fig. 8a).
    train_names, validation_names : tuple of str
        Which runs went where.
    """

    model: AnnModel
    errors: RunErrors
    train_names: tuple[str, ...]
    validation_names: tuple[str, ...]

    @property
    def validation(self) -> dict[str, ErrorStats]:
        """μ, σ (m) and samples per axis on the validation runs (Table II, ANN, column 1)."""
        e = self.errors
        return {
            a: ErrorStats(float(e.mean[j]), float(e.std[j]), e.n_samples)
            for j, a in enumerate(e.axes)
        }


def train_stage_ann(
    train: Sequence[StageRecord],
    val: Sequence[StageRecord],
    config: AnnConfig,
    *,
    checkpoint_dir: str | os.PathLike[str] | None = None,
    progress: Callable[[EpochRecord], None] | None = None,
    restart: bool = False,
    keep: bool = False,
    init: AnnModel | None = None,
) -> StageAnnFit:
    """Train the networks on ``train``, stopped early and scored on ``val``.

    Parameters
    ----------
    train, val : sequence of StageRecord
        Training and validation runs (`split_records`), at ``config``'s run rate.
    config : AnnConfig
        `ann_config`'s.
    checkpoint_dir : path, optional
        Checkpoints of `microfab.identify.ann_train.train_ann`: a rerun resumes there.
    progress : callable, optional
        Called after each epoch with an `microfab.identify.ann_train.EpochRecord`.
    restart : bool
        Discard the checkpoints and start afresh.
    keep : bool
        Keep every validation error sample (`RunErrors.samples`).
    init : AnnModel, optional
        Warm start from these networks, keeping their scaling
        (`microfab.identify.ann_train.train_ann`: the seed's next generation, §III-C.2).

    Raises
    ------
    ValueError
        From the training (too little data) or the scoring.
    microfab.identify.ann_train.CheckpointMismatchError
        A checkpoint of another configuration or data set (and not ``restart``).
    """
    model = train_ann(
        runs_of(train), runs_of(val), config, checkpoint_dir=checkpoint_dir,
        progress=progress, restart=restart, init=init,
    )  # fmt: skip
    return StageAnnFit(
        model=model,
        errors=StageAnnModel(model).errors(val, keep=keep),
        train_names=tuple(r.name for r in train),
        validation_names=tuple(r.name for r in val),
    )


def read_ann_stage_model(path: str | os.PathLike[str]) -> StageAnnModel:
    """`AnnModel.load` of a model directory as a `StageAnnModel`.

    Raises
    ------
    ValueError
        No model there, unreadable or inconsistent files, another format version, a
        model rate other than 400 Hz or a history other than 200 (seed 002 §III-B); the
        message names the directory.
    """
    d = Path(path)
    if not (d / _META).is_file():
        raise ValueError(
            f"{d}: no {_META}: not a network model of `identify ann` (an interrupted training "
            "leaves only checkpoints/: run the same command again to finish it)"
        )
    try:
        model = AnnModel.load(d, rate_hz=MODEL_RATE_HZ, h=HISTORY)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if str(d) in msg else f"{d}: {msg}") from None
    except (OSError, KeyError, TypeError, RuntimeError, json.JSONDecodeError) as exc:
        raise ValueError(
            f"{d}: cannot read the network model: {type(exc).__name__}: {exc}"
        ) from None
    return StageAnnModel(model=model, path=str(d))


def save_ann_model(model: AnnModel, directory: str | os.PathLike[str]) -> Path:
    """`AnnModel.save` into ``directory``, never leaving a mixed model (module docstring).

    Returns the directory.
    """
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".model-", dir=d))
    try:
        model.save(tmp)
        (d / _META).unlink(missing_ok=True)
        os.replace(tmp / _WEIGHTS, d / _WEIGHTS)
        os.replace(tmp / _META, d / _META)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return d
