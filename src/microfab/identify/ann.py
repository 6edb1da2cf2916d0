"""Per-axis feed-forward neural networks of seed 002 (§III-B, eq. 7, Fig. 5).

One network per axis predicts the measured position at a 400 Hz sample from the last
500 ms of that axis's command, ``φ_i = f_nlm(r_{i-h}, ..., r_{i-1})`` (eq. 7, h = 200).
Windows, encoding and scaling are `microfab.identify.ann_data` (read its docstring for
what ``φ_i`` is and how a run's start is handled).

* Network (`build_network`, seed 002 Fig. 5): fully connected, hidden layers
  ``{200, 200, 100, 100, 50, 25, 12, 6}``, LeakyReLU of slope 0.01 after each, biases,
  one linear output: 117 322 weights for 200 inputs (`n_weights`).
* Training (`train_ann`, seed 002 §III-C): mean square error of the scaled target, Adam
  with an exponentially decaying learning rate, batches of 16 384 windows, CUDA when
  present else the CPU (``torch.set_num_threads`` from the cores this process may use),
  seeded; early stopping on the validation loss (the best epoch's weights are kept).
  Checkpoints (weights, Adam, scheduler, RNG, epoch, best, scaling) are written
  atomically every ``checkpoint_every`` epochs; a rerun with the same configuration and
  data resumes, and on the CPU the result is bit for bit that of an uninterrupted run. A
  checkpoint of another configuration, data set or format version is refused, naming
  the difference (``restart=True`` starts afresh).
* `AnnModel`: `AnnModel.predict` (400 Hz at one start offset, or every 10 kHz sample by
  interleaving all offsets), `AnnModel.metrics` (μ, σ per axis as seed 002 Table II),
  `AnnModel.save` / `AnnModel.load` (``weights.npz`` + ``model.json``, no pickles;
  another format version, rate or history refused).

PyTorch is imported here only (extra ``ann``).
"""

from __future__ import annotations

import itertools
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from microfab.core.validate import check_int, check_positive
from microfab.identify.ann_data import (
    AXES,
    Run,
    Scaling,
    WindowSet,
    WindowSpec,
    check_run,
    data_digest,
    windows,
)
from microfab.io.atomic import atomic_save_npz, atomic_write_json

__all__ = [
    "FORMAT_VERSION",
    "HIDDEN",
    "NEGATIVE_SLOPE",
    "AnnConfig",
    "AnnModel",
    "CheckpointMismatchError",
    "EpochRecord",
    "ErrorStats",
    "build_network",
    "n_weights",
    "train_ann",
]

FORMAT_VERSION = 1  # of model.json / weights.npz and of the checkpoints
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
    seed : int
        Seeds the initial weights and each epoch's shuffle.
    device : str
        "auto" (CUDA if present, else CPU), "cpu" or "cuda". Not fingerprinted.
    threads : int, optional
        CPU threads (default: the cores this process may use). Not fingerprinted.
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
    seed: int = 0
    device: str = "auto"
    threads: int | None = None

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

    _NOT_FINGERPRINTED = ("max_epochs", "checkpoint_every", "device", "threads")

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
        return out


class CheckpointMismatchError(ValueError):
    """A checkpoint was written for another configuration, data set or format version."""


@dataclass(frozen=True)
class EpochRecord:
    """One finished epoch, handed to ``progress``: losses are scaled MSE."""

    axis: str
    epoch: int
    train_loss: float
    val_loss: float
    learning_rate: float
    seconds: float


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


def _device(config: AnnConfig) -> torch.device:
    if config.device == "cuda" or (config.device == "auto" and torch.cuda.is_available()):
        return torch.device("cuda")
    return torch.device("cpu")


def _set_threads(config: AnnConfig) -> None:
    if config.threads is not None:
        n = config.threads
    else:
        try:
            n = len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            n = os.cpu_count() or 1
    torch.set_num_threads(max(1, n))


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
        meta = json.loads((d / "model.json").read_text())
        ver = meta.get("format_version")
        if ver != FORMAT_VERSION:
            raise ValueError(
                f"{d / 'model.json'}: model format version {ver}, this microfab reads "
                f"version {FORMAT_VERSION}; retrain the model"
            )
        spec = WindowSpec(**meta["window"])
        for name, want, got in (
            ("run rate", run_rate_hz, spec.run_rate_hz),
            ("model rate", rate_hz, spec.rate_hz),
            ("history h", h, spec.h),
        ):
            if want is not None and abs(float(want) - got) > 1e-9 * abs(got):
                raise ValueError(
                    f"{d / 'model.json'}: the model's {name} is {got:g}, expected {want:g}"
                )
        if meta["layers"] != [spec.n_inputs, *HIDDEN, 1]:
            raise ValueError(f"{d / 'model.json'}: layers {meta['layers']} are not Fig. 5's")
        cfg_d = dict(meta["config"])
        cfg_d["window"] = spec
        cfg_d["axes"] = tuple(cfg_d["axes"])
        if cfg_d["offsets"] is not None:
            cfg_d["offsets"] = tuple(cfg_d["offsets"])
        config = AnnConfig(**cfg_d)
        nets: dict[str, nn.Module] = {}
        with np.load(d / "weights.npz", allow_pickle=False) as z:
            for a in config.axes:
                net = build_network(spec.n_inputs, seed=0)
                state = {k: torch.from_numpy(z[f"{a}.{k}"].copy()) for k in net.state_dict()}
                net.load_state_dict(state)
                nets[a] = net
        scal = {a: Scaling.from_dict(meta["scaling"][a]) for a in config.axes}
        return cls(config, nets, scal, meta.get("info", {}))


