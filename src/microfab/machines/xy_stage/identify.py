"""Identification runs on the XY stage twin: random runs played, the linear model fitted.

What ``microfab calibrate xy-stage`` (`microfab.machines.xy_stage.calibration_core`) and the
seed 002 reproductions run on the twin (`microfab.machines.xy_stage.play_runs`): seeded
random runs (`microfab.identify.excitation.random_runs`, seed 002 §III-C.1), played from
rest, and eq. (6) fitted to them by `microfab.identify.stage_data.fit_linear`, the same
function ``microfab identify linear`` runs on measured files:

* **Decimation.** At 10 kHz the slowest modes (≈20 ms, §III-B) sit at ``z ≈ 0.995`` and a
  four-state subspace fit is ill-conditioned on this data (its ``A`` came out unstable).
  Input and output are both decimated by ``decimate`` (default 10, to 1 kHz) with the
  same zero-phase FIR anti-alias filter (`scipy.signal.decimate`, ``ftype="fir"``); the
  same linear filter on both sides keeps the input-output relation of an LTI model.
* **Feedthrough.** Eq. (6b) writes ``γ = C z + D ρ``. On the twin, whose built-in loop
  tracks within microns, ``D = 0`` (MATLAB ``n4sid``'s default) gave σ ≈ 210 µm per axis
  at order 4, while ``D`` free gives σ near the nonlinear floor; so ``D`` is estimated.

Prediction errors are the measured output minus the model's, on the decimated records,
each run simulated from the model's rest state under its first input
(`stage_data.run_errors`); μ and σ are their mean and standard deviation per axis
(seed 002 Table II). `linear_order_scan` fits every order of the order check (seed 002
§III-A) from one R factor; `linear_checks` measures the twin's linear-model figures (σ,
tracking error, slowest time constant, the order scan) for the calibration's checks;
`order_check` scores each order of the scan from rest (the ``stage-identify`` job).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.identify import stage_data
from microfab.identify.excitation import random_runs
from microfab.identify.subspace import OrderScan, SubspaceConfig, SubspaceModel, order_scan
from microfab.machines.xy_stage.machine import Played, TwinSettings, play_runs

__all__ = [
    "LINEAR_A_MAX",
    "LINEAR_ORDER",
    "LINEAR_TOTAL_S",
    "LinearChecks",
    "LinearFit",
    "LinearSettings",
    "OrderRow",
    "fit_linear",
    "linear_checks",
    "linear_order_scan",
    "linear_study",
    "order_check",
]

#: Random-run data of the linear model, s: seed 002 §III-C.1, 6×10⁶ points at the 10 kHz
#: loop of Table I (``experiments/seed002_stage/paper.py``: LINEAR_SAMPLES / LOOP_RATE_HZ).
LINEAR_TOTAL_S = 6_000_000 / 10_000.0
#: Largest acceleration of that data, m/s² (seed 002 §III-D: "up to 5 m s^-2").
LINEAR_A_MAX = 5.0
#: States of eq. (6) (seed 002 §III-A: z in R^4).
LINEAR_ORDER = 4


@dataclass(frozen=True, kw_only=True)
class LinearSettings:
    """The linear model's data and fit (seed 002 §III-A, §III-C.1).

    Parameters
    ----------
    total_s : float
        Random-run data, s (seed §III-C.1: 6×10⁶ samples, 600 s at 10 kHz).
    a_max : float
        Largest acceleration of the runs, m/s² (seed §III-D: up to 5).
    order : int
        States (seed §III-A: 4).
    decimate : int
        Decimation before the fit (module doc; 10: to 1 kHz).
    feedthrough : bool
        Estimate ``D`` (module doc).
    block_rows : int, optional
        Hankel block rows (default `SubspaceConfig`'s).
    seed : int
        Seed of the random runs.
    """

    total_s: float = LINEAR_TOTAL_S  # seed 002 §III-C.1
    a_max: float = LINEAR_A_MAX  # seed 002 §III-D
    order: int = LINEAR_ORDER  # seed 002 §III-A
    decimate: int = 10  # assumed, module doc
    feedthrough: bool = True  # module doc
    block_rows: int | None = None
    seed: int = 0
    twin: TwinSettings = field(default_factory=TwinSettings)

    def __post_init__(self) -> None:
        if not self.total_s > 0:
            raise ValueError(f"total_s must be positive, got {self.total_s!r} s")
        if not isinstance(self.decimate, int) or self.decimate < 1:
            raise ValueError(f"decimate must be an integer >= 1, got {self.decimate!r}")


@dataclass(frozen=True, eq=False)
class LinearFit:
    """The linear model and its errors on its own training data.

    Attributes
    ----------
    model : SubspaceModel
        At the decimated rate.
    mu_m, sigma_m : numpy.ndarray
        Mean and standard deviation of the prediction error per axis (x, y), m.
    n_samples : int
        Samples of training data at 10 kHz.
    decimate : int
        Decimation factor used.
    """

    model: SubspaceModel
    mu_m: np.ndarray
    sigma_m: np.ndarray
    n_samples: int
    decimate: int

    def stage_model(self) -> stage_data.StageLinearModel:
        """The model as ``microfab identify linear`` writes and ``identify validate`` reads it."""
        dt = self.model.dt / self.decimate
        return stage_data.StageLinearModel(model=self.model, input_dt=dt, decimate=self.decimate)


def fit_linear(played: Played, settings: LinearSettings | None = None) -> LinearFit:
    """Fit eq. (6) to the played runs and measure it on them (module doc).

    Raises
    ------
    ValueError
        From the subspace fit: too little excitation, an order above the block rows, an
        unstable ``A``.
    """
    s = LinearSettings() if settings is None else settings
    model = stage_data.fit_linear(
        played.records,
        played.dt,
        order=s.order,
        decimate=s.decimate,
        feedthrough=s.feedthrough,
        block_rows=s.block_rows,
    )
    err = stage_data.run_errors(model, played.records, s.decimate)
    return LinearFit(
        model=model,
        mu_m=err.mean,
        sigma_m=err.std,
        n_samples=int(sum(r.n_samples for r in played.records)),
        decimate=s.decimate,
    )


def linear_study(settings: LinearSettings | None = None) -> tuple[Played, LinearFit]:
    """Random runs (§III-C.1), played on the twin, and the linear model fitted to them."""
    s = LinearSettings() if settings is None else settings
    runs = random_runs(s.total_s, a_max=s.a_max, seed=s.seed)
    played = play_runs(runs, s.twin)
    return played, fit_linear(played, s)


def linear_order_scan(played: Played, settings: LinearSettings, orders: Sequence[int]) -> OrderScan:
    """Eq. (6) at each of ``orders`` on the played runs, from one R factor (seed §III-A).

    The runs are decimated and fitted as by `fit_linear` (its ``decimate`` and
    ``feedthrough``; `microfab.identify.subspace.order_scan`).
    """
    q = settings.decimate
    data = [(stage_data.decimate(r.u, q), stage_data.decimate(r.y, q)) for r in played.records]
    cfg = SubspaceConfig(feedthrough=settings.feedthrough)
    return order_scan(data, played.dt * q, tuple(orders), cfg)


@dataclass(frozen=True)
class OrderRow:
    """One order of the order check: σ (x, y) from rest on the training data, m."""

    order: int
    singular_ratio: float
    sigma_m: tuple[float, float]


def order_check(
    played: Played, settings: LinearSettings, orders: Sequence[int]
) -> tuple[tuple[OrderRow, ...], np.ndarray]:
    """Each order of ``orders`` fitted (`linear_order_scan`) and scored from rest.

    Every model is simulated on the played runs from its rest state
    (`microfab.identify.stage_data.run_errors`), as `fit_linear` scores the chosen order.

    Returns
    -------
    (tuple of OrderRow, numpy.ndarray)
        A row per order and the projection's singular values (both empty for no orders).
    """
    if not orders:
        return (), np.zeros(0)
    scan = linear_order_scan(played, settings, orders)
    rows = []
    for n, model, (_, ratio, _) in zip(scan.orders, scan.models, scan.rows(), strict=True):
        err = stage_data.run_errors(model, played.records, settings.decimate)
        rows.append(OrderRow(n, ratio, (float(err.std[0]), float(err.std[1]))))
    return tuple(rows), np.asarray(scan.singular_values)


@dataclass(frozen=True, kw_only=True)
class LinearChecks:
    """What `linear_checks` measured on one data set (nothing here is fitted).

    Attributes
    ----------
    total_s : float
        Random-run data, s.
    sigma_m, mu_m : tuple of float
        The 4-state model's σ and μ on it (x, y), m (Table II column 1).
    tracking_sigma_m : tuple of float
        σ of measured minus command, (x, y), m: the stage's own tracking error.
    slowest_time_constant_s : float
        Of the 4-state model (§III-B reading: about 20 ms).
    orders : tuple of int
        Orders of the order scan.
    order_sigma_m : numpy.ndarray
        Shape (n_orders, 2): σ per order and axis, m.
    """

    total_s: float
    sigma_m: tuple[float, float]
    mu_m: tuple[float, float]
    tracking_sigma_m: tuple[float, float]
    slowest_time_constant_s: float
    orders: tuple[int, ...]
    order_sigma_m: np.ndarray = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (µm, ms)."""
        return {
            "total_s": self.total_s,
            "sigma_um": [v * 1e6 for v in self.sigma_m],
            "mu_um": [v * 1e6 for v in self.mu_m],
            "tracking_sigma_um": [v * 1e6 for v in self.tracking_sigma_m],
            "slowest_time_constant_ms": self.slowest_time_constant_s * 1e3,
            "order_scan_sigma_um": {
                str(n): [float(v) * 1e6 for v in row]
                for n, row in zip(self.orders, self.order_sigma_m, strict=True)
            },
        }


def linear_checks(
    total_s: float = LINEAR_TOTAL_S,
    *,
    seed: int = 0,
    changes: tuple[tuple[str, Any], ...] = (),
    orders: Sequence[int] = range(2, 9),
) -> LinearChecks:
    """Measure the twin's linear-model figures on ``total_s`` of seeded random data.

    Parameters
    ----------
    total_s : float
        Data, s (default the seed's 6×10⁶ samples, 600 s).
    seed : int
        Seed of the runs and the noise.
    changes : tuple of (str, value)
        Twin changes (default: the data file's twin, i.e. the calibrated one).
    orders : sequence of int
        Orders of the order scan (seed §III-A: 2..8; empty: no scan).
    """
    lin = LinearSettings(total_s=total_s, seed=seed)
    played = play_runs(
        random_runs(total_s, a_max=lin.a_max, seed=seed), TwinSettings(seed=seed, changes=changes)
    )
    fit = fit_linear(played, lin)
    err = np.concatenate([r.y - r.u for r in played.records])
    ords = tuple(orders)
    if ords:
        order_sigma = np.asarray(linear_order_scan(played, lin, ords).fit_std, dtype=float)
    else:
        order_sigma = np.zeros((0, 2))
    return LinearChecks(
        total_s=total_s,
        sigma_m=(float(fit.sigma_m[0]), float(fit.sigma_m[1])),
        mu_m=(float(fit.mu_m[0]), float(fit.mu_m[1])),
        tracking_sigma_m=tuple(float(v) for v in err.std(axis=0)),  # type: ignore[arg-type]
        slowest_time_constant_s=float(np.max(fit.model.time_constants_s())),
        orders=ords,
        order_sigma_m=order_sigma,
    )
