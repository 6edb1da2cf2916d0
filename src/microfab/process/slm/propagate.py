"""Exact propagation of a scanner axis model over RTC segments, in closed form.

The axis model is a SISO `microfab.plants.lti.DiscreteLTI` ``x[k+1] = A x[k] + B u[k]``,
``y = C x`` (set position -> measured position, bit), the same for ``x`` and ``y`` (the
state is ``X``, shape (nx, 2), one column per axis). A segment of a
`microfab.process.slm.timing.Timeline` moves the set position from ``p`` to ``q`` in ``n``
equal steps (``u_k = p + (k + 1) / n Δ``, ``Δ = q - p``) and holds ``q``. In deviation
coordinates ``X̃ = X - g q`` (``g = (I - A)⁻¹ B``: the state at rest under a unit input) the
held input vanishes and the ramp is ``ũ_k = -Δ (n - k - 1) / n``, so after ``k <= n`` ticks

``X̃_k = A^k X̃_0 - [(n - k) S_k + R_k] Δ / n``,  ``S_k = Σ_{j<k} A^j B``,
``R_k = Σ_{j<k} j A^j B``,

and ``h`` ticks into the hold ``X̃ = A^h X̃_n``. The tables ``A^k``, ``S_k``, ``R_k`` and
``C A^k`` are built once per model (`tables`); a segment then costs two small
matrix-vector products whatever its length, and the chain of segments is one pass
(`propagate`, numba) over the segments, not over the ticks.

**Settling** (the shortest delay): after a segment's motion the error of the calibrated
position ``e_m = C A^m X̃ / G(0)`` (``G(0) = C g``) must stay within a tolerance for all
``m >= h``. ``κ_m = max_{i >= m} |C A^i|`` bounds every later error by ``κ_m |X̃|_F``; the
first ``m`` where that bound is within the tolerance certifies the rest, and the samples
below it are scanned backwards for the last one outside (`settle_ticks`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numba import njit

from microfab.plants.lti import DiscreteLTI

__all__ = ["Propagation", "Tables", "propagate", "settle_ticks", "tables"]

_TAIL = 1e-13  # tables run until |A^N|_F is below this (the tail bound is then negligible)


@dataclass(frozen=True, eq=False)
class Tables:
    """Powers and sums of one SISO model up to ``N`` ticks (module doc).

    Attributes
    ----------
    P : numpy.ndarray
        ``A^k``, shape (N + 1, nx, nx).
    S, R, CP : numpy.ndarray
        ``S_k``, ``R_k`` and ``C A^k``, shape (N + 1, nx) each.
    kappa : numpy.ndarray
        ``max_{i >= k} |C A^i|`` (the tail beyond ``N`` bounded), shape (N + 1,).
    g : numpy.ndarray
        ``(I - A)⁻¹ B``, shape (nx,).
    gain : float
        Static gain ``C g``.
    """

    P: np.ndarray
    S: np.ndarray
    R: np.ndarray
    CP: np.ndarray
    kappa: np.ndarray
    g: np.ndarray
    gain: float

    @property
    def size(self) -> int:
        """``N``: the largest tick count the tables hold."""
        return int(self.P.shape[0] - 1)


@njit(cache=True)
def _build(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    P: np.ndarray,
    S: np.ndarray,
    R: np.ndarray,
    CP: np.ndarray,
) -> None:
    """Fill ``P[k] = A^k``, ``S``, ``R`` and ``CP[k] = C A^k`` for k = 0..N (in place)."""
    nx = A.shape[0]
    N = P.shape[0] - 1
    for i in range(nx):
        for j in range(nx):
            P[0, i, j] = 1.0 if i == j else 0.0
        S[0, i] = 0.0
        R[0, i] = 0.0
    for k in range(N + 1):
        for j in range(nx):
            acc = 0.0
            for i in range(nx):
                acc += C[i] * P[k, i, j]
            CP[k, j] = acc
        if k == N:
            break
        for i in range(nx):
            pb = 0.0
            for j in range(nx):
                pb += P[k, i, j] * B[j]
                acc = 0.0
                for m in range(nx):
                    acc += A[i, m] * P[k, m, j]
                P[k + 1, i, j] = acc
            S[k + 1, i] = S[k, i] + pb
            R[k + 1, i] = R[k, i] + k * pb


def _check_siso(model: DiscreteLTI) -> None:
    if model.n_inputs != 1 or model.n_outputs != 1:
        raise ValueError(
            f"the axis model must be SISO (set position -> position), got "
            f"{model.n_inputs} inputs and {model.n_outputs} outputs"
        )
    if np.any(model.D != 0):
        raise ValueError("the axis model must be strictly proper (D = 0)")
    if np.max(np.abs(model.poles()), initial=0.0) >= 1.0:
        raise ValueError("the axis model is not stable (a pole on or outside |z| = 1)")


@functools.lru_cache(maxsize=16)
def _tables(model: DiscreteLTI, N: int) -> Tables:
    A = np.ascontiguousarray(model.A)
    B = np.ascontiguousarray(model.B[:, 0])
    C = np.ascontiguousarray(model.C[0])
    nx = A.shape[0]
    P = np.empty((N + 1, nx, nx))
    S = np.empty((N + 1, nx))
    R = np.empty((N + 1, nx))
    CP = np.empty((N + 1, nx))
    _build(A, B, C, P, S, R, CP)
    g = np.linalg.solve(np.eye(nx) - A, B)
    gain = float(C @ g)
    if gain == 0.0:
        raise ValueError("the axis model has zero static gain: no set position is reached")
    cn = np.linalg.norm(CP, axis=1)
    pf = np.linalg.norm(P.reshape(N + 1, -1), axis=1)
    # beyond N: |C A^i| <= |C| max_k |A^k|_F |A^N|_F (valid while |A^N|_F <= 1)
    tail = float(np.linalg.norm(C) * pf.max() * pf[-1])
    kappa = np.maximum(np.maximum.accumulate(cn[::-1])[::-1], tail)
    for a in (P, S, R, CP, kappa, g):
        a.setflags(write=False)
    return Tables(P, S, R, CP, kappa, g, gain)


def tables(model: DiscreteLTI, at_least: int = 0) -> Tables:
    """The tables of ``model`` up to at least ``at_least`` ticks and its settling horizon.

    Kept per model (by identity) and size; the size is a power of two, so that calls with
    nearby needs share one set.

    Parameters
    ----------
    model : DiscreteLTI
        SISO, strictly proper and stable.
    at_least : int
        Largest tick count the caller will look up.

    Raises
    ------
    ValueError
        When the model is not SISO, has feed-through, is unstable or has zero static gain.
    """
    _check_siso(model)
    rho = float(np.max(np.abs(model.poles()), initial=0.0))
    # ticks until rho^k < _TAIL, with a margin for the transient growth of A^k
    horizon = int(np.ceil(np.log(_TAIL) / np.log(rho))) + 64 if rho > 0 else 64
    N = 1 << int(np.ceil(np.log2(max(at_least, horizon, 2))))
    t = _tables(model, N)
    while np.linalg.norm(t.P[-1]) > _TAIL:  # a strongly non-normal A: grow until it decays
        N *= 2
        t = _tables(model, N)
    return t


@njit(cache=True)
def settle_ticks(CP: np.ndarray, kappa: np.ndarray, gain: float, X: np.ndarray, tol: float) -> int:
    """Shortest ``h`` with ``|C A^m X| / |gain| <= tol`` for every ``m >= h`` (-1: beyond N).

    Parameters
    ----------
    CP, kappa : numpy.ndarray
        `Tables.CP` and `Tables.kappa`.
    gain : float
        The static gain (the error is of the calibrated position ``y / gain``).
    X : numpy.ndarray
        Deviation state, shape (nx, 2).
    tol : float
        Tolerance, bit (> 0).
    """
    nx = X.shape[0]
    fro = 0.0
    for i in range(nx):
        fro += X[i, 0] * X[i, 0] + X[i, 1] * X[i, 1]
    fro = np.sqrt(fro)
    thr = tol * abs(gain)
    N = kappa.shape[0] - 1
    if kappa[N] * fro > thr:
        return -1
    if kappa[0] * fro <= thr:
        return 0
    lo, hi = 0, N  # kappa[lo] * fro > thr >= kappa[hi] * fro
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if kappa[mid] * fro > thr:
            lo = mid
        else:
            hi = mid
    thr2 = thr * thr
    for m in range(hi - 1, -1, -1):
        e0 = 0.0
        e1 = 0.0
        for i in range(nx):
            e0 += CP[m, i] * X[i, 0]
            e1 += CP[m, i] * X[i, 1]
        if e0 * e0 + e1 * e1 > thr2:
            return m + 1
    return 0


@njit(cache=True)
def _chain(
    P: np.ndarray,
    R: np.ndarray,
    CP: np.ndarray,
    kappa: np.ndarray,
    g: np.ndarray,
    gain: float,
    p0: np.ndarray,
    p1: np.ndarray,
    n: np.ndarray,
    hold: np.ndarray,
    settle: np.ndarray,
    tol: np.ndarray,
    apply: bool,
    X0: np.ndarray,
    Xend: np.ndarray,
    hold_out: np.ndarray,
    required: np.ndarray,
) -> int:
    """The pass over the segments (module doc); returns -1, or the segment beyond the tables.

    ``required[j]``: the settling delay where ``settle[j]`` (else -1); it replaces the hold
    when ``apply``.
    """
    nx = g.shape[0]
    X = np.empty((nx, 2))
    Y = np.empty((nx, 2))
    m = n.shape[0]
    for i in range(nx):  # at rest at the first segment's start, relative to its end
        for a in range(2):
            X[i, a] = g[i] * (p0[0, a] - p1[0, a])
    for j in range(m):
        if j > 0:  # re-reference to this segment's end
            for i in range(nx):
                for a in range(2):
                    X[i, a] += g[i] * (p1[j - 1, a] - p1[j, a])
        X0[j] = X
        nj = n[j]
        if nj > 0:
            for a in range(2):
                d = (p1[j, a] - p0[j, a]) / nj
                for i in range(nx):
                    acc = -R[nj, i] * d
                    for k in range(nx):
                        acc += P[nj, i, k] * X[k, a]
                    Y[i, a] = acc
            X[:, :] = Y
        Xend[j] = X
        h = hold[j]
        required[j] = -1
        if settle[j]:
            r = settle_ticks(CP, kappa, gain, X, tol[j])
            if r < 0:
                return j
            required[j] = r
            if apply:
                h = r
        hold_out[j] = h
        if h > 0:
            for a in range(2):
                for i in range(nx):
                    acc = 0.0
                    for k in range(nx):
                        acc += P[h, i, k] * X[k, a]
                    Y[i, a] = acc
            X[:, :] = Y
    return -1


@dataclass(frozen=True, eq=False)
class Propagation:
    """The states of a model along a segment chain, and what they give.

    Attributes
    ----------
    tables : Tables
        The model's tables.
    p0, p1, n, hold : numpy.ndarray
        The segments (bit, bit, ticks, ticks), holds as run (settled ones included).
    X0, Xend : numpy.ndarray
        Deviation states at each segment's start and at the end of its motion, relative to
        its end point ``p1``, shape (m, nx, 2).
    required : numpy.ndarray
        Shortest settling delay after each segment asked for (``settle``), ticks; -1 for the
        others, int (m,).
    """

    tables: Tables
    p0: np.ndarray
    p1: np.ndarray
    n: np.ndarray
    hold: np.ndarray
    X0: np.ndarray
    Xend: np.ndarray
    required: np.ndarray

    @property
    def start(self) -> np.ndarray:
        """First tick of each segment, int (m,)."""
        s = np.zeros(self.n.size, dtype=np.int64)
        np.cumsum((self.n + self.hold)[:-1], out=s[1:])
        return s

    def positions(self, tick: np.ndarray) -> np.ndarray:
        """Calibrated positions ``y / G(0)`` at absolute ticks, bit, shape (k, 2).

        A tick after the last segment's hold continues that hold.
        """
        t = np.asarray(tick, dtype=np.int64).reshape(-1)
        if np.any(t < 0):
            raise ValueError("ticks must be >= 0")
        tb = self.tables
        j = np.searchsorted(self.start, t, side="right") - 1
        k = t - self.start[j]
        n = self.n[j]
        if np.any(k > tb.size + n):
            raise ValueError(f"a tick lies beyond the tables ({tb.size} ticks past a motion)")
        moving = k <= n
        X = np.empty((t.size, tb.g.size, 2))
        if np.any(moving):
            jm, km = j[moving], k[moving]
            d = (self.p1[jm] - self.p0[jm]) / np.maximum(n[moving], 1)[:, None]
            w = (n[moving] - km)[:, None] * tb.S[km] + tb.R[km]
            X[moving] = np.einsum("eik,eka->eia", tb.P[km], self.X0[jm])
            X[moving] -= w[:, :, None] * d[:, None, :]
        held = ~moving
        if np.any(held):
            X[held] = np.einsum("eik,eka->eia", tb.P[k[held] - n[held]], self.Xend[j[held]])
        C = tb.CP[0]
        return np.einsum("i,eia->ea", C, X) / tb.gain + self.p1[j]


def propagate(
    model: DiscreteLTI,
    p0: np.ndarray,
    p1: np.ndarray,
    n: np.ndarray,
    hold: np.ndarray,
    settle: np.ndarray | None = None,
    tol: np.ndarray | None = None,
    extra_ticks: int = 0,
    apply: bool = True,
) -> Propagation:
    """Run ``model`` (both axes) along segments from rest at ``p0[0]``, exactly.

    Parameters
    ----------
    model : DiscreteLTI
        SISO axis model, bit -> bit.
    p0, p1 : numpy.ndarray
        Segment ends, bit, shape (m, 2) (continuous: ``p0[j + 1] = p1[j]``).
    n, hold : numpy.ndarray
        Motion and hold ticks, shape (m,).
    settle : numpy.ndarray, optional
        Bool (m,): find the shortest delay after these segments after which the calibrated
        error stays within ``tol`` (`settle_ticks`), and hold it (``apply``).
    tol : numpy.ndarray, optional
        Tolerance per segment, bit, shape (m,) (> 0 where ``settle``).
    extra_ticks : int
        Further ticks past a motion the caller will look up (laser delays).
    apply : bool
        Hold the settling delays found (True), or keep ``hold`` and only report them in
        `Propagation.required` (False: does a fixed delay suffice?).

    Returns
    -------
    Propagation
        States per segment and the holds as run.

    Raises
    ------
    ValueError
        On a bad model, or when a settling delay lies beyond the model's tables (a
        tolerance far below the error's scale).
    """
    p0 = np.ascontiguousarray(p0, dtype=float).reshape(-1, 2)
    p1 = np.ascontiguousarray(p1, dtype=float).reshape(-1, 2)
    n = np.ascontiguousarray(n, dtype=np.int64)
    hold = np.ascontiguousarray(hold, dtype=np.int64)
    m = n.size
    settle = np.zeros(m, dtype=bool) if settle is None else np.ascontiguousarray(settle, bool)
    tol = np.ones(m) if tol is None else np.ascontiguousarray(tol, dtype=float)
    if np.any(tol[settle] <= 0) or not np.all(np.isfinite(tol[settle])):
        raise ValueError("settling tolerances must be positive and finite, bit")
    need = max(int(n.max(initial=0)), int(hold.max(initial=0))) + int(extra_ticks)
    tb = tables(model, need)
    nx = tb.g.size
    X0 = np.empty((m, nx, 2))
    Xend = np.empty((m, nx, 2))
    hold_out = np.empty(m, dtype=np.int64)
    required = np.empty(m, dtype=np.int64)
    if m:
        bad = _chain(
            tb.P,
            tb.R,
            tb.CP,
            tb.kappa,
            tb.g,
            tb.gain,
            p0,
            p1,
            n,
            hold,
            settle,
            tol,
            bool(apply),
            X0,
            Xend,
            hold_out,
            required,
        )
        if bad >= 0:
            raise ValueError(
                f"segment {bad}: the error does not settle within {tol[bad]:.3g} bit inside "
                f"the model's {tb.size} ticks of tables; raise the tolerance"
            )
    return Propagation(tb, p0, p1, n, hold_out, X0, Xend, required)
