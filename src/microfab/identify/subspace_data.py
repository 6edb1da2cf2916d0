"""Records and the chunked R factor of their block-Hankel matrix (subspace identification).

`identify/subspace.py` works on small matrices only; the passes over the (possibly
6e6-sample) records are here and in `identify/subspace_fit.py`, and none holds more than
one chunk of rows:

* `hankel_factor`: the R factor of the QR decomposition of the block-Hankel data matrix
  ``H^T`` whose row for time ``k`` is ``[u_{k+i..k+2i-1}, u_{k..k+i-1}, y_{k..k+i-1},
  y_{k+i..k+2i-1}]`` (``U_f, U_p, Y_p, Y_f``; ``i`` block rows, each block time-major then
  channel), i.e. ``L = R^T`` of the LQ decomposition of ``[U_f; U_p; Y_p; Y_f]``. Rows are
  built ``chunk_samples`` at a time and folded into ``R`` by LAPACK ``dtpqrt`` (QR of ``R``
  stacked on the chunk: Householder, so the accuracy of a QR of the whole matrix, with no
  Gram matrix and its squared condition number). Hankel rows never straddle two runs.
* `RAccumulator`: that incremental QR, also used for the least squares of B, D and x0.
* `check_runs`: one or several records (`IORun`) as float64 arrays, checked.

BLAS/LAPACK run on one thread each (`microfab.core.threads.one_blas_thread`): an OpenBLAS
thread team on these tall-skinny factorisations made them 15x slower on the busy 2-core
machine. Instead ``workers`` threads (default 2) each fold a contiguous share of the chunks
into their own R (``dtpqrt`` and the numba fill release the GIL) and the Rs are folded in
order: the answer depends on ``workers`` in its rounding, not on the core count.

Cost: about ``2 N (2 i (m + p))^2`` flops, 6.5 s for 6e6 samples, 10 block rows, 2 in /
2 out on one core of the project machine (22 s at 20 block rows). Memory: the records
themselves, plus per worker one chunk of Hankel rows (``chunk_samples x 2 i (m + p)``
floats: 5 MB at the default 8192 samples, 10 block rows, 2 in / 2 out) and its R; nothing
grows with the number of samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg.lapack as lapack
from numba import njit

from microfab.core.arrays import readonly
from microfab.core.threads import one_blas_thread

__all__ = [
    "HankelFactor",
    "IORun",
    "RAccumulator",
    "channel_rms",
    "check_runs",
    "hankel_factor",
]

_NB = 16  # dtpqrt block size: fastest of 16/32/64 for 80-160 columns on the 2-core machine


@dataclass(frozen=True, eq=False)
class IORun:
    """One record: input and output samples at a common sample time, from its start.

    Parameters
    ----------
    u : numpy.ndarray
        Inputs, shape (N, m) (a 1-D array is one channel), any unit.
    y : numpy.ndarray
        Outputs, shape (N, p), any unit.
    """

    u: np.ndarray
    y: np.ndarray

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.u.shape[0])


def _as_2d(name: str, a: Any, run: int) -> np.ndarray:
    """``a`` as a C-contiguous float64 (N, channels) array (a copy only where needed)."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] < 1:
        raise ValueError(
            f"run {run}: {name} must have shape (n_samples, n_channels), got {arr.shape}"
        )
    return np.ascontiguousarray(arr)


def check_runs(runs: Any, min_samples: int) -> list[IORun]:
    """Check one or several records and return them as `IORun`s of float64 arrays.

    Parameters
    ----------
    runs : IORun, (u, y) pair, or a sequence of those
        One record or several. Hankel blocks are never formed across two records.
    min_samples : int
        Fewest samples a record must have (``2 i`` plus one for ``i`` block rows).

    Returns
    -------
    list of IORun

    Raises
    ------
    ValueError
        No record; u and y of different lengths; channel counts differing between
        records; a record shorter than ``min_samples``; a NaN or infinite sample.
    """
    if isinstance(runs, IORun):
        items: Sequence[Any] = [runs]
    elif (
        isinstance(runs, tuple) and len(runs) == 2 and all(isinstance(a, np.ndarray) for a in runs)
    ):
        items = [runs]
    else:
        items = list(runs)
    if not items:
        raise ValueError("no record given: pass one (u, y) pair or a list of them")
    out: list[IORun] = []
    for r, item in enumerate(items):
        u_raw, y_raw = (item.u, item.y) if isinstance(item, IORun) else item
        u = _as_2d("u", u_raw, r)
        y = _as_2d("y", y_raw, r)
        if u.shape[0] != y.shape[0]:
            raise ValueError(
                f"run {r}: u has {u.shape[0]} samples but y has {y.shape[0]}; "
                "they must be sampled together"
            )
        if out and (u.shape[1], y.shape[1]) != (out[0].u.shape[1], out[0].y.shape[1]):
            raise ValueError(
                f"run {r}: {u.shape[1]} inputs and {y.shape[1]} outputs, but run 0 has "
                f"{out[0].u.shape[1]} and {out[0].y.shape[1]}"
            )
        if u.shape[0] < min_samples:
            raise ValueError(
                f"run {r} has {u.shape[0]} samples; at least {min_samples} are needed "
                "(2 x block_rows + 1): use fewer block rows or a longer run"
            )
        for name, a in (("u", u), ("y", y)):
            bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
            if bad.size:
                raise ValueError(
                    f"run {r}: {name} is not finite at sample {int(bad[0])} ({a[bad[0]].tolist()})"
                )
        out.append(IORun(u, y))
    return out


