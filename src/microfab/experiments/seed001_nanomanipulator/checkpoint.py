"""Checkpoints of a seed 001 job (`run.run_job`): period-long chunks saved in batches.

A checkpoint file ``run/chunks/NNNNN.npz`` (``NNNNN`` its first chunk) holds one or more
consecutive chunks: their signals and log points, concatenated, the circles they end
(with those circles' final controller states), and the loop state after its last chunk
(plant, controller with its RBF weights and RC memory, last command, gate state). Each
file is a run-store state file (`microfab.io.checkpoint`): written atomically, complete or
absent, stamped with its kind, format version and the job's fingerprint, and refused on
one line when cut short, damaged or of another job. The run resumes after the last chunk
of the last file in the unbroken sequence from chunk 0.

How many chunks a file holds is the writer's choice (`run.run_job` saves at most once
per ``checkpoint_s`` of wall time, and always when interrupted); reading does not care.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.checkpoint import read_state, save_state
from microfab.sim.loop import LoopState

__all__ = ["FORMAT_VERSION", "Chunk", "chunk_path", "load_chunks", "save_chunks"]

#: Format of the checkpoint files (4: a run-store state file; 3: several chunks per file;
#: 2 had one chunk per file; 1 kept a separate ``run/state.npz``).
FORMAT_VERSION = 4
#: What `microfab.io.checkpoint` calls these files.
KIND = "nanomanipulator job checkpoint"
_FIX = "rerun with --fresh, or use another output folder"
_OLD_STATE = "state.npz"  # format 1


@dataclass(frozen=True, kw_only=True, eq=False)
class Chunk:
    """One period-long chunk of a job: its signals and the loop state after it.

    Attributes
    ----------
    output, measured, command : numpy.ndarray
        True position (mm), measured position (mm), command (V) over the chunk, (n, 2).
    laser : numpy.ndarray
        Laser on per sample, bool, shape (n,).
    log_index : numpy.ndarray
        Samples (job index) of the log points, int, shape (m,).
    log_w, log_s : numpy.ndarray
        ‖Ŵ‖ (V) and ``s`` (mm/s) per axis at the log points, shape (m, 2).
    loop : LoopState or None
        Plant, controller and last command after the chunk (no observer). None for a
        chunk read back from inside a checkpoint file (only the last one's is saved).
    gate : numpy.ndarray or None
        Laser gate state after the chunk (None outside a circle, or with ``loop`` None).
    final_circle : int or None
        The circle this chunk ends, if it ends one.
    final_controller : numpy.ndarray or None
        That circle's final controller state (the RC memory a later circle may carry).
    """

    output: np.ndarray
    measured: np.ndarray
    command: np.ndarray
    laser: np.ndarray
    log_index: np.ndarray
    log_w: np.ndarray
    log_s: np.ndarray
    loop: LoopState | None
    gate: np.ndarray | None = None
    final_circle: int | None = None
    final_controller: np.ndarray | None = None


def chunk_path(run_dir: Path, first: int) -> Path:
    """``run_dir/chunks/NNNNN.npz``: the checkpoint whose first chunk is ``first``."""
    return run_dir / "chunks" / f"{first:05d}.npz"


def save_chunks(run_dir: Path, first: int, chunks: Sequence[Chunk], fingerprint: str) -> None:
    """Write chunks ``first, first + 1, ...`` and the state after the last, atomically.

    Parameters
    ----------
    run_dir : pathlib.Path
        The run folder (``out/run``).
    first : int
        Number of the first chunk, from 0.
    chunks : sequence of Chunk
        Consecutive chunks (at least one); the last must carry its ``loop`` state.
    fingerprint : str
        `JobConfig.fingerprint` of the job.
    """
    if not chunks:
        raise ValueError("save_chunks needs at least one chunk")
    last = chunks[-1]
    if last.loop is None:
        raise ValueError("the last chunk of a checkpoint must carry its loop state")
    ends = [c for c in chunks if c.final_circle is not None]
    arrays: dict[str, Any] = {
        "sizes": np.array([c.laser.shape[0] for c in chunks], dtype=np.int64),
        "log_sizes": np.array([c.log_index.shape[0] for c in chunks], dtype=np.int64),
        "output": np.concatenate([c.output for c in chunks]),
        "measured": np.concatenate([c.measured for c in chunks]),
        "command": np.concatenate([c.command for c in chunks]),
        "laser": np.concatenate([c.laser for c in chunks]),
        "log_index": np.concatenate([np.asarray(c.log_index, dtype=np.int64) for c in chunks]),
        "log_w": np.concatenate([np.reshape(c.log_w, (-1, 2)) for c in chunks]),
        "log_s": np.concatenate([np.reshape(c.log_s, (-1, 2)) for c in chunks]),
        "ends_at": np.array([i for i, c in enumerate(chunks) if c.final_circle is not None]),
        "final_circles": np.array([c.final_circle for c in ends], dtype=np.int64),
        "plant": last.loop.plant,
        "controller": last.loop.controller,
        "last_command": last.loop.command,
    }
    if ends:
        arrays["final_controllers"] = np.stack([c.final_controller for c in ends])
    if last.gate is not None:
        arrays["gate"] = last.gate
    save_state(chunk_path(run_dir, first), kind=KIND, version=FORMAT_VERSION,
               settings={"job": fingerprint}, arrays=arrays)  # fmt: skip


def _split(a: np.ndarray, sizes: np.ndarray) -> list[np.ndarray]:
    return np.split(a, np.cumsum(sizes)[:-1])


def _load(path: Path, fingerprint: str) -> list[Chunk]:
    saved = read_state(path, kind=KIND, versions=(FORMAT_VERSION,),
                       settings={"job": fingerprint}, fix=_FIX)  # fmt: skip
    if saved is None:
        return []
    z = saved.arrays
    sizes, log_sizes = z["sizes"], z["log_sizes"]
    sig = {k: _split(z[k], sizes) for k in ("output", "measured", "command", "laser")}
    logs = {k: _split(z[k], log_sizes) for k in ("log_index", "log_w", "log_s")}
    # chunk (within the file) -> (circle it ends, that circle's final controller state)
    ends = {
        int(i): (int(c), z["final_controllers"][j])
        for j, (i, c) in enumerate(zip(z["ends_at"], z["final_circles"], strict=True))
    }
    loop = LoopState(
        plant=z["plant"],
        controller=z["controller"],
        observer=np.zeros(0),
        command=z["last_command"],
    )
    gate = z["gate"] if "gate" in z else None
    out = []
    n = sizes.shape[0]
    for i in range(n):
        circle, final = ends.get(i, (None, None))
        out.append(
            Chunk(
                **{k: v[i] for k, v in sig.items()},
                **{k: v[i] for k, v in logs.items()},
                loop=loop if i == n - 1 else None,
                gate=gate if i == n - 1 else None,
                final_circle=circle,
                final_controller=final,
            )
        )
    return out


def load_chunks(run_dir: Path, fingerprint: str, total: int) -> list[Chunk]:
    """The saved chunks 0, 1, ... up to the first missing checkpoint (at most ``total``).

    Raises
    ------
    ValueError
        When a checkpoint belongs to another job configuration or format (including
        the format-1 ``state.npz``), or holds more chunks than the job; nothing is
        changed then.
    """
    if (run_dir / _OLD_STATE).exists():
        raise ValueError(
            f"{run_dir} holds a run saved in format 1 ({_OLD_STATE}); this microfab reads "
            f"format {FORMAT_VERSION}; {_FIX}"
        )
    out: list[Chunk] = []
    while len(out) < total:
        path = chunk_path(run_dir, len(out))
        if not path.exists():
            break
        out += _load(path, fingerprint)
    if len(out) > total:
        raise ValueError(f"{run_dir} holds more chunks than this job; {_FIX}")
    return out
