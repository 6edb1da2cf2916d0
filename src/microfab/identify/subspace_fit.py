"""B, D and initial states by least squares on the data; simulation and error moments.

The passes over the records that follow the decomposition of `identify/subspace.py`,
each a chunk (or a sample) at a time, so that nothing grows with the number of samples:

* `fit_bdx0`: B, D (optional) and each run's x0 by linear least squares for given A, C.
  The regressors of output j, ``(A^T)^k c_j`` (x0) and ``eta^{jc}_k`` with
  ``eta^{jc}_{k+1} = A^T eta^{jc}_k + c_j u_c(k)`` (column c of B), are simulated by a numba
  kernel a chunk at a time (``p n (m + 1)`` states, ``p n^2 (m + 1)`` multiply-adds a
  sample) and folded into an incremental QR (`RAccumulator`). Each run's
  x0 is eliminated by its own R before the runs are joined, so runs never share a state.
* `simulate_ss`: the discrete model's output (numba), `error_moments`: mean and standard
  deviation per output of ``y - y_model`` without storing ``y_model``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numba import njit

from microfab.identify.subspace_data import IORun, RAccumulator

__all__ = ["BDX0", "error_moments", "fit_bdx0", "simulate_ss"]


@njit(cache=True)
def _regressors(
    at: np.ndarray,
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

    In the transposed form: for output j, ``zeta^j_k = (A^T)^k c_j`` multiplies x0 and
    ``eta^{jc}_{k+1} = A^T eta^{jc}_k + c_j u_c(k)`` multiplies column c of B (``y_{k,j}
    = zeta^j_k . x0 + sum_c eta^{jc}_k . B[:, c] + D[j] u_k``). ``state`` (p, n (m + 1))
    holds ``[zeta^j, eta^{j1}, ..., eta^{jm}]`` per row j on entry (``[c_j, 0, ..., 0]``
    at a run's start) and is advanced past the chunk; ``at`` is ``A^T``. Row
    ``(k - k0) p + j`` of ``out`` (Fortran-ordered) is ``[zeta^j_k (if with_x0),
    eta^{j1}_k, ..., eta^{jm}_k, u_k / su in D's row j (if with_d), y_{k,j} / sy_j]``.
    ``u``, ``y`` are divided by ``su``, ``sy`` on the fly.
    """
    n = at.shape[0]
    p = state.shape[0]
    m = u.shape[1]
    rows = out.shape[0] // p
    tmp = np.empty(n)
    nx = n if with_x0 else 0
    ncol = out.shape[1]
    for kk in range(rows):
        k = k0 + kk
        for j in range(p):
            row = kk * p + j
            sj = state[j]
            if with_x0:
                for q in range(n):
                    out[row, q] = sj[q]
            for q in range(n * m):
                out[row, nx + q] = sj[n + q]
            if with_d:
                for q in range(p * m):
                    out[row, nx + n * m + q] = 0.0
                for ch in range(m):
                    out[row, nx + n * m + j * m + ch] = u[k, ch] / su[ch]
            out[row, ncol - 1] = y[k, j] / sy[j]
            # advance every block of row j by A^T; eta^{jc} also takes c_j u_c(k)
            for blk in range(m + 1):
                v = sj[blk * n : (blk + 1) * n]
                for r in range(n):
                    acc = 0.0
                    for t in range(n):
                        acc += at[r, t] * v[t]
                    tmp[r] = acc
                if blk == 0:
                    for r in range(n):
                        v[r] = tmp[r]
                else:
                    uk = u[k, blk - 1] / su[blk - 1]
                    for r in range(n):
                        v[r] = tmp[r] + c[j, r] * uk


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
    at, c, su, sy = _f64(a.T, c, u_scale, y_scale)
    joint = RAccumulator(nth + 1)
    x0_parts: list[np.ndarray] = []
    rows_per_chunk = max(1, chunk_samples // p)
    for run in runs:
        acc = RAccumulator(nx + nth + 1) if estimate_x0 else joint
        state = np.zeros((p, n * (m + 1)))
        state[:, :n] = c
        buf = np.empty((rows_per_chunk * p, nx + nth + 1), order="F")
        for k0 in range(0, run.n_samples, rows_per_chunk):
            rows = min(rows_per_chunk, run.n_samples - k0)
            out = buf if rows == rows_per_chunk else np.empty((rows * p, buf.shape[1]), order="F")
            _regressors(at, c, run.u, run.y, k0, su, sy, state, estimate_x0, feedthrough, out)
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


@njit(cache=True, inline="always")
def _output(c: np.ndarray, d: np.ndarray, x: np.ndarray, u_k: np.ndarray, j: int) -> float:
    """``(C x + D u_k)[j]``."""
    s = 0.0
    for r in range(c.shape[1]):
        s += c[j, r] * x[r]
    for q in range(d.shape[1]):
        s += d[j, q] * u_k[q]
    return s


@njit(cache=True, inline="always")
def _advance(a: np.ndarray, b: np.ndarray, x: np.ndarray, u_k: np.ndarray, tmp: np.ndarray) -> None:
    """``x <- A x + B u_k`` in place (``tmp``: scratch of length n)."""
    n = a.shape[0]
    for r in range(n):
        s = 0.0
        for t in range(n):
            s += a[r, t] * x[t]
        for q in range(b.shape[1]):
            s += b[r, q] * u_k[q]
        tmp[r] = s
    for r in range(n):
        x[r] = tmp[r]


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
    tmp = np.empty(a.shape[0])
    for k in range(u.shape[0]):
        for j in range(c.shape[0]):
            out[k, j] = _output(c, d, x, u[k], j)
        _advance(a, b, x, u[k], tmp)


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
    tmp = np.empty(a.shape[0])
    for k in range(u.shape[0]):
        for j in range(c.shape[0]):
            e = y[k, j] - _output(c, d, x, u[k], j)
            sums[0, j] += e
            sums[1, j] += e * e
        _advance(a, b, x, u[k], tmp)


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