class RAccumulator:
    """The R factor of ``QR([rows_1; rows_2; ...])``, folded in chunk by chunk.

    Each `add` factors ``[R; rows]`` with LAPACK ``dtpqrt`` (Householder on the
    triangle-over-rectangle pair), so ``R^T R`` equals the Gram matrix of all rows added
    so far with the backward error of a single QR. Memory: ``R`` only.

    Parameters
    ----------
    n_columns : int
        Number of columns of the rows.
    """

    def __init__(self, n_columns: int) -> None:
        self.n_columns = int(n_columns)
        self._r = np.zeros((self.n_columns, self.n_columns), order="F")
        self.n_rows = 0

    def add(self, rows: np.ndarray) -> None:
        """Fold ``rows`` (shape (k, n_columns); overwritten) into R."""
        if rows.shape[0] == 0:
            return
        b = np.asfortranarray(rows)
        nb = max(1, min(_NB, self.n_columns, b.shape[0]))
        with one_blas_thread():
            a, _, _, info = lapack.dtpqrt(0, nb, self._r, b, overwrite_a=1, overwrite_b=1)
        if info != 0:  # pragma: no cover - LAPACK argument error
            raise RuntimeError(f"dtpqrt failed with info = {info}")
        if a is not self._r:  # pragma: no cover - f2py made a copy
            self._r = np.asfortranarray(a)
        self.n_rows += rows.shape[0]

    def add_r(self, r: np.ndarray) -> None:
        """Fold another accumulator's R (upper triangular) into this one."""
        self.add(np.array(r, order="F"))

    @property
    def r(self) -> np.ndarray:
        """R (upper triangular, nonnegative diagonal), a copy."""
        r = np.triu(self._r)
        sign = np.where(np.diag(r) < 0.0, -1.0, 1.0)
        return r * sign[:, None]


@njit(cache=True, nogil=True)
def _fill_hankel(
    u: np.ndarray, y: np.ndarray, k0: int, su: np.ndarray, sy: np.ndarray, i: int, out: np.ndarray
) -> None:
    """Rows k0 .. k0 + out.shape[0] - 1 of ``H^T`` ([U_f U_p Y_p Y_f], scaled) into ``out``.

    ``out`` is Fortran-ordered (rows, 2 i (m + p)): each column is written contiguously.
    """
    rows = out.shape[0]
    m = u.shape[1]
    p = y.shape[1]
    for t in range(i):
        for a in range(m):
            inv = 1.0 / su[a]
            col_f = out[:, t * m + a]
            col_p = out[:, i * m + t * m + a]
            for r in range(rows):
                col_f[r] = u[k0 + r + i + t, a] * inv
                col_p[r] = u[k0 + r + t, a] * inv
        for b in range(p):
            inv = 1.0 / sy[b]
            col_p = out[:, 2 * i * m + t * p + b]
            col_f = out[:, 2 * i * m + i * p + t * p + b]
            for r in range(rows):
                col_p[r] = y[k0 + r + t, b] * inv
                col_f[r] = y[k0 + r + i + t, b] * inv


