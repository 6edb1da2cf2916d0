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
   chunked pass, `identify/subspace_fit.py`), which is exact on noise-free data.

The result is a `SubspaceModel` (`identify/subspace_model.py`); its ``singular_values``
(the ``S`` above) are kept for the order check; `order_scan` reuses one
R factor and one SVD for every order.

Default weighting: MOESP, not the unit ("n4sid") weighting. MATLAB's ``n4sid`` itself
does not use the unit weighting by default (``n4sidOptions('N4Weight')`` is ``'auto'``,
which picks MOESP, CVA or SSARX), and on what the stage is fed, jerk-limited position
commands at 10 kHz, the input Hankel matrix is numerically rank-deficient: there the unit
weighting's ``L22^+ [L21 L22]`` swings with ``rcond`` (noise-free poles off by 0.05-50 %)
while MOESP and CVA recover them to 1e-9 (tests). On white inputs all three agree to
1e-14. ``weighting="n4sid"`` remains an option.

Feed-through: eq. (6b) writes ``D ρ``, but MATLAB's ``n4sid`` estimates ``D = 0`` unless
asked (``'Feedthrough'``, default false) and the stage's position cannot follow its command
within the same sample, so ``feedthrough=False`` (D = 0) is the default here;
``feedthrough=True`` estimates D.

No mean is removed: the model maps positions to positions and the records start at rest,
so the offsets are part of the dynamics (a static gain near 1). Each channel is divided by
its RMS before the decomposition (``scale``) and the model is scaled back.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.validate import check_int, check_positive
from microfab.identify.subspace_data import HankelFactor, IORun, check_runs, hankel_factor
from microfab.identify.subspace_fit import error_moments, fit_bdx0
from microfab.identify.subspace_model import ContinuousModel, SubspaceModel

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
_PE_RTOL = 1e-12  # singular values of the input Hankel matrix counted above this x largest


def default_block_rows(max_order: int) -> int:
    """Default block rows ``i = 2 max_order + 2`` (10 for the seed's order 4).

    Past and future windows of twice the order plus two samples: enough for the shift
    invariance of ``Gamma`` (needs ``(i - 1) p >= n``) with margin against noise, while the
    cost of the R factor grows as ``i^2``. Assumed (MATLAB picks its horizon by an AIC
    search the seed does not report).
    """
    return 2 * int(max_order) + 2


#: Highest model order accepted. Assumed bound of the work: the R factor grows as
#: (2 i (m + p))² with i = 2 n + 2 block rows; at n = 100 and two inputs and outputs it is
#: 3.2e3 wide (80 MB); order 1000 would be 8 GB. Seed 002 §III-A fits order 4.
MAX_ORDER = 100
#: Most block rows accepted (the same bound: 2 i (m + p) = 2 x 256 x 4 = 2048 columns).
MAX_BLOCK_ROWS = 2 * MAX_ORDER + 56


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
    weighting : {"moesp", "n4sid", "cva"}
        Weighting of the oblique projection before the SVD (module docstring; default
        MOESP, as MATLAB ``n4sid``'s automatic choice often is, and the only robust one of
        the three on smooth 10 kHz commands besides CVA).
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
    weighting: Weighting = "moesp"
    feedthrough: bool = False
    initial_state: Literal["estimate", "zero"] = "estimate"
    chunk_samples: int = 8192
    rcond: float = 1e-10
    scale: bool = True
    workers: int = 2

    def __post_init__(self) -> None:
        check_int("order", self.order, 1)
        if self.order > MAX_ORDER:
            raise ValueError(
                f"order {self.order} is above {MAX_ORDER}: its R factor would not fit in "
                f"memory (seed 002 §III-A fits 4 states; more add nothing)"
            )
        if self.block_rows is not None:
            check_int("block_rows", self.block_rows, 2)
            if self.block_rows > MAX_BLOCK_ROWS:
                raise ValueError(
                    f"block_rows {self.block_rows} is above {MAX_BLOCK_ROWS}: the R factor of "
                    f"the Hankel matrices would not fit in memory"
                )
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
    u2, s2, vt2 = _pinv_parts(l22, rcond)  # L22^+ = V_r S_r^-1 U_r^T
    l32v = l32 @ vt2.T
    w1_pinv = None
    if weighting == "n4sid":
        mat = (l32v / s2) @ (u2.T @ np.hstack([l21, l22]))
    else:
        mat = l32v @ vt2  # L32 L22^+ L22 (W2 = Pi_{U_f}^perp), without S^-1 S
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


def _check_excitation(f: HankelFactor, order: int) -> None:
    """Refuse an input whose block-Hankel matrix has numerical rank below ``order + m``.

    Full rank ``2 i m`` (persistent excitation of order ``2 i``) is what the theory asks;
    smooth position commands sampled at 10 kHz never have it numerically (within 2 ms a
    jerk-limited move is a cubic: rank 4 per channel plus its jerk steps), yet the MOESP
    and CVA weightings identify from them to 1e-9 (tests). What is refused is an input that
    cannot excite ``order`` states beyond a constant per channel: a constant (rank ``m``),
    a single tone (``2 m``) for ``order > m``.
    """
    rank = f.input_rank(_PE_RTOL)
    need = order + f.n_inputs
    if rank < need:
        raise ValueError(
            f"the input is not exciting enough: its block-Hankel matrix (2 x {f.block_rows} "
            f"block rows) has numerical rank {rank}, below order + inputs = {need} (a "
            "constant or single-tone input cannot identify the dynamics); use a richer "
            "excitation"
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
    _check_excitation(f, max_order)
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
        Order, block rows, weighting, feed-through, ... (defaults: order 4, MOESP weighting).

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
