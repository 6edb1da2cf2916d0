"""What identifies a data set of recorded runs for the seed 002 networks.

`data_digest` (the SHA-256 of the runs' bytes: the same bytes or not) and `data_summary`
with `summary_deviation` (per-column statistics and samples that two data sets can be
compared by to a tolerance, since simulated bytes differ at the last bits between
machines), over runs of the type `Run`. Kept apart from the windowing of
`microfab.identify.ann_data`, which re-exports these names.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["SUMMARY_POINTS", "Run", "data_digest", "data_summary", "summary_deviation"]

Run = tuple[np.ndarray, np.ndarray]


def data_digest(runs: Sequence[Run]) -> str:
    """SHA-256 of the runs (shapes and float64 bytes, in order), hex."""
    h = hashlib.sha256()
    for command, measured in runs:
        for a in (command, measured):
            arr = np.ascontiguousarray(a, dtype=np.float64)
            h.update(repr(arr.shape).encode())
            h.update(arr.tobytes())
    return h.hexdigest()


#: Samples of each run's signals kept by `data_summary` (evenly spaced, ends included).
SUMMARY_POINTS = 9


def data_summary(runs: Sequence[Run]) -> dict[str, Any]:
    """A summary of runs that can be compared with a tolerance (unlike `data_digest`).

    The bytes of data made by a simulation depend on the CPU's BLAS kernels and thread
    count at the last bits; `data_digest` therefore only tells whether two data sets are
    the same bytes. This summary tells whether they are the same data to a tolerance:
    per run and per column of the command and the measured position, the mean, the RMS
    and `SUMMARY_POINTS` samples evenly spaced over the run.

    Parameters
    ----------
    runs : sequence of (command, measured)
        Each a float array (n, 2), m, as `train_ann` reads them.

    Returns
    -------
    dict
        ``"samples"``: the runs' lengths (integers); ``"command"`` and ``"measured"``:
        nested lists (runs, 2 columns, 2 + `SUMMARY_POINTS` values), m: mean, RMS, then
        the samples. JSON-ready.
    """
    out: dict[str, Any] = {"samples": [], "command": [], "measured": []}
    for command, measured in runs:
        out["samples"].append(int(np.shape(command)[0]))
        for name, a in (("command", command), ("measured", measured)):
            arr = np.asarray(a, dtype=np.float64).reshape(len(a), -1)
            idx = np.linspace(0, len(arr) - 1, SUMMARY_POINTS).round().astype(int)
            stats = np.vstack([arr.mean(axis=0), np.sqrt((arr**2).mean(axis=0)), arr[idx]])
            out[name].append(stats.T.tolist())
    return out


def summary_deviation(got: dict[str, Any], want: dict[str, Any]) -> float:
    """Largest difference between two `data_summary` results, relative to the data's scale.

    Every value's difference is divided by the RMS over all runs of that signal's column
    in ``want`` (so a deviation of 1e-9 is a nanometre on a metre-sized signal's scale).

    Raises
    ------
    ValueError
        When the two summaries are of different run counts, run lengths or columns: the
        data are not the same data at all (infinite deviation would hide which).
    """
    if got["samples"] != want["samples"]:
        raise ValueError(
            f"the runs differ in count or length: {len(got['samples'])} runs "
            f"{got['samples'][:4]}... against {len(want['samples'])} runs {want['samples'][:4]}..."
        )
    worst = 0.0
    for name in ("command", "measured"):
        g, w = np.asarray(got[name], dtype=float), np.asarray(want[name], dtype=float)
        if g.shape != w.shape:
            raise ValueError(f"{name}: summary shapes {g.shape} and {w.shape} differ")
        scale = np.sqrt(np.mean(w[:, :, 1] ** 2, axis=0))  # RMS over runs, per column
        scale = np.where(scale > 0, scale, 1.0)
        worst = max(worst, float(np.max(np.abs(g - w) / scale[None, :, None])))
    return worst
