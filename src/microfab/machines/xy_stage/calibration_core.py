"""The XY stage twin on the calibration core: seed 002 Table II fitted, all magnitudes at once.

Issue 46 item 1. The twin's nonlinear and coupling magnitudes are assumed
(``data/xy_stage_twin.toml``: the seed gives none); here they are the free parameters of
one `microfab.calibrate.CalibrationProblem` (`problem`), fitted jointly to seed 002
Table II:

* **linear σ and μ per axis** (column 1: the 4-state model eq. 6 on its own training
  data, 600 s of random runs up to 5 m/s², §III-C.1, §III-D), measured as
  `microfab.machines.xy_stage.identify.fit_linear` measures them, on `XYCalData.linear_s`
  of the same kind of data;
* **the networks' σ per axis** (column 1 of the non-linear model: the validation data),
  through the proxy `microfab.machines.xy_stage.proxy.proxy_sigma` (a fixed
  random-feature ridge regression on the networks' own windows and split): training the
  networks inside the loop is far too slow. The proxy against the full training (whitened
  inputs, `microfab.identify.ann_whiten`): within 25 % on both axes of the calibrated twin
  (`microfab.machines.xy_stage.proxy`, checked on the shipped record by the suite).

Check held back (never fitted): the slowest time constant of the 4-state model, about
20 ms (seed 002 §III-B reading, `experiments/seed002_stage/paper.py`
SLOW_TIME_CONSTANT_S). Table III needs the two-stage trajectory optimisation and trained
networks per case: far beyond one model evaluation's budget, so it is left to the
reproduction (predicted there from the calibrated twin, never fitted).

The free magnitudes (`PARAMETERS`): the Coulomb friction per axis (its break-away force
and the LuGre bristle stiffness and damping follow in the ratios of the assumed twin:
``F_s = 1.5 F_c``, ``σ0 = F_c / 2 µm``, ``σ1 = 25 s/m × F_c``, so the pre-sliding law
stays; `twin_keys`), the cogging amplitude per axis, the y cable carrier's link ripple
and stiffness, the carriage resonance frequency, the y -> x reaction coupling, and the
acceleration feedforward of the built-in loop per axis (a black box in the seed).

**Why the feedforward is free.** A first run without it (8 parameters; 295 points) met 1
of 6 fit targets: over every point the proxy σ followed the linear σ (correlation 0.99,
proxy / linear at least 0.31 on x and 0.43 on y, the paper's 0.067 and 0.038): friction,
cogging and the cable raise what a linear model misses and what a network misses
together. The real stage's linear error is mostly predictable from its input window. A
mistuned feedforward is such an error: linear in the window, beyond a 4-state model
(measured at a fifth of the file's friction with no feedforward: linear σ 31.3 / 30.9 µm,
proxy 3.9 / 5.2 µm).

**Finding** (the shipped twin: ``calibrate(problem(), budget=120, seed=0, workers=2)``,
what ``microfab calibrate xy-stage --workers 2`` runs; 381 points asked, 338 evaluated,
2167 s on two cores shared with other work). Not converged: 1 of 6 fit targets met, at
Coulomb 5.8 / 8.2 N, cogging 8.7 / 0.75 N, cable ripple 2.6 N and spring 126 N/m,
resonance 165 Hz, coupling 0.012, feedforward 2.6 / 22.7 kg (about none on x, 2.3 times
y's 10 kg; no parameter at a bound): linear σ 29.4 / 41.7 µm (paper 48.0 / 156.3), proxy
σ 5.4 / 8.2 µm (3.2 / 6.0: within 2x), μ 0.4 / 0.7 µm (3.0 / -13.2); the τ check is
not met (40.7 ms for about 20).

* **linear σ against the networks' σ.** The proxy / linear ratio falls to 0.10 on x and
  0.14 on y (the first run: 0.31, 0.43), not to the paper's. Where the linear σ is met,
  the least proxy σ is 6.7 µm on x (6 points: 2.1x the paper) and 52.4 µm on y (94
  points: 8.7x); where the proxy σ is within 50 %, the largest linear σ is 30.4 µm on x
  and 55.1 µm on y. On x the twin nearly holds both; on y a large linear error that a
  network predicts to 6 µm needs more than a feedforward (the y loop's own dynamics, a
  larger input-determined nonlinearity: not in this twin).
* **linear μ.** Over every point μ stays within -2.7..0.5 µm on x and -0.6..1.1 µm on y;
  the paper's 3.0 / -13.2 µm needs a mean offset none of these forces makes (the core's
  conflict pair: μ_y against σ_y, best |r| 6.79 with σ_y met).

Each evaluation builds the twin from the candidate values through the same `TWIN_KEYS`
that `write_twin` uses (rounded to the digits written), so the model the search runs is
the file it writes.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.calibrate import CalibrationProblem, CalibrationResult, FreeParameter, Target
from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.core.provenance import Calibration, quantity
from microfab.core.threads import single_threaded
from microfab.core.validate import check_int, check_positive
from microfab.identify.excitation import ann_dataset, random_runs, split_runs
from microfab.machines.twins import data_path
from microfab.machines.xy_stage.ann import play_split
from microfab.machines.xy_stage.calibration import table_ii_quantity
from microfab.machines.xy_stage.identify import LINEAR_A_MAX, LinearSettings, fit_linear
from microfab.machines.xy_stage.machine import TwinSettings, play_runs
from microfab.machines.xy_stage.proxy import ProxySettings, proxy_sigma
from microfab.plants.xy_stage_params import AXES, XYStageParams, load_params

__all__ = [
    "CALIBRATION",
    "CHECK_NAMES",
    "COMMAND",
    "DATA_FILE",
    "DEFAULT_BUDGET",
    "FIT_NAMES",
    "PARAMETERS",
    "TWIN_KEYS",
    "XYCalData",
    "changes_of",
    "evaluate",
    "problem",
    "twin_keys",
    "write_twin",
]

COMMAND = "microfab calibrate xy-stage"
DATA_FILE = "xy_stage_twin.toml"

# seed 002 Table II (experiments/seed002_stage/paper.py TABLE_II), µm
_LINEAR_SIGMA_UM = (48.0, 156.3)  # linear, training data, σ x / y
_LINEAR_MU_UM = (3.0, -13.2)  # linear, training data, μ x / y
_ANN_SIGMA_UM = (3.2, 6.0)  # non-linear, validation data, σ x / y
_SLOW_TAU_MS = 20.0  # seed 002 §III-B reading: 500 ms history / 25

# Tolerances, beside the spread measured over the data seed (0, 1, 2) at the data file's
# twin on the default data (`XYCalData`): linear σ x 44.8-48.1, y 82.3-86.2 µm (±4 %);
# linear μ x -0.4..0.4, y 0.1..1.1 µm; proxy σ (before its `ProxySettings.recent`
# setting) x 22.9-33.0, y 45.1-60.9 µm (±20 %: three validation runs); τ 44-50 ms.
# σ linear: ±15 % (issue 46's band), about four times the spread. μ linear: ±2 µm, twice
# the spread (the seed states μ to 0.1 µm). Network σ: ±50 % (assumed: the issue's
# acceptance asks the networks within 2x of Table II; over twice the proxy's spread).
# τ: ±10 ms (assumed: the seed's "approximately 25 times" is a reading).
_SIGMA_BAND = 0.15
_MU_TOL_UM = 2.0
_ANN_BAND = 0.5
_TAU_TOL_MS = 10.0

#: Fit target names (model output keys), x then y, and the check's.
FIT_NAMES = (
    "linear_sigma_x_um",
    "linear_sigma_y_um",
    "linear_mu_x_um",
    "linear_mu_y_um",
    "proxy_sigma_x_um",
    "proxy_sigma_y_um",
)
CHECK_NAMES = ("slowest_time_constant_ms",)

#: What this calibration fits and holds back (`microfab.core.provenance`).
CALIBRATION = Calibration(
    command=COMMAND,
    data_file=DATA_FILE,
    targets=frozenset(
        table_ii_quantity(model, ax, "training", stat)
        for ax in AXES
        for model, stat in (("linear", "sigma"), ("linear", "mu"), ("ann", "sigma"))
    ),
    checks=frozenset({quantity("002", "§III-B", "slowest time constant")}),
    what=(
        "friction, cogging and the loop's acceleration feedforward per axis, cable ripple "
        "and stiffness, resonance, coupling"
    ),
    # the core's sources (`write_twin`); the retired fit's began otherwise
    # (`xy_stage.calibration.CALIBRATION`): the shipped file tells which one it holds
    marker=f"calibrated: `{COMMAND}`",
)

_T2 = "seed 002 Table II"


def _targets() -> tuple[Target, ...]:
    out = []
    for i, ax in enumerate(AXES):
        v = _LINEAR_SIGMA_UM[i]
        out.append(
            Target(
                f"linear_sigma_{ax}_um", v, _SIGMA_BAND * v, "µm",
                f"{_T2}: linear model, {ax}, training data, σ {v:g} µm. Tolerance ±15 % "
                "(issue 46's band)",
            )
        )  # fmt: skip
    for i, ax in enumerate(AXES):
        v = _LINEAR_MU_UM[i]
        out.append(
            Target(
                f"linear_mu_{ax}_um", v, _MU_TOL_UM, "µm",
                f"{_T2}: linear model, {ax}, training data, μ {v:g} µm. Tolerance ±2 µm: "
                "twice the spread over the data's seed at a fixed twin (measured)",
            )
        )  # fmt: skip
    for i, ax in enumerate(AXES):
        v = _ANN_SIGMA_UM[i]
        out.append(
            Target(
                f"proxy_sigma_{ax}_um", v, _ANN_BAND * v, "µm",
                f"{_T2}: non-linear model, {ax}, validation data, σ {v:g} µm, through the "
                "random-feature proxy (xy_stage.proxy). Tolerance ±50 % assumed: the "
                "issue's 2x acceptance for the networks",
            )
        )  # fmt: skip
    out.append(
        Target(
            CHECK_NAMES[0], _SLOW_TAU_MS, _TAU_TOL_MS, "ms",
            "seed 002 §III-B: the 500 ms input history is about 25 times the slowest mode "
            "of the linear model: about 20 ms. Tolerance ±10 ms assumed (a reading)",
            role="check",
        )
    )  # fmt: skip
    return tuple(out)


#: The free parameters, bounds assumed with the reason (the seed gives no magnitude).
PARAMETERS: tuple[FreeParameter, ...] = (
    FreeParameter(
        "coulomb_x_n",
        3.0,
        450.0,
        "N",
        "assumed: Coulomb friction of the x axis (30 kg moving) from a friction "
        "coefficient 0.01 (a clean rolling guide) to 1.5, far beyond any guided stage: "
        "wide enough that the search shows what Table II asks rather than stopping at a "
        "bound (the earlier per-axis fit needed 131 N, coefficient 1.3, on y)",
        log=True,
    ),
    FreeParameter(
        "coulomb_y_n",
        1.0,
        150.0,
        "N",
        "assumed: Coulomb friction of the y axis (10 kg moving), coefficient 0.01 to 1.5 "
        "(as x: the earlier fit needed 131 N for Table II's 156.3 µm)",
        log=True,
    ),
    FreeParameter(
        "cogging_x_n",
        1.5,
        75.0,
        "N",
        "assumed: cogging of the x motor, 0.1 % to 5 % of its 1500 N peak force (iron-core "
        "linear motors: about 1-5 %, less with skewed magnets)",
        log=True,
    ),
    FreeParameter(
        "cogging_y_n",
        0.5,
        25.0,
        "N",
        "assumed: cogging of the y motor, 0.1 % to 5 % of its 500 N peak force",
        log=True,
    ),
    FreeParameter(
        "cable_link_n",
        0.3,
        30.0,
        "N",
        "assumed: chain-link ripple of the y cable carrier, a tenth to ten times the file's 3 N",
        log=True,
    ),
    FreeParameter(
        "cable_stiffness_n_per_m",
        10.0,
        1000.0,
        "N/m",
        "assumed: spring of the y cable carrier, a tenth to ten times the file's 100 N/m",
        log=True,
    ),
    FreeParameter(
        "resonance_hz",
        100.0,
        200.0,
        "Hz",
        "assumed: the carriage resonance within issue 17's 100-200 Hz",
    ),
    FreeParameter(
        "feedforward_mass_x_kg",
        0.0,
        90.0,
        "kg",
        "assumed: the acceleration feedforward of the built-in x loop, which seed 002 "
        "§II-B keeps a black box: from none to three times the 30 kg that x moves (the "
        "file assumed 28 kg, tuned without the head). A mistuned feedforward leaves an "
        "error that is linear in the input window, so a network predicts it and a 4-state "
        "model does not (measured: with it off and friction a fifth of the file's, linear "
        "σ 31 µm against the proxy's 4 µm)",
    ),
    FreeParameter(
        "feedforward_mass_y_kg",
        0.0,
        30.0,
        "kg",
        "assumed: the acceleration feedforward of the built-in y loop, none to three times "
        "the 10 kg that y moves (as x; the file assumed 8 kg)",
    ),
    FreeParameter(
        "reaction_coupling",
        0.0,
        0.05,
        "1",
        "assumed: share of the y motor force reacting on x, none to 5 % (50 mrad of skew; "
        "seed 002 §III-B finds the coupling negligible)",
    ),
)

#: The assumed twin's ratios to the Coulomb force (xy_stage.calibration.REFERENCE):
#: break-away 1.5 F_c; σ0 = F_c / 2 µm; σ1 = 25 s/m × F_c (both axes alike).
_FRICTION_RATIOS = (
    ("static_n", 1.5),
    ("bristle_stiffness_n_per_m", 5.0e5),
    ("bristle_damping_n_s_per_m", 25.0),
)


def twin_keys() -> tuple[TwinKey, ...]:
    """Where each free parameter goes in ``xy_stage_twin.toml``."""
    keys: list[TwinKey] = []
    for ax in AXES:
        sec = f"axes.{ax}"
        keys.append(TwinKey(f"coulomb_{ax}_n", sec, "coulomb_n"))
        keys += [TwinKey(f"coulomb_{ax}_n", sec, k, scale=r) for k, r in _FRICTION_RATIOS]
        keys.append(TwinKey(f"cogging_{ax}_n", sec, "cogging_n"))
        keys.append(TwinKey(f"feedforward_mass_{ax}_kg", sec, "feedforward_mass_kg"))
    keys += [
        TwinKey("cable_link_n", "cable", "cable_link_force_n"),
        TwinKey("cable_stiffness_n_per_m", "cable", "cable_stiffness_n_per_m"),
        TwinKey("resonance_hz", "carriage", "resonance_hz"),
        TwinKey("reaction_coupling", "coupling", "reaction_coupling"),
    ]
    return tuple(keys)


#: `twin_keys`: one per file value the calibration writes.
TWIN_KEYS: tuple[TwinKey, ...] = twin_keys()


def changes_of(
    values: Mapping[str, float], base: XYStageParams | None = None
) -> tuple[tuple[str, Any], ...]:
    """`TwinSettings.changes` of one parameter set, through `TWIN_KEYS` (values as written).

    Parameters
    ----------
    values : mapping
        Parameter name -> value, each in its `PARAMETERS` unit.
    base : XYStageParams, optional
        The twin whose other axis values a per-axis key leaves (default the data file's).
    """
    cfg = load_params() if base is None else base
    per_axis: dict[str, list[float]] = {}
    flat: dict[str, float] = {}
    for k in TWIN_KEYS:
        v = float(f"{values[k.parameter] * k.scale:.{k.digits}g}")
        if k.section.startswith("axes."):
            row = per_axis.setdefault(k.key, list(getattr(cfg, k.key)))
            row[AXES.index(k.section.split(".")[1])] = v
        else:
            flat[k.key] = v
    out: list[tuple[str, Any]] = [(n, (r[0], r[1])) for n, r in sorted(per_axis.items())]
    return tuple(out + sorted(flat.items()))


@dataclass(frozen=True, kw_only=True)
class XYCalData:
    """The data one evaluation plays on the twin.

    Parameters
    ----------
    linear_s : float
        Random runs of the linear model, s (the seed: 600 s; default 60 s, measured on the
        file's twin, seed 0: σ 48.1 / 85.0 µm against 48.1 / 87.8 µm on 600 s).
    ann_s : float
        The networks' data (random runs and shapes, 80/20 split), s (the seed: about
        525 s; default 60 s, so that one evaluation costs about 15 s on one core).
    seed : int
        Seed of both data sets and of the twin's noise.
    proxy : ProxySettings
        The proxy regression.
    """

    linear_s: float = 60.0
    ann_s: float = 60.0
    seed: int = 0
    proxy: ProxySettings = field(default_factory=ProxySettings)

    def __post_init__(self) -> None:
        check_positive("linear_s", self.linear_s, "s")
        check_positive("ann_s", self.ann_s, "s")
        check_int("seed", self.seed, 0)


@functools.lru_cache(maxsize=4)
def _linear_runs(total_s: float, seed: int) -> tuple[Any, ...]:
    return tuple(random_runs(total_s, a_max=LINEAR_A_MAX, seed=seed))


@functools.lru_cache(maxsize=4)
def _ann_runs(total_s: float, seed: int) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
    # seed 002 §III-C: about 60 % random runs, 80 % / 20 % by whole runs (ann.AnnSettings)
    train, val = split_runs(ann_dataset(total_s, random_share=0.6, seed=seed), 0.2, seed=seed)
    if not train or not val:
        raise ValueError(
            f"ann_s = {total_s:g} s of the networks' data gives {len(train)} training and "
            f"{len(val)} validation runs; the proxy needs one of each: give more data"
        )
    return tuple(train), tuple(val)


@single_threaded
def evaluate(values: Mapping[str, float], *, data: XYCalData) -> dict[str, float]:
    """Model values of every target at one parameter set (the model of `problem`).

    Returns
    -------
    dict
        `FIT_NAMES` (µm) and `CHECK_NAMES` (ms); all NaN when the linear fit fails (an
        unstable identified model).
    """
    twin = TwinSettings(seed=data.seed, changes=changes_of(values))
    played = play_runs(_linear_runs(data.linear_s, data.seed), twin)
    nan = {n: float("nan") for n in (*FIT_NAMES, *CHECK_NAMES)}
    try:
        fit = fit_linear(played, LinearSettings(total_s=data.linear_s, seed=data.seed))
    except ValueError:
        return nan
    train, val = play_split(*_ann_runs(data.ann_s, data.seed), twin)
    px = proxy_sigma(train.records, val.records, train.dt, data.proxy)
    out = {
        "linear_sigma_x_um": float(fit.sigma_m[0]) * 1e6,
        "linear_sigma_y_um": float(fit.sigma_m[1]) * 1e6,
        "linear_mu_x_um": float(fit.mu_m[0]) * 1e6,
        "linear_mu_y_um": float(fit.mu_m[1]) * 1e6,
        "proxy_sigma_x_um": px[0] * 1e6,
        "proxy_sigma_y_um": px[1] * 1e6,
        CHECK_NAMES[0]: float(np.max(fit.model.time_constants_s())) * 1e3,
    }
    return out


def problem(data: XYCalData | None = None) -> CalibrationProblem:
    """The joint calibration of the XY stage twin to seed 002 Table II (module notes).

    Parameters
    ----------
    data : XYCalData, optional
        Data lengths and seed (default: 60 s each, seed 0).

    Returns
    -------
    CalibrationProblem
        Fit targets `FIT_NAMES`, check `CHECK_NAMES`, free `PARAMETERS`; its identity holds
        the packaged data file's SHA-256 and the data settings.

    Raises
    ------
    ValueError
        ``data.ann_s`` too short to leave one training and one validation run.
    """
    d = XYCalData() if data is None else data
    _ann_runs(d.ann_s, d.seed)  # too little data for a validation run: refused here, once
    digest = hashlib.sha256(data_path(DATA_FILE).read_bytes()).hexdigest()
    return CalibrationProblem(
        targets=_targets(),
        parameters=PARAMETERS,
        evaluate=functools.partial(evaluate, data=d),
        identity=f"{DATA_FILE} sha256 {digest}; data {d!r}",
    )


#: Evaluations of a real run (`calibrate`'s ``budget``). Measured: one evaluation on the
#: default data (`XYCalData`) takes 3-5 s on one core with one BLAS thread (60 s of linear
#: data played and fitted, 60 s of the networks' data played, the cross-validated proxy);
#: the shipped twin's run (10 parameters, budget 120, ``workers=2``, seed 0) asked 381
#: points (search and polish, sensitivity, conflict sweep), evaluated 338 and took 2167 s
#: on two cores shared with three other jobs (the first run, 8 parameters: 882 s).
DEFAULT_BUDGET = 120


def write_twin(
    result: CalibrationResult, path: str | Path, *, source: str | Path | None = None
) -> Path:
    """Write the twin data file with the calibrated values (atomically).

    Parameters
    ----------
    result : CalibrationResult
        A calibration of `problem`.
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to start from (default the packaged ``xy_stage_twin.toml``).

    Raises
    ------
    ValueError
        A result without this problem's parameters, or a file without the keys; nothing
        is written then.
    """
    return write_calibrated(
        result,
        TWIN_KEYS,
        command=COMMAND,
        data_file=DATA_FILE,
        path=path,
        source=None if source is None else str(source),
    )
