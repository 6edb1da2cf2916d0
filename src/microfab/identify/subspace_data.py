"""Chunked data passes of the subspace identification: the Hankel R factor, B/D/x0, errors.

`identify/subspace.py` works on small matrices only; every pass over the (possibly
6e6-sample) records is here, and none of them holds more than one chunk of rows:

* `hankel_factor`: the R factor of the QR decomposition of the block-Hankel data matrix
  ``H^T`` whose row for time ``k`` is ``[u_{k+i..k+2i-1}, u_{k..k+i-1}, y_{k..k+i-1},
  y_{k+i..k+2i-1}]`` (``U_f, U_p, Y_p, Y_f``; ``i`` block rows, each block time-major then
  channel), i.e. ``L = R^T`` of the LQ decomposition of ``[U_f; U_p; Y_p; Y_f]``. Rows are
  built ``chunk_samples`` at a time and folded into ``R`` by LAPACK ``dtpqrt`` (QR of ``R``
  stacked on the chunk: Householder, so the accuracy of a QR of the whole matrix, with no
  Gram matrix and its squared condition number). Hankel rows never straddle two runs.
* `RAccumulator`: that incremental QR, also used for the least squares of B, D and x0.
* `fit_bdx0`: B, D (optional) and each run's x0 by linear least squares on the data, for
  given A, C: the regressors ``C A^k`` (x0) and ``C Xi_k`` (B; ``Xi`` the state response to
  each input with ``B = I``) are simulated by a numba kernel a chunk at a time. Each run's
  x0 is eliminated by its own R before the runs are joined.
* `simulate_ss`, `error_moments`: simulation and per-output error sums (for mean and
  standard deviation) without storing the simulated output.

BLAS/LAPACK run on one thread (`microfab.core.threads.one_blas_thread`): a thread team
gains nothing on a 2-core machine for these tall-skinny factorisations (on a busy one it
made a QR 15x slower), and the result then does not depend on the core count.

Memory: the records themselves, plus one chunk of Hankel rows (``chunk_samples x
2 i (m + p)`` floats: 21 MB at 16 384 samples, 20 block rows, 2 in / 2 out) and the R
factor; nothing grows with the number of samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.linalg.lapack as lapack
from numba import njit

from microfab.core.arrays import readonly
from microfab.core.threads import one_blas_thread

__all__ = [
    "HankelFactor",
    "IORun",
    "RAccumulator",
    "check_runs",
    "error_moments",
    "fit_bdx0",
    "hankel_factor",
    "simulate_ss",
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

    def input_rank_ratio(self) -> float:
        """Smallest over largest singular value of the inputs' part ``[U_f; U_p]`` of R."""
        k = 2 * self.block_rows * self.n_inputs
        s = np.linalg.svd(self.r[:k, :k], compute_uv=False)
        return float(s[-1] / s[0]) if s[0] > 0.0 else 0.0


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


