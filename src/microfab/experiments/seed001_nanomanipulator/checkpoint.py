"""Checkpoints of a seed 001 job: one atomic file per period-long chunk (`run.run_job`).

Each chunk file ``run/chunks/NNNNN.npz`` is a whole checkpoint: the chunk's signals, its
log points, and the loop state after it (plant, controller with its RBF weights and RC
memory, last command, gate state), stamped with the format version and the job's
fingerprint. One file per chunk means one write and one ``fsync`` per period; a file is
either complete (written to a temporary name, synced, renamed: `atomic_save_npz`) or
absent, so the run resumes after the last chunk whose file exists.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.atomic import atomic_save_npz
from microfab.sim.loop import LoopState

__all__ = ["Chunk", "chunk_path", "load_chunks", "save_chunk"]

#: Format of the chunk files (2: one file per chunk with the loop state in it; 1 kept a
#: separate ``run/state.npz``).
FORMAT_VERSION = 2
_OLD_STATE = "state.npz"  # format 1


@dataclass(frozen=True, kw_only=True, eq=False)
class Chunk:
    """One saved chunk: its signals and the loop state after it.

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
    loop : LoopState
        Plant, controller and last command after the chunk (no observer).
    gate : numpy.ndarray or None
        Laser gate state after the chunk (None outside a circle).
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
    loop: LoopState
    gate: np.ndarray | None = None
    final_circle: int | None = None
    final_controller: np.ndarray | None = None


def chunk_path(run_dir: Path, index: int) -> Path:
    """``run_dir/chunks/NNNNN.npz`` of chunk ``index``."""
    return run_dir / "chunks" / f"{index:05d}.npz"


def save_chunk(run_dir: Path, index: int, chunk: Chunk, fingerprint: str) -> None:
    """Write chunk ``index`` with the loop state after it, atomically (one file).

    Parameters
    ----------
    run_dir : pathlib.Path
        The run folder (``out/run``).
    index : int
        Chunk number, from 0.
    chunk : Chunk
        What to save.
    fingerprint : str
        `JobConfig.fingerprint` of the job.
    """
    arrays: dict[str, Any] = {
        "version": np.int64(FORMAT_VERSION),
        "fingerprint": np.array(fingerprint),
        "output": chunk.output,
        "measured": chunk.measured,
        "command": chunk.command,
        "laser": chunk.laser,
        "log_index": np.asarray(chunk.log_index, dtype=np.int64),
        "log_w": np.asarray(chunk.log_w, dtype=float).reshape(-1, 2),
        "log_s": np.asarray(chunk.log_s, dtype=float).reshape(-1, 2),
        "plant": chunk.loop.plant,
        "controller": chunk.loop.controller,
        "last_command": chunk.loop.command,
    }
    if chunk.gate is not None:
        arrays["gate"] = chunk.gate
    if chunk.final_circle is not None:
        assert chunk.final_controller is not None
        arrays["final_circle"] = np.int64(chunk.final_circle)
        arrays["final_controller"] = chunk.final_controller
    atomic_save_npz(chunk_path(run_dir, index), **arrays)


def _load(path: Path, fingerprint: str) -> Chunk:
    with np.load(path, allow_pickle=False) as z:
        version = int(z["version"]) if "version" in z else 1
        if version != FORMAT_VERSION:
            raise ValueError(
                f"{path}: saved run format {version}, this microfab reads "
                f"{FORMAT_VERSION}; remove {path.parent.parent} to start again"
            )
        if str(z["fingerprint"]) != fingerprint:
            raise ValueError(
                f"{path.parent.parent} holds a run of another job configuration; use "
                "another output folder, or remove it to start again"
            )
        final = "final_circle" in z
        return Chunk(
            output=z["output"],
            measured=z["measured"],
            command=z["command"],
            laser=z["laser"],
            log_index=z["log_index"],
            log_w=z["log_w"],
            log_s=z["log_s"],
            loop=LoopState(
                plant=z["plant"],
                controller=z["controller"],
                observer=np.zeros(0),
                command=z["last_command"],
            ),
            gate=z["gate"] if "gate" in z else None,
            final_circle=int(z["final_circle"]) if final else None,
            final_controller=z["final_controller"] if final else None,
        )


def load_chunks(run_dir: Path, fingerprint: str, total: int) -> list[Chunk]:
    """The saved chunks 0, 1, ... up to the first missing one (at most ``total``).

    Raises
    ------
    ValueError
        When a chunk file belongs to another job configuration or format (including the
        format-1 ``state.npz``); nothing is changed then.
    """
    if (run_dir / _OLD_STATE).exists():
        raise ValueError(
            f"{run_dir} holds a run saved in format 1 ({_OLD_STATE}); this microfab reads "
            f"format {FORMAT_VERSION}; remove {run_dir} to start again"
        )
    out: list[Chunk] = []
    for c in range(total):
        path = chunk_path(run_dir, c)
        if not path.exists():
            break
        out.append(_load(path, fingerprint))
    return out