# --- training ----------------------------------------------------------------------------


def _ckpt_path(directory: Path, axis: str) -> Path:
    return directory / f"ann_{axis}.ckpt.npz"


def _state_arrays(prefix: str, state: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
    return {f"{prefix}.{k}": v.detach().cpu().numpy().copy() for k, v in state.items()}


def _save_checkpoint(path: Path, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    blob = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    atomic_save_npz(path, meta=blob, **arrays)


def _load_checkpoint(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    meta = json.loads(arrays.pop("meta").tobytes().decode())
    return meta, arrays


def _differences(there: dict[str, Any], here: dict[str, Any], prefix: str = "") -> list[str]:
    out = []
    for k in sorted(set(there) | set(here)):
        a, b = there.get(k), here.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k} {a!r} there, {b!r} here")
    return out


def _check_checkpoint(path: Path, meta: dict[str, Any], expect: dict[str, Any]) -> None:
    diffs = _differences({k: meta.get(k) for k in expect}, {k: expect[k] for k in expect})
    if diffs:
        shown = "; ".join(d if len(d) < 200 else d[:200] + "..." for d in diffs)
        raise CheckpointMismatchError(
            f"{path}: checkpoint of another training: {shown}; pass restart=True or use "
            f"another checkpoint directory"
        )


def train_ann(
    train_runs: Sequence[Run],
    val_runs: Sequence[Run],
    config: AnnConfig | None = None,
    *,
    checkpoint_dir: str | os.PathLike[str] | None = None,
    progress: Callable[[EpochRecord], None] | None = None,
    restart: bool = False,
) -> AnnModel:
    """Train one network per axis on ``train_runs``, stop early on ``val_runs``.

    Parameters
    ----------
    train_runs, val_runs : sequence of (command, measured)
        Whole runs (the seed's 80/20 split is by run), each (n, 2), m, at
        ``config.window.run_rate_hz``, from rest.
    config : AnnConfig, optional
        Defaults to ``AnnConfig()`` (the seed's network and batch size).
    checkpoint_dir : path, optional
        Where ``ann_<axis>.ckpt.npz`` is kept; an existing one is resumed (or refused if
        it belongs to another configuration, data set or version).
    progress : callable, optional
        Called with an `EpochRecord` after each epoch.
    restart : bool
        Ignore (overwrite) existing checkpoints.

    Returns
    -------
    AnnModel
        The best validation epoch's weights per axis.
    """
    config = AnnConfig() if config is None else config
    spec = config.window
    device = _device(config)
    _set_threads(config)
    train = WindowSet(train_runs, spec, config.offsets)
    val = WindowSet(val_runs, spec, config.offsets)
    expect = {
        "format_version": FORMAT_VERSION,
        "config": config.fingerprint(),
        "train_digest": data_digest(train_runs),
        "val_digest": data_digest(val_runs),
    }
    ckdir = None if checkpoint_dir is None else Path(checkpoint_dir)
    nets: dict[str, nn.Module] = {}
    scalings: dict[str, Scaling] = {}
    info: dict[str, Any] = {
        "train_digest": expect["train_digest"],
        "val_digest": expect["val_digest"],
        "train_windows": len(train),
        "val_windows": len(val),
        "command_accel_max_m_s2": dict(zip(AXES, train.command_accel_max(), strict=True)),
        "axes": {},
    }
    for a in config.axes:
        net, scaling, summary = _train_axis(
            a, train, val, config, device, expect, ckdir, progress, restart
        )
        nets[a], scalings[a] = net, scaling
        info["axes"][a] = summary
    return AnnModel(config, nets, scalings, info)


def _train_axis(
    axis: str,
    train: WindowSet,
    val: WindowSet,
    config: AnnConfig,
    device: torch.device,
    expect: dict[str, Any],
    ckdir: Path | None,
    progress: Callable[[EpochRecord], None] | None,
    restart: bool,
) -> tuple[nn.Module, Scaling, dict[str, Any]]:
    ax = AXES.index(axis)
    spec = config.window
    net = build_network(spec.n_inputs, seed=config.seed + 1000 * ax).to(device)
    opt = torch.optim.Adam(net.parameters(), lr=config.learning_rate)
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma=config.lr_decay)
    path = None if ckdir is None else _ckpt_path(ckdir, axis)
    st: dict[str, Any] = {
        "epoch": 0,
        "best_val": None,
        "best_epoch": -1,
        "bad": 0,
        "stopped": False,
        "history": [],
    }
    best_state: dict[str, torch.Tensor] | None = None
    if path is not None and path.exists() and not restart:
        meta, arrays = _load_checkpoint(path)
        _check_checkpoint(path, meta, expect)
        scaling = Scaling.from_dict(meta["scaling"])
        net.load_state_dict(_tensors(arrays, "w", device))
        best_state = _tensors(arrays, "best", device)
        opt_state = {"state": {}, "param_groups": meta["adam_groups"]}
        for i in range(len(list(net.parameters()))):
            keys = [k for k in arrays if k.startswith(f"adam.{i}.")]
            if keys:
                opt_state["state"][i] = {
                    k.split(".", 2)[2]: torch.from_numpy(arrays[k]).to(device) for k in keys
                }
                opt_state["state"][i]["step"] = opt_state["state"][i]["step"].cpu()
        opt.load_state_dict(opt_state)
        sched.load_state_dict(meta["scheduler"])
        torch.set_rng_state(torch.from_numpy(arrays["torch_rng"]))
        st = meta["state"]
    else:
        scaling = train.fit_scaling(ax)

    n = len(train)
    bs = config.batch_size
    loss_fn = nn.MSELoss()
    while not st["stopped"] and st["epoch"] < config.max_epochs:
        t0 = time.perf_counter()
        net.train()
        perm = np.random.default_rng([config.seed, ax, st["epoch"]]).permutation(n)
        total = 0.0
        for i in range(0, n, bs):
            idx = perm[i : i + bs]
            x, t = train.batch(idx, ax)
            xb = torch.from_numpy(scaling.scale_inputs(x)).to(device)
            tb = torch.from_numpy(scaling.scale_target(t)).to(device)
            opt.zero_grad(set_to_none=True)
            loss = loss_fn(net(xb)[:, 0], tb)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * idx.size
        sched.step()
        net.eval()
        val_loss = _val_loss(net, val, ax, scaling, device)
        train_loss = total / n
        if st["best_val"] is None or val_loss < st["best_val"]:
            st["best_val"], st["best_epoch"], st["bad"] = val_loss, st["epoch"], 0
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        else:
            st["bad"] += 1
        st["epoch"] += 1
        st["history"].append([train_loss, val_loss])
        if st["bad"] >= config.patience:
            st["stopped"] = True
        done = st["stopped"] or st["epoch"] >= config.max_epochs
        if path is not None and (done or st["epoch"] % config.checkpoint_every == 0):
            assert best_state is not None
            _write_checkpoint(path, expect, st, scaling, net, best_state, opt, sched)
        if progress is not None:
            progress(
                EpochRecord(
                    axis,
                    st["epoch"],
                    train_loss,
                    val_loss,
                    float(sched.get_last_lr()[0]),
                    time.perf_counter() - t0,
                )
            )
    if best_state is not None:
        net.load_state_dict(best_state)
    net = net.cpu().eval()
    summary = {
        "epochs": st["epoch"],
        "best_epoch": st["best_epoch"],
        "best_val_loss": st["best_val"],
        "stopped_early": st["stopped"],
        "history": st["history"],
    }
    return net, scaling, summary


def _tensors(arrays: dict[str, np.ndarray], prefix: str, device: torch.device) -> dict[str, Any]:
    p = prefix + "."
    return {
        k[len(p) :]: torch.from_numpy(v).to(device) for k, v in arrays.items() if k.startswith(p)
    }


def _val_loss(
    net: nn.Module, ws: WindowSet, ax: int, scaling: Scaling, device: torch.device
) -> float:
    """Scaled MSE over all windows of ``ws``, gathered chunk by chunk (memory bounded)."""
    idx = np.arange(len(ws))
    total = 0.0
    for i in range(0, len(ws), _EVAL_CHUNK):
        x, t = ws.batch(idx[i : i + _EVAL_CHUNK], ax)
        z = _forward(net, scaling.scale_inputs(x), device)
        total += float(((z - scaling.scale_target(t)) ** 2).sum())
    return total / len(ws)


def _write_checkpoint(
    path: Path,
    expect: dict[str, Any],
    st: dict[str, Any],
    scaling: Scaling,
    net: nn.Module,
    best_state: dict[str, torch.Tensor],
    opt: torch.optim.Optimizer,
    sched: torch.optim.lr_scheduler.LRScheduler,
) -> None:
    osd = opt.state_dict()
    arrays = _state_arrays("w", net.state_dict())
    arrays.update(_state_arrays("best", best_state))
    for i, s in osd["state"].items():
        arrays.update(_state_arrays(f"adam.{i}", s))
    arrays["torch_rng"] = torch.get_rng_state().numpy().copy()
    meta = dict(expect)
    meta.update(
        state=st,
        scaling=scaling.as_dict(),
        adam_groups=osd["param_groups"],
        scheduler=sched.state_dict(),
    )
    _save_checkpoint(path, meta, arrays)
