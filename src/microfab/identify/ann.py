"""Per-axis feed-forward neural networks of seed 002 (§III-B, eq. 7, Fig. 5): the model.

One network per axis predicts the measured position at a 400 Hz sample from the last
500 ms of that axis's command, ``φ_i = f_nlm(r_{i-h}, ..., r_{i-1})`` (eq. 7, h = 200).
Windows, encoding and scaling are `microfab.identify.ann_data` (read its docstring for
what ``φ_i`` is and how a run's start is handled); training is
`microfab.identify.ann_train` (`train_ann`, checkpoints), which imports this module and
not the other way round.

* Network (`build_network`, seed 002 Fig. 5): fully connected, hidden layers
  ``{200, 200, 100, 100, 50, 25, 12, 6}``, LeakyReLU of slope 0.01 after each, biases,
  one linear output: 117 322 weights for 200 inputs (`n_weights`).
* `AnnConfig`: the networks and their training (kept here because a saved model carries
  it and `AnnModel.load` rebuilds it).
* `AnnModel`: `AnnModel.predict` (400 Hz at one start offset, or every 10 kHz sample by
  interleaving all offsets), `AnnModel.metrics` (μ, σ per axis as seed 002 Table II,
  `ErrorStats`), `AnnModel.save` / `AnnModel.load` (``weights.npz`` + ``model.json``, no
  pickles; another format version, rate or history refused).
* The files' schema and readers (`MetaDoc`, `read_model_meta`, `read_weights`,
  `FORMAT_VERSION`) are in `microfab.identify.ann_files`, re-exported here.

PyTorch is imported here and in `microfab.identify.ann_train` only (extra ``ann``).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from microfab.core.validate import check_int, check_positive
from microfab.identify.ann_data import AXES, Run, Scaling, WindowSpec, check_run, windows
from microfab.identify.ann_files import _STRICT as _STRICT
from microfab.identify.ann_files import (
    FORMAT_VERSION,
    read_model_meta,
    read_weights,
)
from microfab.identify.ann_files import MAX_SCALING_M as MAX_SCALING_M
from microfab.identify.ann_files import MAX_WEIGHT as MAX_WEIGHT
from microfab.identify.ann_files import META_KIND as META_KIND
from microfab.identify.ann_files import ConfigDoc as ConfigDoc
from microfab.identify.ann_files import MetaDoc as MetaDoc
from microfab.identify.ann_files import ScalingDoc as ScalingDoc
from microfab.identify.ann_files import WindowDoc as WindowDoc
from microfab.io.atomic import atomic_save_npz, atomic_write_json
from microfab.io.schema import SchemaError

__all__ = [
    "FORMAT_VERSION",
    "HIDDEN",
    "NEGATIVE_SLOPE",
    "WHITEN_LOW",
    "AnnConfig",
    "AnnModel",
    "ErrorStats",
    "build_network",
    "check_whiten",
    "n_weights",
    "read_model_meta",
    "read_weights",
]

HIDDEN = (200, 200, 100, 100, 50, 25, 12, 6)  # seed 002 Fig. 5: hidden layer sizes
NEGATIVE_SLOPE = 0.01  # seed 002 §III-B: LeakyReLU slope 0.01
BATCH = 16_384  # seed 002 §III-C: "batches of 16k segments"
_EVAL_CHUNK = 65_536


def n_weights(n_inputs: int, hidden: Sequence[int] = HIDDEN) -> int:
    """Weights and biases of the network: 117 322 for 200 inputs (seed 002 Fig. 5)."""
    sizes = [n_inputs, *hidden, 1]
    return sum((a + 1) * b for a, b in itertools.pairwise(sizes))


def build_network(n_inputs: int, *, seed: int, hidden: Sequence[int] = HIDDEN) -> nn.Sequential:
    """The Fig. 5 network, float32, initialised by PyTorch's defaults under ``seed``.

    The global RNG is left as it was (``torch.random.fork_rng``).
    """
    sizes = [n_inputs, *hidden]
    layers: list[nn.Module] = []
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        for a, b in itertools.pairwise(sizes):
            layers += [nn.Linear(a, b), nn.LeakyReLU(NEGATIVE_SLOPE)]
        layers.append(nn.Linear(sizes[-1], 1))
        net = nn.Sequential(*layers)
    return net


#: Least shrinkage of the whitened inputs, relative to the mean eigenvalue (assumed): a
#: direction the data do not visit is amplified at most 1e3 times, so the whitening folded
#: into the float32 first layer (`microfab.identify.ann_whiten.fold`) keeps its weights
#: within about 1e3 of the network's; below it the amplification grows as ``ε^-1/2``
#: without bound (at 5e-324 the shrinkage is zero in float64 and the whitening divides by
#: the zero eigenvalues of the seed's collinear windows).
WHITEN_LOW = 1e-6


def check_whiten(whiten: float) -> float:
    """``whiten`` (`AnnConfig.whiten`) if it lies in [`WHITEN_LOW`, 1]; ValueError else."""
    w = check_positive("whiten", whiten, "of the mean eigenvalue")
    if not WHITEN_LOW <= w <= 1.0:
        raise ValueError(
            f"whiten must lie in [{WHITEN_LOW:g}, 1] of the mean eigenvalue (or be off), got {w:g}"
        )
    return w


@dataclass(frozen=True, kw_only=True)
class AnnConfig:
    """Networks and their training.

    Parameters
    ----------
    window : WindowSpec
        Rates, history, inputs, encoding, padding (`microfab.identify.ann_data`).
    axes : tuple of str
        Axes to model, from ("x", "y"); one network each.
    offsets : tuple of int, optional
        Subsampling offsets used for the windows (default all: ``0 .. factor-1``).
    batch_size : int
        Windows per Adam step (16 384, seed 002 §III-C).
    learning_rate : float
        Adam's initial learning rate (1e-3: Adam's default, assumed).
    lr_decay : float
        Learning rate factor per epoch, in (0, 1] (0.97, assumed: 1/20 after 100 epochs).
    patience : int
        Epochs without a better validation loss before stopping (assumed 10).
    max_epochs : int
        Most epochs per axis. Not part of the fingerprint: a rerun may extend it.
    checkpoint_every : int
        Epochs between checkpoints (also written when an axis ends). Not fingerprinted.
    epoch_windows : int, optional
        Training windows per epoch, a fresh random draw without replacement from all of
        them each epoch (default all). The seed's data give about 4×10⁶ windows (25
        offsets of the same runs, nearly alike); on one CPU thread a pass over all takes
        about a minute, and the learning rate decays per epoch, so shorter epochs let the
        decay and early stopping act within a CPU budget.
    val_windows : int, optional
        Validation windows for the per-epoch loss (early stopping): a fixed random subset
        drawn once (default all).
    whiten : float or None
        Shrinkage ``ε`` of the whitened inputs the training feeds the network, relative to
        the mean eigenvalue of the scaled inputs' covariance (`microfab.identify.ann_whiten`:
        the whitening is folded into the first layer when the training ends, so the saved
        network is the seed's). Assumed 1e-3: a direction the data hardly visit is
        amplified at most about 32 times. Measured on the calibrated twin (60 s of the
        networks' data, y, best validation σ within 25 epochs): ε 1e-2 / 1e-3 / 1e-4 gave
        10.1 / 9.8 / 9.8 µm; without whitening 13.7 µm after 60 epochs. None: the scaled inputs
        as they are (the training before whitening; a model file without the field).
        Between `WHITEN_LOW` and 1.
    workers : int
        Axes trained at once on the CPU, each in its own (spawned) process with
        ``threads`` threads; 1 (default): one after the other in this process. The
        networks are the same either way (each axis is seeded on its own). On a 2-core
        machine 2 threads in one process trained no faster than 1 (measured: 4.9 against
        5.0 s per epoch of 262 144 windows), two processes halve the time. Not
        fingerprinted.
    seed : int
        Seeds the initial weights and each epoch's shuffle.
    device : str
        "auto" (CUDA if present, else CPU), "cpu" or "cuda". Not fingerprinted.
    threads : int or None
        CPU threads of PyTorch for training (``torch.set_num_threads``, process wide).
        Default 1: on a shared 2-core machine 2 threads trained about 3x slower per step
        than 1 (measured by the author; a rerun of ``benchmarks/bench_ann.py``'s step
        timing there gave 2.4x slower by the median while other work ran, and 2x faster
        once it had stopped), so more threads are for a machine of one's own. ``None``:
        the cores this process may use. Not fingerprinted.
    """

    window: WindowSpec = field(default_factory=WindowSpec)
    axes: tuple[str, ...] = AXES
    offsets: tuple[int, ...] | None = None
    batch_size: int = BATCH
    learning_rate: float = 1e-3
    lr_decay: float = 0.97
    patience: int = 10
    max_epochs: int = 200
    checkpoint_every: int = 1
    epoch_windows: int | None = None
    val_windows: int | None = None
    whiten: float | None = 1e-3  # assumed: see the docstring
    workers: int = 1
    seed: int = 0
    device: str = "auto"
    threads: int | None = 1  # assumed: see the docstring (shared machines)

    def __post_init__(self) -> None:
        if not isinstance(self.window, WindowSpec):
            raise ValueError(f"window must be a WindowSpec, got {type(self.window).__name__}")
        axes = tuple(self.axes)
        if not axes or len(set(axes)) != len(axes) or any(a not in AXES for a in axes):
            raise ValueError(f"axes must be distinct names from {AXES}, got {self.axes!r}")
        object.__setattr__(self, "axes", axes)
        if self.offsets is not None:
            offs = tuple(check_int("offset", o, 0, "samples") for o in self.offsets)
            f = self.window.factor
            if not offs or any(not 0 <= o < f for o in offs) or len(set(offs)) != len(offs):
                raise ValueError(
                    f"offsets must be distinct and lie in [0, {f}) run samples, got {self.offsets}"
                )
            object.__setattr__(self, "offsets", offs)
        for name in ("batch_size", "patience", "max_epochs", "checkpoint_every"):
            check_int(name, getattr(self, name), 1)
        check_positive("learning_rate", self.learning_rate, "")
        d = check_positive("lr_decay", self.lr_decay, "per epoch")
        if d > 1.0:
            raise ValueError(f"lr_decay must lie in (0, 1] per epoch, got {d}")
        check_int("seed", self.seed, 0)
        if self.device not in ("auto", "cpu", "cuda"):
            raise ValueError(f"device must be 'auto', 'cpu' or 'cuda', got {self.device!r}")
        if self.threads is not None:
            check_int("threads", self.threads, 1)
        check_int("workers", self.workers, 1)
        for name in ("epoch_windows", "val_windows"):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), 1, "windows")
        if self.whiten is not None:
            check_whiten(self.whiten)

    _NOT_FINGERPRINTED = ("max_epochs", "checkpoint_every", "device", "threads", "workers")

    def fingerprint(self) -> dict[str, Any]:
        """What decides the training's course (JSON): all but the stopping and device knobs."""
        out: dict[str, Any] = {}
        for f in fields(self):
            if f.name in self._NOT_FINGERPRINTED:
                continue
            v = getattr(self, f.name)
            out[f.name] = v.as_dict() if isinstance(v, WindowSpec) else v
        out["axes"] = list(self.axes)
        out["offsets"] = None if self.offsets is None else list(self.offsets)
        if self.whiten is None:  # as before the field: such checkpoints stay valid
            del out["whiten"]
        return out


@dataclass(frozen=True)
class ErrorStats:
    """Prediction error ``predicted - measured`` of one axis (seed 002 Table II).

    Parameters
    ----------
    mu : float
        Mean error, m.
    sigma : float
        Standard deviation of the error, m.
    n : int
        Samples compared.
    """

    mu: float
    sigma: float
    n: int

    def as_um(self) -> tuple[float, float]:
        """``(μ, σ)`` in µm."""
        return self.mu * 1e6, self.sigma * 1e6


def _forward(net: nn.Module, x: np.ndarray, device: torch.device) -> np.ndarray:
    """Network output (float64, (b,)) for scaled float32 inputs, in chunks, no grad."""
    out = np.empty(x.shape[0])
    with torch.no_grad():
        for i in range(0, x.shape[0], _EVAL_CHUNK):
            xb = torch.from_numpy(x[i : i + _EVAL_CHUNK]).to(device)
            out[i : i + _EVAL_CHUNK] = net(xb)[:, 0].double().cpu().numpy()
    return out


class AnnModel:
    """Trained networks, one per axis, with their scaling (see the module docstring).

    Parameters
    ----------
    config : AnnConfig
        The configuration it was trained with.
    networks : dict of str to torch.nn.Module
        One `build_network` per axis in ``config.axes``.
    scalings : dict of str to Scaling
        Per axis.
    info : dict
        Training summary (epochs, losses, data digest, command acceleration seen), JSON.
    """

    def __init__(
        self,
        config: AnnConfig,
        networks: dict[str, nn.Module],
        scalings: dict[str, Scaling],
        info: dict[str, Any] | None = None,
    ) -> None:
        if set(networks) != set(config.axes) or set(scalings) != set(config.axes):
            raise ValueError(f"networks and scalings must be given for axes {config.axes}")
        self.config = config
        self.spec = config.window
        self.networks = {a: networks[a].eval() for a in config.axes}
        self.scalings = dict(scalings)
        self.info = dict(info or {})
        self.device = torch.device("cpu")
        for net in self.networks.values():
            net.to(self.device)

    @property
    def axes(self) -> tuple[str, ...]:
        """Modelled axes, in column order of `predict`."""
        return self.config.axes

    def _predict_offset(self, cmd: np.ndarray, offset: int) -> np.ndarray:
        cols = []
        for a in self.axes:
            ax = AXES.index(a)
            x, _, base = windows(cmd, None, self.spec, axis=ax, offset=offset)
            z = _forward(self.networks[a], self.scalings[a].scale_inputs(x), self.device)
            y = self.scalings[a].unscale_target(z) + base
            if not self.spec.pad:  # no prediction for the first h model samples
                y = np.concatenate([np.full(self.spec.h, np.nan), y])
            cols.append(y)
        return np.column_stack(cols)

    def predict(
        self,
        command: np.ndarray,
        *,
        at: str = "400hz",
        offset: int = 0,
        rate_hz: float | None = None,
    ) -> np.ndarray:
        """Predicted measured position for a command recorded from rest.

        Parameters
        ----------
        command : numpy.ndarray
            Shape (n, 2) (x, y), m, at the model's run rate (10 kHz), starting at rest.
        at : {"400hz", "10khz"}
            "400hz": the model samples ``offset, offset + factor, ...`` of the run,
            shape (ceil((n - offset) / factor), n_axes). "10khz": every run sample, shape
            (n, n_axes), sample ``k`` predicted from the commands at ``k - factor``,
            ``k - 2 factor``, ..., ``k - h factor`` (the offsets interleaved).
        offset : int
            Start offset for ``at="400hz"``.
        rate_hz : float, optional
            Rate of ``command``; refused unless it is the model's run rate.

        Returns
        -------
        numpy.ndarray
            Columns in `axes` order, m. Without padding the first ``h`` model samples
            are NaN.
        """
        if rate_hz is not None and abs(rate_hz - self.spec.run_rate_hz) > 1e-9 * rate_hz:
            raise ValueError(
                f"the model was trained on runs at {self.spec.run_rate_hz:g} Hz, got a "
                f"command at {rate_hz:g} Hz; resample it first"
            )
        cmd, _ = check_run(command, None, self.spec, name="command")
        if at == "400hz":
            return self._predict_offset(cmd, offset)
        if at != "10khz":
            raise ValueError(f"at must be '400hz' or '10khz', got {at!r}")
        out = np.empty((cmd.shape[0], len(self.axes)))
        for o in range(self.spec.factor):
            out[o :: self.spec.factor] = self._predict_offset(cmd, o)
        return out

    def metrics(self, runs: Sequence[Run], *, at: str = "10khz") -> dict[str, ErrorStats]:
        """μ and σ of ``predicted - measured`` per axis over ``runs`` (seed 002 Table II).

        Parameters
        ----------
        runs : sequence of (command, measured)
            Each (n, 2), m, at the run rate, from rest.
        at : {"10khz", "400hz"}
            Compare every run sample, or the 400 Hz samples at offset 0.

        Returns
        -------
        dict of str to ErrorStats
            Per modelled axis (NaN rows of an unpadded model left out).
        """
        errs: list[np.ndarray] = []
        for k, (command, measured) in enumerate(runs):
            cmd, meas = check_run(command, measured, self.spec, name=f"run {k}")
            assert meas is not None
            pred = self.predict(cmd, at=at)
            ref = meas if at == "10khz" else meas[:: self.spec.factor]
            cols = [AXES.index(a) for a in self.axes]
            errs.append(pred - ref[:, cols])
        e = np.concatenate(errs)
        out = {}
        for j, a in enumerate(self.axes):
            col = e[:, j][np.isfinite(e[:, j])]
            out[a] = ErrorStats(float(col.mean()), float(col.std()), int(col.size))
        return out

    # --- files ------------------------------------------------------------------------

    def meta(self) -> dict[str, Any]:
        """The JSON header of `save`."""
        return {
            "format_version": FORMAT_VERSION,
            "kind": "microfab per-axis ANN (seed 002 eq. 7)",
            "window": self.spec.as_dict(),
            "axes": list(self.axes),
            "layers": [self.spec.n_inputs, *HIDDEN, 1],
            "negative_slope": NEGATIVE_SLOPE,
            "n_weights": n_weights(self.spec.n_inputs),
            "config": self.config.fingerprint(),
            "scaling": {a: self.scalings[a].as_dict() for a in self.axes},
            "info": self.info,
            "torch_version": torch.__version__,
        }

    def save(self, directory: str | os.PathLike[str]) -> Path:
        """Write ``weights.npz`` (state dicts, float32) and ``model.json``, each atomically.

        Returns the directory.
        """
        d = Path(directory)
        arrays = {
            f"{a}.{k}": v.detach().cpu().numpy()
            for a in self.axes
            for k, v in self.networks[a].state_dict().items()
        }
        atomic_save_npz(d / "weights.npz", **arrays)
        atomic_write_json(d / "model.json", self.meta())
        return d

    @classmethod
    def load(
        cls,
        directory: str | os.PathLike[str],
        *,
        run_rate_hz: float | None = None,
        rate_hz: float | None = None,
        h: int | None = None,
    ) -> AnnModel:
        """Read a model written by `save`.

        Parameters
        ----------
        directory : path
            Holds ``model.json`` and ``weights.npz``.
        run_rate_hz, rate_hz, h : optional
            What the caller expects; a model with another value is refused.

        Raises
        ------
        ValueError
            Another format version, rate or history, or files that do not match.
        """
        d = Path(directory)
        meta = read_model_meta(d)
        spec = WindowSpec(**meta.window.model_dump())
        for name, want, got in (
            ("run rate", run_rate_hz, spec.run_rate_hz),
            ("model rate", rate_hz, spec.rate_hz),
            ("history h", h, spec.h),
        ):
            if want is not None and abs(float(want) - got) > 1e-9 * abs(got):
                raise ValueError(
                    f"{d / 'model.json'}: the model's {name} is {got:g}, expected {want:g}"
                )
        if meta.layers != [spec.n_inputs, *HIDDEN, 1]:
            raise ValueError(f"{d / 'model.json'}: layers {meta.layers} are not Fig. 5's")
        cfg_d = meta.config.model_dump()
        cfg_d["window"] = spec
        cfg_d["axes"] = tuple(cfg_d["axes"])
        if cfg_d["offsets"] is not None:
            cfg_d["offsets"] = tuple(cfg_d["offsets"])
        config = AnnConfig(**cfg_d)
        missing = [a for a in config.axes if a not in meta.scaling]
        if missing:
            raise SchemaError(f"{d / 'model.json'}: scaling.{missing[0]} is missing")
        scal = {}
        for a in config.axes:
            sd = meta.scaling[a]
            if len(sd.in_offset) != spec.n_inputs or len(sd.in_scale) != spec.n_inputs:
                raise SchemaError(
                    f"{d / 'model.json'}: scaling.{a} must hold {spec.n_inputs} input offsets "
                    f"and scales, got {len(sd.in_offset)} and {len(sd.in_scale)}"
                )
            scal[a] = Scaling.from_dict(sd.model_dump())
        nets = {a: build_network(spec.n_inputs, seed=0) for a in config.axes}
        arrays = read_weights(d / "weights.npz", nets)
        for a, net in nets.items():
            net.load_state_dict({k: torch.from_numpy(arrays[f"{a}.{k}"]) for k in net.state_dict()})
        return cls(config, nets, scal, meta.info)