@njit(cache=True)
def _regressors(
    a: np.ndarray,
    c: np.ndarray,
    u: np.ndarray,
    y: np.ndarray,
    k0: int,
    su: np.ndarray,
    sy: np.ndarray,
    state: np.ndarray,
    with_x0: bool,
    with_d: bool,
    out: np.ndarray,
) -> None:
    """Least-squares rows of samples k0 .. k0 + out.shape[0] / p - 1 into ``out``.

    ``u``, ``y`` are divided by ``su``, ``sy`` on the fly (no scaled copy of a run).

    ``state`` (n, n (m + 1)) holds ``[A^k, Xi^1_k, ..., Xi^m_k]`` on entry and is advanced
    past the chunk; ``Xi^c_{k+1} = A Xi^c_k + I u_c(k)``. Row ``(k - k0) p + j`` of ``out``
    (Fortran-ordered) is ``[(C A^k)_j (if with_x0), (C Xi^c_k)_{j r} for c, r,
    u_k in D's row j (if with_d), y_{k, j}]``.
    """
    n = a.shape[0]
    p = c.shape[0]
    m = u.shape[1]
    w = state.shape[1]
    rows = out.shape[0] // p
    tmp = np.empty(w)
    nx = n if with_x0 else 0
    ncol = out.shape[1]
    for kk in range(rows):
        k = k0 + kk
        for j in range(p):
            row = kk * p + j
            for q in range(ncol):
                out[row, q] = 0.0
            cj = c[j]
            if with_x0:
                for q in range(n):
                    s = 0.0
                    for r in range(n):
                        s += cj[r] * state[r, q]
                    out[row, q] = s
            for ch in range(m):
                base = n * (ch + 1)
                for q in range(n):
                    s = 0.0
                    for r in range(n):
                        s += cj[r] * state[r, base + q]
                    out[row, nx + ch * n + q] = s
            if with_d:
                for ch in range(m):
                    out[row, nx + n * m + j * m + ch] = u[k, ch] / su[ch]
            out[row, ncol - 1] = y[k, j] / sy[j]
        # advance: state <- A state + [0 | I u_1 | ... | I u_m]
        for q in range(w):
            for r in range(n):
                s = 0.0
                for t in range(n):
                    s += a[r, t] * state[t, q]
                tmp[r] = s
            for r in range(n):
                state[r, q] = tmp[r]
        for ch in range(m):
            base = n * (ch + 1)
            uk = u[k, ch] / su[ch]
            for r in range(n):
                state[r, base + r] += uk


@dataclass(frozen=True, eq=False)
class BDX0:
    """B, D and the runs' initial states fitted by least squares (scaled coordinates)."""

    b: np.ndarray
    d: np.ndarray
    x0: np.ndarray


