"""Stage 2's state between runs (`microfab.optimize.stage2`): checkpoint and best iterate.

`fingerprint` keys a checkpoint by the problem's inputs; `save_iterate` / `load_state`
write and read the iterate, the trust radius, the iteration count, the history (merit,
cost, feasibility score per accepted iterate) and the least violating iterate so far
(`Best`) through `microfab.io.checkpoint`, so that a resumed run returns what an
uninterrupted one would.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.io.checkpoint import read_state, save_state

__all__ = ["Best", "fingerprint", "load_state", "save_iterate"]


def fingerprint(target: np.ndarray, r_init: np.ndarray, rest: np.ndarray, extra: dict) -> str:
    """SHA-256 of the inputs of a stage-2 problem (checkpoint key)."""
    h = hashlib.sha256()
    for a in (target, r_init, rest):
        arr = np.ascontiguousarray(a, dtype=np.float64)
        h.update(repr(arr.shape).encode())
        h.update(arr.tobytes())
    h.update(repr(sorted(extra.items())).encode())
    return h.hexdigest()


@dataclass(frozen=True, eq=False)
class Best:
    """The least violating accepted iterate so far (`Stage2Result.returned`)."""

    score: float  # `Feasibility.score` of its prediction
    merit: float
    cost: float
    r: np.ndarray  # (2M,), µm
    index: int  # in the history

    @staticmethod
    def better(old: Best | None, score: float, merit: float, cost: float, r: np.ndarray,
               index: int) -> Best:  # fmt: skip
        """``old``, or the new iterate when it violates less (on a tie: the lower merit)."""
        if old is None or score < old.score or (score == old.score and merit <= old.merit):
            return Best(float(score), float(merit), float(cost), np.array(r, dtype=float),
                         int(index))  # fmt: skip
        return old


#: The stage-2 checkpoint as `microfab.io.checkpoint` knows it (format 2: the run store's
#: state file, every setting named; format 1 kept one digest of everything). Since issue
#: 43 it also holds the least violating iterate (``best_r`` and ``best`` in the metadata);
#: a file without them resumes with the resumed iterate as the least violating so far.
_KIND, _VERSION = "stage-2 iterate", 2


def load_state(
    path: str | None, key: dict[str, Any]
) -> tuple[np.ndarray, float, int, list, int | None, Best | None] | None:
    """The saved ``(r, trust, iteration, history, band, best)``, or None.

    None without ``path`` or a file there; a file of other settings, or an unreadable
    one, is refused (ValueError naming it).
    """
    if path is None:
        return None
    saved = read_state(path, kind=_KIND, versions=(_VERSION,), settings=key,
                       fix="remove it, or rerun with --fresh, to start afresh")  # fmt: skip
    if saved is None:
        return None
    z, meta = saved.arrays, saved.meta
    try:
        # (merit, cost, score); files written before issue 43 hold no score: NaN
        hist = [(*row, *[math.nan] * (3 - len(row))) for row in z["history"].tolist()]
        band = meta["band"]
        b = meta.get("best")
        best = None if b is None or "best_r" not in z else Best(
            float(b["score"]), float(b["merit"]), float(b["cost"]), np.array(z["best_r"]),
            int(b["index"]))  # fmt: skip
        return (np.array(z["r"]), float(meta["trust"]), int(meta["iteration"]), hist,
                None if band is None else int(band), best)  # fmt: skip
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: an incomplete stage-2 checkpoint ({exc}); remove it") from None


def save_iterate(
    path: str | None, key: dict[str, Any], r: np.ndarray, trust: float, it: int, hist: list,
    band: int | None, best: Best | None,
) -> None:  # fmt: skip
    """Write the state atomically (nothing without ``path``); `load_state` reads it."""
    if path is None:
        return
    arrays = {"r": r, "history": np.array(hist, dtype=float)}
    meta: dict[str, Any] = {"trust": float(trust), "iteration": int(it), "band": band}
    if best is not None:
        arrays["best_r"] = best.r
        meta["best"] = {"score": best.score, "merit": best.merit, "cost": best.cost,
                        "index": best.index}  # fmt: skip
    save_state(path, kind=_KIND, version=_VERSION, settings=key, arrays=arrays,
               meta=meta)  # fmt: skip