@dataclass(frozen=True, eq=False)
class HankelFactor:
    """The R factor of the scaled block-Hankel data matrix and what it was built from.

    Attributes
    ----------
    r : numpy.ndarray
        Upper triangular, shape (2 i (m + p), 2 i (m + p)); columns in the order
        ``U_f, U_p, Y_p, Y_f``. ``r.T`` is the L of the LQ decomposition of
        ``[U_f; U_p; Y_p; Y_f] / sqrt(n_columns)`` (divided so that it does not grow with N).
    block_rows : int
        ``i``.
    n_inputs, n_outputs : int
        ``m``, ``p``.
    n_columns : int
        Hankel columns over all runs, ``sum(N_r - 2 i + 1)``.
    u_scale, y_scale : numpy.ndarray
        Per-channel RMS over all runs that the data were divided by, shapes (m,), (p,).
    """

    r: np.ndarray
    block_rows: int
    n_inputs: int
    n_outputs: int
    n_columns: int
    u_scale: np.ndarray
    y_scale: np.ndarray

    def input_rank(self, rtol: float) -> int:
        """Numerical rank of the inputs' block-Hankel matrix ``[U_f; U_p]`` (of ``2 i m``).

        Singular values of its part of R above ``rtol`` times the largest are counted.
        """
        k = 2 * self.block_rows * self.n_inputs
        s = np.linalg.svd(self.r[:k, :k], compute_uv=False)
        return int(np.count_nonzero(s > rtol * s[0])) if s[0] > 0.0 else 0


def channel_rms(runs: Sequence[IORun]) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel RMS of u and y over all runs, shapes (m,), (p,)."""
    su = np.zeros(runs[0].u.shape[1])
    sy = np.zeros(runs[0].y.shape[1])
    n = 0
    for run in runs:
        su += np.einsum("ij,ij->j", run.u, run.u)
        sy += np.einsum("ij,ij->j", run.y, run.y)
        n += run.n_samples
    return np.sqrt(su / n), np.sqrt(sy / n)


def _split(items: list[Any], n: int) -> list[list[Any]]:
    """``items`` in ``n`` contiguous groups of near-equal length (the last ones shorter)."""
    size = -(-len(items) // n)
    return [items[g * size : (g + 1) * size] for g in range(n) if items[g * size : (g + 1) * size]]


def hankel_factor(
    runs: Sequence[IORun],
    block_rows: int,
    *,
    chunk_samples: int,
    scale: bool = True,
    workers: int = 2,
) -> HankelFactor:
    """R factor of the block-Hankel data matrix of all runs, by chunks of rows.

    Parameters
    ----------
    runs : sequence of IORun
        Checked records (`check_runs`).
    block_rows : int
        ``i``, block rows of the past and of the future.
    chunk_samples : int
        Hankel rows built and folded at a time (memory ``chunk_samples x 2 i (m + p)``
        floats).
    scale : bool
        Divide each channel by its RMS over all runs first (else by 1).
    workers : int
        Threads, each folding a contiguous share of the chunks into its own R (LAPACK and
        the fill kernel release the GIL); their Rs are then folded in order. The result
        depends on this number (in its rounding) but not on the machine's core count.

    Returns
    -------
    HankelFactor

    Raises
    ------
    ValueError
        A channel that is zero throughout (nothing to identify from).
    """
    i = int(block_rows)
    m = runs[0].u.shape[1]
    p = runs[0].y.shape[1]
    if scale:
        su, sy = channel_rms(runs)
    else:
        su, sy = np.ones(m), np.ones(p)
    for name, s in (("input", su), ("output", sy)):
        zero = np.flatnonzero(s == 0.0)
        if zero.size:
            raise ValueError(
                f"{name} channel {int(zero[0])} is zero in every run: the data cannot "
                "identify anything through it"
            )
    ncol = 2 * i * (m + p)
    # (run, first Hankel row, rows) of every chunk, split into `workers` contiguous groups
    chunks = [
        (q, k0, min(chunk_samples, run.n_samples - 2 * i + 1 - k0))
        for q, run in enumerate(runs)
        for k0 in range(0, run.n_samples - 2 * i + 1, chunk_samples)
    ]
    total = sum(rows for _, _, rows in chunks)
    groups = _split(chunks, max(1, min(workers, len(chunks))))

    def work(group: list[tuple[int, int, int]]) -> RAccumulator:
        acc = RAccumulator(ncol)
        buf = np.empty((chunk_samples, ncol), order="F")
        for q, k0, rows in group:
            out = buf if rows == chunk_samples else np.empty((rows, ncol), order="F")
            _fill_hankel(runs[q].u, runs[q].y, k0, su, sy, i, out)
            acc.add(out)
        return acc

    with one_blas_thread():
        if len(groups) == 1:
            accs = [work(groups[0])]
        else:
            with ThreadPoolExecutor(max_workers=len(groups)) as pool:
                accs = list(pool.map(work, groups))
        acc = accs[0]
        for other in accs[1:]:
            acc.add_r(other.r)
    return HankelFactor(
        r=readonly(acc.r / np.sqrt(total)),
        block_rows=i,
        n_inputs=m,
        n_outputs=p,
        n_columns=total,
        u_scale=readonly(su),
        y_scale=readonly(sy),
    )