def fit_bdx0(
    a: np.ndarray,
    c: np.ndarray,
    runs: Sequence[IORun],
    u_scale: np.ndarray,
    y_scale: np.ndarray,
    *,
    feedthrough: bool,
    estimate_x0: bool,
    chunk_samples: int,
) -> BDX0:
    """B, D and x0 by least squares on the (scaled) data for given A, C.

    Minimises ``sum_r sum_k |y_k - C A^k x0_r - sum_l C A^(k-1-l) B u_l - D u_k|^2`` over
    B, D (zero when ``feedthrough`` is False) and each run's ``x0_r`` (zero when
    ``estimate_x0`` is False).

    Returns
    -------
    BDX0
        ``b`` (n, m), ``d`` (p, m), ``x0`` (n_runs, n), in the scaled coordinates.

    Raises
    ------
    ValueError
        ``A`` unstable (the regressors would grow without bound), or the regression is
        singular (the data do not determine B, D and x0).
    """
    n = a.shape[0]
    p = c.shape[0]
    m = runs[0].u.shape[1]
    rho = float(np.max(np.abs(np.linalg.eigvals(a)))) if n else 0.0
    if rho >= 1.0:
        raise ValueError(
            f"the identified A is not stable (largest |eigenvalue| {rho:.6g} >= 1): B and D "
            "cannot be fitted by simulation; try another order or more block rows"
        )
    nth = n * m + (p * m if feedthrough else 0)
    nx = n if estimate_x0 else 0
    a, c, su, sy = _f64(a, c, u_scale, y_scale)
    joint = RAccumulator(nth + 1)
    x0_parts: list[np.ndarray] = []
    rows_per_chunk = max(1, chunk_samples // p)
    for run in runs:
        acc = RAccumulator(nx + nth + 1) if estimate_x0 else joint
        state = np.zeros((n, n * (m + 1)))
        state[:, :n] = np.eye(n)
        buf = np.empty((rows_per_chunk * p, nx + nth + 1), order="F")
        for k0 in range(0, run.n_samples, rows_per_chunk):
            rows = min(rows_per_chunk, run.n_samples - k0)
            out = buf if rows == rows_per_chunk else np.empty((rows * p, buf.shape[1]), order="F")
            _regressors(a, c, run.u, run.y, k0, su, sy, state, estimate_x0, feedthrough, out)
            acc.add(out)
        if estimate_x0:
            r = acc.r
            joint.add(np.array(r[nx:, nx:], order="F"))
            x0_parts.append(r[:nx, :])
    r = joint.r
    diag = np.abs(np.diag(r[:nth, :nth]))
    if nth and (diag.min() <= 1e-12 * diag.max()):
        raise ValueError(
            "the data do not determine B"
            + (" and D" if feedthrough else "")
            + ": the least-squares problem is singular (input not exciting enough)"
        )
    theta = scipy.linalg.solve_triangular(r[:nth, :nth], r[:nth, nth])
    b = theta[: n * m].reshape(m, n).T
    d = theta[n * m :].reshape(p, m) if feedthrough else np.zeros((p, m))
    x0 = np.zeros((len(runs), n))
    for q, rx in enumerate(x0_parts):
        x0[q] = scipy.linalg.solve_triangular(
            rx[:, :nx], rx[:, nx + nth] - rx[:, nx : nx + nth] @ theta
        )
    return BDX0(b=b, d=d, x0=x0)


@njit(cache=True)
def _simulate(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    d: np.ndarray,
    u: np.ndarray,
    x: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[k] = C x_k + D u_k``, ``x_{k+1} = A x_k + B u_k`` from ``x`` (advanced in place)."""
    n = a.shape[0]
    m = b.shape[1]
    p = c.shape[0]
    tmp = np.empty(n)
    for k in range(u.shape[0]):
        for j in range(p):
            s = 0.0
            for r in range(n):
                s += c[j, r] * x[r]
            for q in range(m):
                s += d[j, q] * u[k, q]
            out[k, j] = s
        for r in range(n):
            s = 0.0
            for t in range(n):
                s += a[r, t] * x[t]
            for q in range(m):
                s += b[r, q] * u[k, q]
            tmp[r] = s
        for r in range(n):
            x[r] = tmp[r]


@njit(cache=True)
def _error_sums(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    d: np.ndarray,
    u: np.ndarray,
    y: np.ndarray,
    x: np.ndarray,
    sums: np.ndarray,
) -> None:
    """Add ``sum e`` and ``sum e^2`` per output (``e = y - y_model``) to ``sums`` (2, p)."""
    n = a.shape[0]
    m = b.shape[1]
    p = c.shape[0]
    tmp = np.empty(n)
    for k in range(u.shape[0]):
        for j in range(p):
            s = 0.0
            for r in range(n):
                s += c[j, r] * x[r]
            for q in range(m):
                s += d[j, q] * u[k, q]
            e = y[k, j] - s
            sums[0, j] += e
            sums[1, j] += e * e
        for r in range(n):
            s = 0.0
            for t in range(n):
                s += a[r, t] * x[t]
            for q in range(m):
                s += b[r, q] * u[k, q]
            tmp[r] = s
        for r in range(n):
            x[r] = tmp[r]


def _f64(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(np.ascontiguousarray(x, dtype=np.float64) for x in arrays)


def simulate_ss(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, u: np.ndarray, x0: np.ndarray
) -> np.ndarray:
    """Output (N, p) of the discrete state-space model driven by ``u`` (N, m) from ``x0``."""
    a, b, c, d, u = _f64(a, b, c, d, u)
    out = np.empty((u.shape[0], c.shape[0]))
    _simulate(a, b, c, d, u, np.array(x0, dtype=np.float64), out)
    return out


def error_moments(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    d: np.ndarray,
    runs: Sequence[IORun],
    x0: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation per output of ``y - y_model`` over all runs.

    Parameters
    ----------
    a, b, c, d : numpy.ndarray
        The discrete model (unscaled units).
    runs : sequence of IORun
        Records.
    x0 : numpy.ndarray
        Initial state of each run, shape (n_runs, n).

    Returns
    -------
    mean, std : numpy.ndarray
        Shapes (p,), output units; ``std`` about the mean (population, ``ddof = 0``).
    """
    a, b, c, d = _f64(a, b, c, d)
    sums = np.zeros((2, c.shape[0]))
    n = 0
    for run, x in zip(runs, x0, strict=True):
        _error_sums(a, b, c, d, run.u, run.y, np.array(x, dtype=np.float64), sums)
        n += run.n_samples
    mean = sums[0] / n
    var = np.maximum(sums[1] / n - mean**2, 0.0)
    return mean, np.sqrt(var)
