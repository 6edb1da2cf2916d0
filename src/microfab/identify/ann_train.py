"""Training of the per-axis networks of seed 002 (§III-C) with resumable checkpoints.

The networks, `AnnConfig` and `AnnModel` are `microfab.identify.ann`; this module
imports them (the model module does not import this one).

* `train_ann`: mean square error of the scaled target, Adam with an exponentially
  decaying learning rate, batches of 16 384 windows, CUDA when present else the CPU on
  ``AnnConfig.threads`` threads (default 1, see `AnnConfig`), seeded; early stopping on
  the validation loss (the best epoch's weights are kept). `EpochRecord` is handed to
  ``progress`` after each epoch.
* Whitened inputs (``AnnConfig.whiten``, `microfab.identify.ann_whiten`): the network is
  trained on the ZCA-whitened scaled windows and the whitening is folded into its first
  layer at the end, so the returned network reads the scaled inputs as before. A warm
  start's first layer is unfolded with the new data's whitening (the same function).
* Checkpoints (weights, Adam, scheduler, RNG, epoch, best, scaling) are written
  atomically every ``checkpoint_every`` epochs; a rerun with the same configuration and
  data resumes, and on the CPU the result is bit for bit that of an uninterrupted run. A
  checkpoint of another configuration, data set or format version is refused with
  `CheckpointMismatchError`, naming the difference (``restart=True`` starts afresh).
* Warm start (``init``): the training starts from the weights of a trained `AnnModel`
  (seed 002 §III-C.2: the first-generation network "trained further" on the optimised
  runs gives the second generation) instead of `build_network`'s seeded ones. The
  previous model's scaling is kept, not refitted: its weights act on inputs and targets
  scaled that way, and a refit would move every input under them (the generations add
  runs of the same workspace and accelerations, so the scaling still fits). Before the
  first epoch the start weights are scored on the validation runs and count as a
  candidate (best epoch -1): a retraining that never improves on them gives them back.
  The start model's digest (`init_digest`) is part of the checkpoint fingerprint, so a
  checkpoint trained from other weights is refused; a cold start's fingerprint is as it
  was.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from microfab.identify.ann import (
    _EVAL_CHUNK,
    FORMAT_VERSION,
    AnnConfig,
    AnnModel,
    _forward,
    build_network,
)
from microfab.identify.ann_data import AXES, Run, Scaling, WindowSet, data_digest
from microfab.identify.ann_whiten import (
    covariance_windows,
    fold,
    input_covariance,
    unfold,
    whitening,
)
from microfab.io.checkpoint import read_state, save_state
from microfab.io.runstore import RunRefusedError

__all__ = ["CheckpointMismatchError", "EpochRecord", "init_digest", "train_ann"]


class CheckpointMismatchError(RunRefusedError):
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


# --- checkpoints -------------------------------------------------------------------------


def _ckpt_path(directory: Path, axis: str) -> Path:
    return directory / f"ann_{axis}.ckpt.npz"


def _state_arrays(prefix: str, state: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
    return {f"{prefix}.{k}": v.detach().cpu().numpy().copy() for k, v in state.items()}


#: What `microfab.io.checkpoint` calls a network's training checkpoint.
_KIND = "network checkpoint"
_FIX = "pass restart=True or use another checkpoint directory"


def _flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested settings as dotted names (``config.window.h``), so a refusal names the leaf."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _settings(expect: dict[str, Any]) -> dict[str, Any]:
    return _flat({k: v for k, v in expect.items() if k != "format_version"})


def _save_checkpoint(
    path: Path, expect: dict[str, Any], meta: dict[str, Any], arrays: dict[str, np.ndarray]
) -> None:
    save_state(path, kind=_KIND, version=FORMAT_VERSION, settings=_settings(expect),
               arrays=arrays, meta=meta)  # fmt: skip


def _load_checkpoint(
    path: Path, expect: dict[str, Any]
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    try:
        saved = read_state(path, kind=_KIND, versions=(FORMAT_VERSION,),
                           settings=_settings(expect), fix=_FIX)  # fmt: skip
    except RunRefusedError as exc:
        raise CheckpointMismatchError(str(exc)) from None
    if saved is None:
        raise FileNotFoundError(path)
    return saved.meta, saved.arrays


def init_digest(model: AnnModel, axes: Sequence[str] | None = None) -> str:
    """SHA-256 (hex) of a model's weights and scalings for ``axes`` (default all).

    What a warm start starts from (`train_ann` ``init``): part of the checkpoint
    fingerprint.
    """
    h = hashlib.sha256()
    for a in model.axes if axes is None else axes:
        h.update(a.encode())
        for k, v in model.networks[a].state_dict().items():
            h.update(k.encode())
            h.update(v.detach().cpu().numpy().astype("<f4").tobytes())
        h.update(json.dumps(model.scalings[a].as_dict(), sort_keys=True, default=str).encode())
    return h.hexdigest()


def _check_init(init: AnnModel, config: AnnConfig) -> None:
    """Refuse a start model whose networks do not fit ``config`` (window, axes)."""
    missing = [a for a in config.axes if a not in init.axes]
    if missing:
        raise ValueError(f"init: the start model has no network for axes {missing}")
    if init.spec.as_dict() != config.window.as_dict():
        raise ValueError(
            f"init: the start model's window {init.spec.as_dict()} is not the training's "
            f"{config.window.as_dict()}; a warm start needs the same inputs"
        )


# --- training ----------------------------------------------------------------------------


def train_ann(
    train_runs: Sequence[Run],
    val_runs: Sequence[Run],
    config: AnnConfig | None = None,
    *,
    checkpoint_dir: str | os.PathLike[str] | None = None,
    progress: Callable[[EpochRecord], None] | None = None,
    restart: bool = False,
    init: AnnModel | None = None,
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
    init : AnnModel, optional
        Warm start (module docstring): start from these networks and keep their scaling;
        same window and axes as ``config``. Its digest is fingerprinted.

    Returns
    -------
    AnnModel
        The best validation epoch's weights per axis (with ``init``: the start weights
        if no epoch beat them, best epoch -1).
    """
    config = AnnConfig() if config is None else config
    if init is not None:
        _check_init(init, config)
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
    if init is not None:  # only then: a cold start's checkpoints stay valid
        expect["init_digest"] = init_digest(init, config.axes)
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
    if init is not None:
        info["init_digest"] = expect["init_digest"]
    start = None if init is None else {a: (init.networks[a], init.scalings[a]) for a in config.axes}
    if config.workers > 1 and len(config.axes) > 1 and device.type == "cpu":
        done = _train_in_processes(train, val, config, expect, ckdir, progress, restart, start)
    else:
        done = {
            a: _train_axis(
                a, train, val, config, device, expect, ckdir, progress, restart,
                None if start is None else start[a],
            )
            for a in config.axes
        }  # fmt: skip
    for a in config.axes:
        nets[a], scalings[a], info["axes"][a] = done[a]
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
    start: tuple[nn.Module, Scaling] | None = None,
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
    val_idx = None
    if config.val_windows is not None and config.val_windows < len(val):
        rng = np.random.default_rng([config.seed, ax, 7919])
        val_idx = np.sort(rng.choice(len(val), config.val_windows, replace=False))
    if path is not None and path.exists() and not restart:
        meta, arrays = _load_checkpoint(path, expect)
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
        white = _whitening_of(arrays, config)
    elif start is not None:  # warm start: the previous weights and scaling (module doc)
        net.load_state_dict({k: v.detach().clone() for k, v in start[0].state_dict().items()})
        scaling = start[1]
        white = _whitening(train, ax, scaling, config)
        if white is not None:  # the same function, now reading whitened inputs
            unfold(net, white[1])
        best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        net.eval()
        st["best_val"] = _val_loss(net, val, ax, scaling, device, val_idx, white)
    else:
        scaling = train.fit_scaling(ax)
        white = _whitening(train, ax, scaling, config)
    w_in = None if white is None else torch.from_numpy(white[0].astype(np.float32)).to(device)

    n_all = len(train)
    n = n_all if config.epoch_windows is None else min(config.epoch_windows, n_all)
    bs = config.batch_size
    loss_fn = nn.MSELoss()
    while not st["stopped"] and st["epoch"] < config.max_epochs:
        t0 = time.perf_counter()
        net.train()
        perm = np.random.default_rng([config.seed, ax, st["epoch"]]).permutation(n_all)[:n]
        total = 0.0
        for i in range(0, n, bs):
            idx = perm[i : i + bs]
            x, t = train.batch(idx, ax)
            xb = torch.from_numpy(scaling.scale_inputs(x)).to(device)
            if w_in is not None:
                xb = xb @ w_in
            tb = torch.from_numpy(scaling.scale_target(t)).to(device)
            opt.zero_grad(set_to_none=True)
            loss = loss_fn(net(xb)[:, 0], tb)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * idx.size
        sched.step()
        net.eval()
        val_loss = _val_loss(net, val, ax, scaling, device, val_idx, white)
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
            _write_checkpoint(path, expect, st, scaling, net, best_state, opt, sched, white)
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
    if white is not None and st["best_epoch"] == -1 and start is not None:
        # no epoch beat the start: its weights exactly (unfold-then-fold rounds them)
        net.load_state_dict({k: v.detach().clone() for k, v in start[0].state_dict().items()})
    elif white is not None:  # the saved network reads the scaled inputs (ann_whiten)
        fold(net, white[0])
    summary = {
        "epochs": st["epoch"],
        "best_epoch": st["best_epoch"],
        "best_val_loss": st["best_val"],
        "stopped_early": st["stopped"],
        "history": st["history"],
    }
    return net, scaling, summary


