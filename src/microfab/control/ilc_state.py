"""The schema of a saved learning state (``ilc_state.npz`` of `microfab.control.ilc`).

`checked_state` checks what `microfab.io.checkpoint.read_state` returns for an ILC state
(its metadata and arrays) against each other before `FrequencyILC.load` builds a learner
from them, so that a state that does not hold what ``FrequencyILC.save`` writes is
refused on one line (naming the file and the field) before anything is learned or
written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.schema import SchemaError, check_array

__all__ = ["checked_state"]


def checked_state(
    path: Path, meta: dict[str, object], data: dict[str, np.ndarray]
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The saved metadata and arrays of an ILC state, checked against each other.

    Types, shapes (``N`` samples of the reference, ``A`` axes, ``B = N // 2 + 1`` rfft
    bins, ``i`` trials learned), dtypes, finiteness and ranges, so that a state that
    does not hold what `save` writes is refused before anything is learned or written.

    Raises
    ------
    SchemaError
        The first field that does not hold what it must, named with the file.
    """
    w = str(path)
    missing = [k for k in ("dt", "axes", "config", "iteration") if k not in meta]
    needed = ("reference", "inputs", "pinv", "mask", "rms", "pp")
    missing += [k for k in needed if k not in data]
    if missing:
        raise SchemaError(f"{w}: an ILC state without {missing}")
    dt, axes, it, config = meta["dt"], meta["axes"], meta["iteration"], meta["config"]
    if isinstance(dt, bool) or not isinstance(dt, int | float) or not 0 < dt < np.inf:
        raise SchemaError(f"{w}: dt must be a positive number of seconds, got {dt!r}")
    if (
        not isinstance(axes, list)
        or not axes
        or not all(isinstance(a, str) and a for a in axes)
        or len(set(axes)) != len(axes)
    ):
        raise SchemaError(f"{w}: axes must be a list of distinct axis names, got {axes!r}")
    if isinstance(it, bool) or not isinstance(it, int) or it < 0:
        raise SchemaError(f"{w}: iteration must be an integer >= 0, got {it!r}")
    if not isinstance(config, dict):
        raise SchemaError(f"{w}: config must be a JSON object, got {config!r}")
    events = meta.get("events", [])
    if not isinstance(events, list) or not all(isinstance(e, str) for e in events):
        raise SchemaError(f"{w}: events must be a list of strings, got {events!r}")
    if not isinstance(meta.get("model", False), bool):
        raise SchemaError(f"{w}: model must be true or false, got {meta.get('model')!r}")
    a = len(axes)
    ref = check_array(w, "reference", data["reference"], shape=(None, a))
    n = ref.shape[0]
    if n < 8:
        raise SchemaError(f"{w}: reference must have at least 8 samples, got {n}")
    b = n // 2 + 1
    out = dict(data)
    out["reference"] = ref
    out["inputs"] = check_array(w, "inputs", data["inputs"], shape=(it + 1, n, a))
    out["rms"] = check_array(w, "rms", data["rms"], shape=(it, a), low=0.0)
    out["pp"] = check_array(w, "pp", data["pp"], shape=(it, a), low=0.0)
    learned = it > 0 or data["pinv"].size > 0  # before the first update: empty
    shape_b = (b, a) if learned else (0, 0)
    out["pinv"] = check_array(w, "pinv", data["pinv"], kind="c", shape=shape_b)
    out["mask"] = check_array(w, "mask", data["mask"], kind="b", shape=shape_b)
    if "gain" in data:  # format 3 on
        out["gain"] = check_array(w, "gain", data["gain"], shape=shape_b, low=0.0, high=2.0)
        for name in ("best_input", "best_rms", "recent_errors"):
            if name not in data:
                raise SchemaError(f"{w}: an ILC state with 'gain' but without {name!r}")
        if learned:
            out["best_input"] = check_array(w, "best_input", data["best_input"], shape=(n, a))
            out["best_rms"] = check_array(  # inf until a trial is best
                w, "best_rms", data["best_rms"], shape=(a,), finite=False, low=0.0
            )
            if np.isnan(out["best_rms"]).any():
                raise SchemaError(f"{w}: best_rms holds NaN")
        out["recent_errors"] = check_array(
            w, "recent_errors", data["recent_errors"], shape=(None, *shape_b), low=0.0
        )
        if out["recent_errors"].shape[0] > 3:
            raise SchemaError(f"{w}: recent_errors keeps at most 3 trials")
    if meta.get("model", False) or "model_frf" in data:
        if "model_frf" not in data:
            raise SchemaError(f"{w}: an ILC state of a given model without 'model_frf'")
        out["model_frf"] = check_array(w, "model_frf", data["model_frf"], kind="c", shape=(b, a))
    return dict(meta), out
