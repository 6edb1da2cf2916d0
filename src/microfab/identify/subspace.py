"""Discrete-time MIMO subspace identification (N4SID, MOESP, CVA) for long records.

Seed 002 §III-A eq. (6) models the XY stage's closed loop, command ρ to position γ, as a
continuous-time LTI state-space model with a 4-state hidden ``z``, identified "using the
MATLAB function ``n4sid``". `identify_subspace` does the same on sampled records: it
identifies a discrete model

``x_{k+1} = A x_k + B u_k``, ``y_k = C x_k + D u_k``

and `SubspaceModel.to_continuous` converts it to eq. (6)'s ``(A, B, C, D)`` by the inverse
of the zero-order hold (as MATLAB's ``d2c``).

Algorithm (Van Overschee & De Moor, *Subspace Identification for Linear Systems*, 1996,
ch. 4 and 6; the weightings of their Theorem 13):

1. ``L = R^T`` of the LQ decomposition of ``[U_f; U_p; Y_p; Y_f]`` (``i`` block rows each),
   built by chunks of rows (`identify/subspace_data.py`): memory does not grow with N, and
   nothing after it touches the data.
2. Oblique projection of ``Y_f`` along ``U_f`` onto ``W_p = [U_p; Y_p]``:
   ``O = L32 L22^+ [L21 L22] Q^T``; its weighted SVD ``W1 O W2 = U S V^T`` with
   ``"n4sid"``: ``W1 = I, W2 = I``; ``"moesp"``: ``W1 = I, W2 = Pi_{U_f}^perp``;
   ``"cva"``: ``W1 = (Y_f Pi^perp Y_f^T)^{-1/2}``, ``W2 = Pi^perp``. The pseudo-inverses
   drop singular values below ``rcond`` times the largest (noise-free data make ``L22``
   exactly rank-deficient: ``i m + n`` of ``i (m + p)``).
3. Extended observability ``Gamma = W1^+ U_n S_n^{1/2}``; ``C`` its first block row, ``A``
   from its shift invariance by least squares.
4. ``B``, ``D`` and each run's initial state by linear least squares on the data (one more
   chunked pass), which is exact on noise-free data.

``singular_values`` (the ``S`` above) are kept for the order check; `order_scan` reuses one
R factor and one SVD for every order.

Feed-through: eq. (6b) writes ``D ρ``, but MATLAB's ``n4sid`` estimates ``D = 0`` unless
asked (``'Feedthrough'``, default false) and the stage's position cannot follow its command
within the same sample, so ``feedthrough=False`` (D = 0) is the default here;
``feedthrough=True`` estimates D.

No mean is removed: the model maps positions to positions and the records start at rest,
so the offsets are part of the dynamics (a static gain near 1). Each channel is divided by
its RMS before the decomposition (``scale``) and the model is scaled back.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import scipy.linalg

from microfab.core.arrays import readonly
from microfab.core.validate import check_int, check_positive
from microfab.identify.subspace_data import (
    HankelFactor,
    IORun,
    check_runs,
    error_moments,
    fit_bdx0,
    hankel_factor,
    simulate_ss,
)

__all__ = [
    "WEIGHTINGS",
    "ContinuousModel",
    "IORun",
    "OrderScan",
    "SubspaceConfig",
    "SubspaceModel",
    "default_block_rows",
    "identify_subspace",
    "order_scan",
]

Weighting = Literal["n4sid", "moesp", "cva"]
WEIGHTINGS: tuple[str, ...] = ("n4sid", "moesp", "cva")
FORMAT = "microfab.identify.SubspaceModel"
VERSION = 1
_PE_RTOL = 1e-12  # input Hankel smallest/largest singular value below this: not exciting
_REAL_POLE_TOL = 1e-12  # |Im z| <= this |z|: a real pole


def default_block_rows(max_order: int) -> int:
    """Default block rows ``i = 2 max_order + 2`` (10 for the seed's order 4).

    Past and future windows of twice the order plus two samples: enough for the shift
    invariance of ``Gamma`` (needs ``(i - 1) p >= n``) with margin against noise, while the
    cost of the R factor grows as ``i^2``. Assumed (MATLAB picks its horizon by an AIC
    search the seed does not report).
    """
    return 2 * int(max_order) + 2


@dataclass(frozen=True, kw_only=True)
class SubspaceConfig:
    """Settings of `identify_subspace` and `order_scan`.

    Parameters
    ----------
    order : int
        Model order n (>= 1; seed 002 §III-A: 4, "dimensions higher than 4 have practically
        the same prediction error").
    block_rows : int or None
        Block rows ``i`` of the past and of the future; None: `default_block_rows` of the
        order (of the largest order in `order_scan`). Needs ``order <= i`` and
        ``order <= (i - 1) p``.
    weighting : {"n4sid", "moesp", "cva"}
        Weighting of the oblique projection before the SVD (module docstring).
    feedthrough : bool
        Estimate D (else D = 0, MATLAB ``n4sid``'s default; see module docstring).
    initial_state : {"estimate", "zero"}
        Fit each run's initial state, or take it as zero (runs from rest).
    chunk_samples : int
        Hankel rows built at a time (>= 16): memory ``chunk_samples x 2 i (m + p) x 8``
        bytes. The result does not depend on it beyond rounding.
    rcond : float
        Relative cut-off of the pseudo-inverses (in (0, 1); assumed 1e-10: noise-free
        null directions sit near 1e-15, genuine ones well above).
    scale : bool
        Divide each channel by its RMS before the decomposition.
    workers : int
        Threads building the R factor (>= 1; default 2, the project machine's cores). The
        answer changes with it only in rounding, and not with the machine's core count.
    """

    order: int = 4  # seed 002 §III-A: z in R^4
    block_rows: int | None = None
    weighting: Weighting = "n4sid"
    feedthrough: bool = False
    initial_state: Literal["estimate", "zero"] = "estimate"
    chunk_samples: int = 8192
    rcond: float = 1e-10
    scale: bool = True
    workers: int = 2

    def __post_init__(self) -> None:
        check_int("order", self.order, 1)
        if self.block_rows is not None:
            check_int("block_rows", self.block_rows, 2)
            if self.order > self.block_rows:
                raise ValueError(
                    f"order {self.order} is above block_rows {self.block_rows}: the "
                    f"extended observability matrix cannot hold {self.order} states; use "
                    f"block_rows >= {self.order} (default {default_block_rows(self.order)})"
                )
        if self.weighting not in WEIGHTINGS:
            raise ValueError(
                f"weighting must be one of {', '.join(WEIGHTINGS)}, got {self.weighting!r}"
            )
        if not isinstance(self.feedthrough, bool):
            raise ValueError(f"feedthrough must be True or False, got {self.feedthrough!r}")
        if self.initial_state not in ("estimate", "zero"):
            raise ValueError(
                f"initial_state must be 'estimate' or 'zero', got {self.initial_state!r}"
            )
        check_int("chunk_samples", self.chunk_samples, 16, "samples")
        rc = check_positive("rcond", self.rcond)
        if rc >= 1.0:
            raise ValueError(f"rcond must be below 1 (relative cut-off), got {self.rcond}")
        check_int("workers", self.workers, 1, "threads")
        if not isinstance(self.scale, bool):
            raise ValueError(f"scale must be True or False, got {self.scale!r}")

    def rows_for(self, max_order: int) -> int:
        """Block rows used for models up to ``max_order``."""
        return self.block_rows if self.block_rows is not None else default_block_rows(max_order)


@dataclass(frozen=True, eq=False)
class ContinuousModel:
    """Continuous-time ``dz/dt = A z + B u``, ``y = C z + D u`` (seed 002 eq. 6), s.

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        Shapes (n, n), (n, m), (p, n), (p, m); ``a`` in 1/s, ``b`` in (state)/(input s).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray

    @property
    def poles(self) -> np.ndarray:
        """Eigenvalues of A, rad/s, sorted by magnitude."""
        return _sorted(np.linalg.eigvals(self.a))

    def to_control(self) -> Any:
        """The model as a python-control ``StateSpace``."""
        import control

        return control.ss(self.a, self.b, self.c, self.d)


def _sorted(z: np.ndarray) -> np.ndarray:
    return z[np.lexsort((z.imag, np.abs(z)))]


@dataclass(frozen=True, eq=False)
class SubspaceModel:
    """An identified discrete-time state-space model (frozen; arrays read-only).

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        Shapes (n, n), (n, m), (p, n), (p, m), in the records' units.
    dt : float
        Sample time, s.
    x0 : numpy.ndarray
        Initial state of each training run, shape (n_runs, n) (zeros if not estimated).
    singular_values : numpy.ndarray
        Singular values of the weighted oblique projection (scaled data), largest first:
        a gap after the n-th shows the order.
    block_rows : int
        ``i`` used.
    weighting : str
        ``"n4sid"``, ``"moesp"`` or ``"cva"``.
    fit_mean, fit_std : numpy.ndarray
        Mean and standard deviation per output of the simulation error ``y - y_model`` on
        the training runs (from each run's ``x0``), output units (seed 002 Table II μ, σ).
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    dt: float
    x0: np.ndarray
    singular_values: np.ndarray
    block_rows: int
    weighting: str
    fit_mean: np.ndarray
    fit_std: np.ndarray

    def __post_init__(self) -> None:
        check_positive("dt", self.dt, "s")
        for name in _ARRAYS:
            arr = readonly(getattr(self, name))
            if not np.isfinite(arr).all():
                raise ValueError(f"{name} holds a NaN or infinite value")
            object.__setattr__(self, name, arr)
        n = self.a.shape[0] if self.a.ndim == 2 else -1
        shapes = {"a": (n, n), "b": (n, None), "c": (None, n), "d": (None, None)}
        for name, (r, c) in shapes.items():
            arr = getattr(self, name)
            if (
                arr.ndim != 2
                or (r is not None and arr.shape[0] != r)
                or (c is not None and arr.shape[1] != c)
            ):
                raise ValueError(
                    f"{name} has shape {arr.shape}, inconsistent with a of shape {self.a.shape}"
                )
        if self.d.shape != (self.c.shape[0], self.b.shape[1]):
            raise ValueError(
                f"d has shape {self.d.shape}, expected (p, m) = "
                f"{(self.c.shape[0], self.b.shape[1])}"
            )
        if self.x0.ndim != 2 or self.x0.shape[1] != n:
            raise ValueError(f"x0 must have shape (n_runs, {n}), got {self.x0.shape}")
        object.__setattr__(self, "dt", float(self.dt))

    @property
    def order(self) -> int:
        """Number of states n."""
        return int(self.a.shape[0])

    @property
    def n_inputs(self) -> int:
        """Number of inputs m."""
        return int(self.b.shape[1])

    @property
    def n_outputs(self) -> int:
        """Number of outputs p."""
        return int(self.c.shape[0])

    @property
    def poles(self) -> np.ndarray:
        """Discrete poles (eigenvalues of A), sorted by magnitude."""
        return _sorted(np.linalg.eigvals(self.a))

    def continuous_poles(self) -> np.ndarray:
        """Poles ``log(z) / dt``, rad/s (refuses negative real z: no real logarithm)."""
        z = self.poles
        _check_log(z)
        return _sorted(np.log(z.astype(complex)) / self.dt)

    def poles_hz(self) -> np.ndarray:
        """Natural frequency ``|s| / 2 pi`` of each continuous pole, Hz."""
        return np.abs(self.continuous_poles()) / (2.0 * math.pi)

    def time_constants_s(self) -> np.ndarray:
        """Time constant ``-1 / Re(s)`` of each continuous pole, s, slowest first."""
        return np.sort(-1.0 / self.continuous_poles().real)[::-1]

    def to_continuous(self) -> ContinuousModel:
        """Continuous ``(A, B, C, D)`` by the inverse zero-order hold (MATLAB ``d2c``).

        ``[[A_c, B_c], [0, 0]] = logm([[A, B], [0, I]]) / dt``; ``C`` and ``D`` unchanged.
        The principal matrix logarithm (`scipy.linalg.logm`) is real when no eigenvalue of
        A is real and negative or zero.

        Raises
        ------
        ValueError
            A real pole at or below zero: a sampled continuous system has none (the
            discrete model has a mode that alternates sign every sample).
        """
        _check_log(np.linalg.eigvals(self.a))
        n, m = self.order, self.n_inputs
        big = np.zeros((n + m, n + m))
        big[:n, :n] = self.a
        big[:n, n:] = self.b
        big[n:, n:] = np.eye(m)
        lg = scipy.linalg.logm(big)
        scale = max(1.0, float(np.abs(lg).max()))
        if np.iscomplexobj(lg):
            if np.abs(lg.imag).max() > 1e-9 * scale:  # pragma: no cover - guarded above
                raise ValueError("the matrix logarithm is not real")
            lg = lg.real
        lg = lg / self.dt
        return ContinuousModel(a=readonly(lg[:n, :n]), b=readonly(lg[:n, n:]), c=self.c, d=self.d)

    def simulate(self, u: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Output (N, p) for inputs ``u`` (N, m) from ``x0`` (default zero: at rest)."""
        u2 = np.asarray(u, dtype=np.float64)
        if u2.ndim == 1:
            u2 = u2[:, None]
        if u2.ndim != 2 or u2.shape[1] != self.n_inputs:
            raise ValueError(f"u must have shape (N, {self.n_inputs}), got {np.shape(u)}")
        x = np.zeros(self.order) if x0 is None else np.asarray(x0, dtype=np.float64)
        if x.shape != (self.order,):
            raise ValueError(f"x0 must have shape ({self.order},), got {x.shape}")
        return simulate_ss(self.a, self.b, self.c, self.d, u2, x)

    def prediction_error(
        self, u: np.ndarray, y: np.ndarray, x0: np.ndarray | None = None
    ) -> np.ndarray:
        """Simulation error ``y - simulate(u, x0)``, shape (N, p)."""
        y2 = np.asarray(y, dtype=np.float64)
        if y2.ndim == 1:
            y2 = y2[:, None]
        sim = self.simulate(u, x0)
        if y2.shape != sim.shape:
            raise ValueError(f"y must have shape {sim.shape}, got {np.shape(y)}")
        return y2 - sim

    def error_stats(self, runs: Any, x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mean and standard deviation per output of the simulation error over ``runs``.

        Parameters
        ----------
        runs : IORun, (u, y) pair or a sequence of them
            Records (e.g. validation runs from rest).
        x0 : numpy.ndarray or None
            Initial state per run, shape (n_runs, n); None: zero (runs from rest).

        Returns
        -------
        mean, std : numpy.ndarray
            Shapes (p,), output units (seed 002 Table II μ, σ). No memory grows with N.
        """
        checked = check_runs(runs, 1)
        x = np.zeros((len(checked), self.order)) if x0 is None else np.asarray(x0, float)
        if x.shape != (len(checked), self.order):
            raise ValueError(f"x0 must have shape {(len(checked), self.order)}, got {x.shape}")
        return error_moments(self.a, self.b, self.c, self.d, checked, x)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (format, version, dt, rate; every array as nested lists)."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "dt": self.dt,
            "rate_hz": 1.0 / self.dt,
            "order": self.order,
            "block_rows": self.block_rows,
            "weighting": self.weighting,
            **{k: getattr(self, k).tolist() for k in _ARRAYS},
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SubspaceModel:
        """Inverse of `to_dict`.

        Raises
        ------
        ValueError
            Another format or version, a rate that disagrees with ``dt``, unknown or
            missing keys, inconsistent shapes, a non-finite value.
        """
        if not isinstance(data, dict):
            raise ValueError(f"a subspace model must be a mapping, got {type(data).__name__}")
        if data.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} (format {data.get('format')!r})")
        if data.get("version") != VERSION:
            raise ValueError(
                f"subspace model version {data.get('version')!r} is not supported "
                f"(this microfab reads version {VERSION})"
            )
        if set(data) != _KEYS:
            extra, missing = sorted(set(data) - _KEYS), sorted(_KEYS - set(data))
            raise ValueError(f"subspace model keys: unknown {extra}, missing {missing}")
        dt = check_positive("dt", data["dt"], "s")
        rate = check_positive("rate_hz", data["rate_hz"], "Hz")
        if abs(rate * dt - 1.0) > 1e-9:
            raise ValueError(f"rate_hz {rate} disagrees with dt {dt} s (1/dt = {1 / dt} Hz)")
        arrays = {k: np.asarray(data[k], dtype=np.float64) for k in _ARRAYS}
        if arrays["x0"].size == 0:
            arrays["x0"] = arrays["x0"].reshape(0, arrays["a"].shape[0])
        model = cls(
            dt=dt, block_rows=int(data["block_rows"]), weighting=str(data["weighting"]), **arrays
        )
        if model.order != data["order"]:
            raise ValueError(f"order {data['order']!r} disagrees with A of size {model.order}")
        return model


_ARRAYS = ("a", "b", "c", "d", "x0", "singular_values", "fit_mean", "fit_std")
_KEYS = frozenset(
    {"format", "version", "dt", "rate_hz", "order", "block_rows", "weighting", *_ARRAYS}
)


def _check_log(z: np.ndarray) -> None:
    bad = [p for p in z if abs(p.imag) <= _REAL_POLE_TOL * max(abs(p), 1e-300) and p.real <= 0]
    if bad:
        raise ValueError(
            f"discrete pole {complex(bad[0]).real:.6g} is real and not positive: it has no "
            "real logarithm, so no continuous model samples to it (an alternating mode, "
            "often a sign of too high an order or of noise); try a lower order"
        )


@dataclass(frozen=True, eq=False)
class _Projection:
    """SVD of the weighted oblique projection: what every order reuses."""

    u: np.ndarray  # left singular vectors (i p, k)
    s: np.ndarray  # singular values
    w1_pinv: np.ndarray | None  # W1^+ (CVA), else None


def _pinv_parts(m: np.ndarray, rcond: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Truncated SVD ``(U_r, s_r, Vt_r)`` of ``m``, dropping ``s < rcond s_max``."""
    uu, s, vt = np.linalg.svd(m, full_matrices=False)
    keep = s > rcond * s[0] if s.size and s[0] > 0 else np.zeros(s.size, bool)
    return uu[:, keep], s[keep], vt[keep]


def _projection(f: HankelFactor, weighting: str, rcond: float) -> _Projection:
    """Weighted oblique projection from the R factor, and its SVD."""
    i, m, p = f.block_rows, f.n_inputs, f.n_outputs
    lo = f.r.T  # L: rows are data blocks [U_f, U_p, Y_p, Y_f], columns Q's
    uf, wp_end = i * m, 2 * i * m + i * p
    l21 = lo[uf:wp_end, :uf]
    l22 = lo[uf:wp_end, uf:wp_end]
    l32 = lo[wp_end:, uf:wp_end]
    u2, s2, vt2 = _pinv_parts(l22, rcond)
    l32_l22p = (l32 @ vt2.T) / s2 @ u2.T  # L32 L22^+
    w1_pinv = None
    if weighting == "n4sid":
        mat = l32_l22p @ np.hstack([l21, l22])
    else:
        mat = l32_l22p @ l22  # W2 = Pi_{U_f}^perp
        if weighting == "cva":
            u3, s3, _ = _pinv_parts(lo[wp_end:, uf:], rcond)  # [L32 L33] = Y_f Pi^perp
            mat = (u3 / s3) @ (u3.T @ mat)  # W1 = (Y_f Pi Y_f^T)^{-1/2}
            w1_pinv = (u3 * s3) @ u3.T
    uu, s, _ = np.linalg.svd(mat, full_matrices=False)
    return _Projection(u=uu, s=s, w1_pinv=w1_pinv)


def _check_order(order: int, i: int, p: int) -> None:
    check_int("order", order, 1)
    if order > i or order > (i - 1) * p:
        raise ValueError(
            f"order {order} is above what {i} block rows allow with {p} outputs "
            f"(order <= block_rows and order <= (block_rows - 1) x outputs); use "
            f"block_rows >= {max(order, -(-order // p) + 1)}"
        )


def _a_c(proj: _Projection, order: int, p: int) -> tuple[np.ndarray, np.ndarray]:
    """A and C (scaled coordinates) from the first ``order`` singular directions."""
    gamma = proj.u[:, :order] * np.sqrt(proj.s[:order])
    if proj.w1_pinv is not None:
        gamma = proj.w1_pinv @ gamma
    c = gamma[:p].copy()
    a = np.linalg.lstsq(gamma[:-p], gamma[p:], rcond=None)[0]
    return a, c


def _check_excitation(f: HankelFactor) -> None:
    ratio = f.input_rank_ratio()
    if ratio <= _PE_RTOL:
        raise ValueError(
            f"the input is not persistently exciting of order {2 * f.block_rows} "
            f"(2 x block_rows): its block-Hankel matrix is rank-deficient (smallest / largest "
            f"singular value {ratio:.3g} <= {_PE_RTOL:g}); a constant or single-tone input "
            "cannot identify the dynamics: use a richer excitation or fewer block rows"
        )


def _model(
    proj: _Projection,
    f: HankelFactor,
    runs: list[IORun],
    dt: float,
    cfg: SubspaceConfig,
    order: int,
) -> SubspaceModel:
    p = f.n_outputs
    a, c_s = _a_c(proj, order, p)
    bdx = fit_bdx0(
        a,
        c_s,
        runs,
        f.u_scale,
        f.y_scale,
        feedthrough=cfg.feedthrough,
        estimate_x0=cfg.initial_state == "estimate",
        chunk_samples=cfg.chunk_samples,
    )
    b = bdx.b / f.u_scale  # B_s diag(1/su)
    c = c_s * f.y_scale[:, None]  # diag(sy) C_s
    d = f.y_scale[:, None] * bdx.d / f.u_scale
    mean, std = error_moments(a, b, c, d, runs, bdx.x0)
    return SubspaceModel(
        a=a,
        b=b,
        c=c,
        d=d,
        dt=dt,
        x0=bdx.x0,
        singular_values=proj.s,
        block_rows=f.block_rows,
        weighting=cfg.weighting,
        fit_mean=mean,
        fit_std=std,
    )


def _factor(
    runs: Any, dt: float, cfg: SubspaceConfig, max_order: int
) -> tuple[list[IORun], HankelFactor]:
    check_positive("dt", dt, "s")
    i = cfg.rows_for(max_order)
    checked = check_runs(runs, 2 * i + 1)
    _check_order(max_order, i, checked[0].y.shape[1])
    f = hankel_factor(
        checked, i, chunk_samples=cfg.chunk_samples, scale=cfg.scale, workers=cfg.workers
    )
    if f.n_columns < f.r.shape[0]:
        raise ValueError(
            f"{f.n_columns} Hankel columns over all runs are fewer than the "
            f"{f.r.shape[0]} rows of the data matrix: use longer runs or fewer block rows"
        )
    _check_excitation(f)
    return checked, f


def identify_subspace(runs: Any, dt: float, config: SubspaceConfig | None = None) -> SubspaceModel:
    """Identify a discrete state-space model from one or several records.

    Parameters
    ----------
    runs : IORun, (u, y) pair, or a sequence of them
        Inputs ``u`` (N, m) and outputs ``y`` (N, p) sampled every ``dt``; several runs
        are joined without forming Hankel blocks across their boundaries.
    dt : float
        Sample time, s.
    config : SubspaceConfig, optional
        Order, block rows, weighting, feed-through, ... (defaults: order 4, N4SID).

    Returns
    -------
    SubspaceModel

    Raises
    ------
    ValueError
        Bad records (`subspace_data.check_runs`), an order below 1 or above the block
        rows, too few samples, an input that is not persistently exciting (e.g. constant),
        an unstable identified A, or a singular B/D regression.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal((4000, 1))
    >>> y = np.zeros((4000, 1)); x = 0.0
    >>> for k in range(4000):
    ...     y[k] = x; x = 0.9 * x + u[k, 0]
    >>> m = identify_subspace((u, y), 1e-3, SubspaceConfig(order=1))
    >>> round(float(m.poles[0].real), 9)
    0.9
    """
    cfg = config or SubspaceConfig()
    checked, f = _factor(runs, dt, cfg, cfg.order)
    proj = _projection(f, cfg.weighting, cfg.rcond)
    return _model(proj, f, checked, dt, cfg, cfg.order)


@dataclass(frozen=True, eq=False)
class OrderScan:
    """Fit error per model order from one R factor (seed 002 §III-A's order check).

    Attributes
    ----------
    orders : tuple of int
        Orders tried.
    singular_values : numpy.ndarray
        All singular values of the weighted projection (shared by every order).
    fit_mean, fit_std : numpy.ndarray
        Shapes (n_orders, p): training simulation error per order and output.
    models : tuple of SubspaceModel
        The model of each order.
    """

    orders: tuple[int, ...]
    singular_values: np.ndarray
    fit_mean: np.ndarray
    fit_std: np.ndarray
    models: tuple[SubspaceModel, ...]

    def rows(self) -> list[tuple[int, float, tuple[float, ...]]]:
        """``(order, n-th singular value / first, fit std per output)`` per order."""
        s0 = float(self.singular_values[0])
        return [
            (n, float(self.singular_values[n - 1]) / s0, tuple(float(v) for v in std))
            for n, std in zip(self.orders, self.fit_std, strict=True)
        ]


def order_scan(
    runs: Any, dt: float, orders: Iterable[int] = range(2, 9), config: SubspaceConfig | None = None
) -> OrderScan:
    """Identify every order in ``orders`` from one R factor and one SVD.

    Parameters
    ----------
    runs, dt : see `identify_subspace`.
    orders : iterable of int
        Orders to try (default 2..8, seed 002 §III-A).
    config : SubspaceConfig, optional
        Its ``order`` is ignored; ``block_rows`` None means `default_block_rows` of the
        largest order, so that all orders share one decomposition.

    Returns
    -------
    OrderScan
        One B/D fit and one simulation pass over the data per order.
    """
    cfg = config or SubspaceConfig()
    ords = tuple(int(check_int("order", o, 1)) for o in orders)
    if not ords:
        raise ValueError("orders is empty: give at least one model order")
    checked, f = _factor(runs, dt, cfg, max(ords))
    proj = _projection(f, cfg.weighting, cfg.rcond)
    models = tuple(_model(proj, f, checked, dt, cfg, n) for n in ords)
    return OrderScan(
        orders=ords,
        singular_values=readonly(proj.s),
        fit_mean=readonly([mdl.fit_mean for mdl in models]),
        fit_std=readonly([mdl.fit_std for mdl in models]),
        models=models,
    )