def _axis_job(
    axis: str,
    train: WindowSet,
    val: WindowSet,
    config: AnnConfig,
    expect: dict[str, Any],
    ckdir: Path | None,
    queue: Any,
    restart: bool,
    start: tuple[dict[str, torch.Tensor], Scaling] | None = None,
) -> tuple[dict[str, torch.Tensor], Scaling, dict[str, Any]]:
    """One axis's training in a worker process; epochs go to ``queue`` (if any)."""
    _set_threads(config)
    report = None if queue is None else queue.put
    begin = None
    if start is not None:  # state dicts travel to the worker, networks are rebuilt there
        net0 = build_network(config.window.n_inputs, seed=0)
        net0.load_state_dict(start[0])
        begin = (net0, start[1])
    net, scaling, summary = _train_axis(
        axis, train, val, config, torch.device("cpu"), expect, ckdir, report, restart, begin
    )
    return net.state_dict(), scaling, summary


def _train_in_processes(
    train: WindowSet,
    val: WindowSet,
    config: AnnConfig,
    expect: dict[str, Any],
    ckdir: Path | None,
    progress: Callable[[EpochRecord], None] | None,
    restart: bool,
    start: dict[str, tuple[nn.Module, Scaling]] | None = None,
) -> dict[str, tuple[nn.Module, Scaling, dict[str, Any]]]:
    """`_train_axis` of each axis in its own spawned process (``config.workers`` at once).

    Epoch records come back through a queue and are handed to ``progress`` here, in this
    process. A failure in a worker is raised here once the others have ended (a running
    training cannot be cancelled).
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, wait

    ctx = mp.get_context("spawn")  # forking a process that ran torch can deadlock
    n = min(config.workers, len(config.axes))
    with ctx.Manager() as manager, ProcessPoolExecutor(n, mp_context=ctx) as pool:
        queue = None if progress is None else manager.Queue()
        futures = {
            a: pool.submit(
                _axis_job, a, train, val, config, expect, ckdir, queue, restart,
                None if start is None else (start[a][0].state_dict(), start[a][1]),
            )
            for a in config.axes
        }  # fmt: skip

        def drain() -> None:
            while queue is not None and not queue.empty():
                progress(queue.get())  # type: ignore[misc]

        pending = set(futures.values())
        while pending:
            _, pending = wait(pending, timeout=0.2)
            drain()
        results = {a: f.result() for a, f in futures.items()}  # raises a worker's error
    out = {}
    for a, (state, scaling, summary) in results.items():
        net = build_network(config.window.n_inputs, seed=0)
        net.load_state_dict(state)
        out[a] = (net.eval(), scaling, summary)
    return out


def _tensors(arrays: dict[str, np.ndarray], prefix: str, device: torch.device) -> dict[str, Any]:
    p = prefix + "."
    return {
        k[len(p) :]: torch.from_numpy(v).to(device) for k, v in arrays.items() if k.startswith(p)
    }


def _val_loss(
    net: nn.Module,
    ws: WindowSet,
    ax: int,
    scaling: Scaling,
    device: torch.device,
    idx: np.ndarray | None = None,
    white: tuple[np.ndarray, np.ndarray] | None = None,
) -> float:
    """Scaled MSE over the windows ``idx`` of ``ws`` (default all), chunk by chunk.

    ``white``: the whitening and its inverse (`_whitening`) the network reads its inputs
    through, or None.
    """
    idx = np.arange(len(ws)) if idx is None else idx
    w = None if white is None else white[0].astype(np.float32)
    total = 0.0
    for i in range(0, idx.size, _EVAL_CHUNK):
        x, t = ws.batch(idx[i : i + _EVAL_CHUNK], ax)
        s = scaling.scale_inputs(x)
        z = _forward(net, s if w is None else s @ w, device)
        total += float(((z - scaling.scale_target(t)) ** 2).sum())
    return total / idx.size


def _whitening(
    train: WindowSet, ax: int, scaling: Scaling, config: AnnConfig
) -> tuple[np.ndarray, np.ndarray] | None:
    """The whitening of the scaled training inputs and its inverse (None: not whitened)."""
    if config.whiten is None:
        return None
    most = covariance_windows(config.epoch_windows)
    return whitening(input_covariance(train, ax, scaling, most=most), config.whiten)


def _whitening_of(
    arrays: dict[str, np.ndarray], config: AnnConfig
) -> tuple[np.ndarray, np.ndarray] | None:
    """The whitening a checkpoint was trained with (its fingerprint holds ``whiten``)."""
    if config.whiten is None:
        return None
    if "whiten" not in arrays or "whiten_inv" not in arrays:
        raise CheckpointMismatchError(
            f"the checkpoint has no whitening though its settings whiten the inputs; {_FIX}"
        )
    return arrays["whiten"], arrays["whiten_inv"]


def _write_checkpoint(
    path: Path,
    expect: dict[str, Any],
    st: dict[str, Any],
    scaling: Scaling,
    net: nn.Module,
    best_state: dict[str, torch.Tensor],
    opt: torch.optim.Optimizer,
    sched: torch.optim.lr_scheduler.LRScheduler,
    white: tuple[np.ndarray, np.ndarray] | None = None,
) -> None:
    osd = opt.state_dict()
    arrays = _state_arrays("w", net.state_dict())
    if white is not None:  # saved, not recomputed: a resume is then bit for bit
        arrays["whiten"], arrays["whiten_inv"] = white
    arrays.update(_state_arrays("best", best_state))
    for i, s in osd["state"].items():
        arrays.update(_state_arrays(f"adam.{i}", s))
    arrays["torch_rng"] = torch.get_rng_state().numpy().copy()
    meta = dict(
        state=st,
        scaling=scaling.as_dict(),
        adam_groups=osd["param_groups"],
        scheduler=sched.state_dict(),
    )
    _save_checkpoint(path, expect, meta, arrays)
