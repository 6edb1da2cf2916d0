"""The whole of seed 002 part 1 on the twin: data, both models, Table II, Fig. 9, the studies.

`run_study` is what the ``stage-identify`` job and ``microfab reproduce stage-models``
run. In order:

1. **Linear model** (§III-A, §III-C.1): random runs (600 s), played on the twin, eq. (6)
   fitted (`microfab.machines.xy_stage.identify.fit_linear`); its error on its own
   training data is Table II column 1. The order check (n = 2…8, one R factor,
   `microfab.machines.xy_stage.identify.order_check`) scores each order the same way,
   from rest.
2. **Networks** (§III-B, §III-C.2): about 60 % random runs and the rest regular shapes,
   80/20 split by whole runs, one network per axis
   (`microfab.machines.xy_stage.ann.train_networks`); the error on the validation runs
   is Table II column 1 of the non-linear model.
3. **Test cases** (`microfab.machines.xy_stage.cases.play_cases`): the letters and the
   airfoil at each ``a_max`` as time-optimal commands (the stand-in for the optimised
   inputs of part 2), played on the twin; both models' errors there. Table II columns
   2-3 pool the four letters at 1 and 3 m/s²; Fig. 9 is the network's σ against
   ``a_max`` for the letters and the airfoil.
4. **Coupling** (promised in §III-B): the same data, each network fed both axes'
   commands; its validation σ beside the per-axis networks'.
5. **Classic signals** (§III-C: PRBS and chirp "none of these proved adequate"): networks
   trained on PRBS and chirp runs of the same total length, scored on the letters.

Every training is resumable through its checkpoint directory. Errors are measured minus
predicted (the sign of Table II is not stated; ours is that of ``y - y_model``).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from microfab.experiments.kinds import Progress, no_progress
from microfab.geometry.text import SEED002_LETTERS
from microfab.identify.stage_data import RunErrors, StageRecord, decimate, rest_state
from microfab.machines.xy_stage.ann import (
    AnnSettings,
    ann_records,
    classic_records,
    train_networks,
)
from microfab.machines.xy_stage.cases import (
    AIRFOIL_TIME_S,
    R_TIME_S,
    CaseRun,
    CaseSizes,
    case_commands,
    case_sizes,
    play_cases,
)
from microfab.machines.xy_stage.identify import (
    LinearFit,
    LinearSettings,
    OrderRow,
    linear_study,
    order_check,
)
from microfab.machines.xy_stage.machine import TwinSettings
from microfab.plants.lti import DiscreteLTI

if TYPE_CHECKING:
    from microfab.identify.stage_ann import StageAnnFit

__all__ = [
    "MODEL_FOLDERS",
    "CaseSettings",
    "IdentifyStudy",
    "StudySettings",
    "run_study",
]

#: Table II's two a_max columns (lost in the text; Fig. 8 gives 1 and 3 m/s²).
TABLE_A_MAX = (1.0, 3.0)
#: Fig. 9's a_max values (the seed's axis is not legible; assumed: across and beyond the
#: 5 m/s² of the training data, §III-D, up to 8).
SWEEP_A_MAX = (0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)


@dataclass(frozen=True, kw_only=True)
class CaseSettings:
    """The test cases and their accelerations.

    Parameters
    ----------
    table_a_max : tuple of float
        Table II's columns, m/s² (seed: 1 and 3).
    sweep_a_max : tuple of float
        Fig. 9's points, m/s².
    r_time_s, airfoil_time_s : float
        The sizing step's targets (`cases`), s.
    """

    table_a_max: tuple[float, ...] = TABLE_A_MAX
    sweep_a_max: tuple[float, ...] = SWEEP_A_MAX
    r_time_s: float = R_TIME_S
    airfoil_time_s: float = AIRFOIL_TIME_S

    def __post_init__(self) -> None:
        for name in ("table_a_max", "sweep_a_max"):
            vals = tuple(float(v) for v in getattr(self, name))
            if any(not (0 < v <= 40.0) for v in vals):
                raise ValueError(
                    f"{name} values must lie in (0, 40] m/s² (Table I), got {list(vals)}"
                )
            object.__setattr__(self, name, vals)
        for name in ("r_time_s", "airfoil_time_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)!r} s")

    @property
    def a_max_values(self) -> tuple[float, ...]:
        """Every a_max played, sorted, once."""
        return tuple(sorted(set(self.table_a_max) | set(self.sweep_a_max)))


@dataclass(frozen=True, kw_only=True)
class StudySettings:
    """What `run_study` does.

    Parameters
    ----------
    twin : TwinSettings
        The twin and its noise seed (used by every part).
    linear : LinearSettings
        The linear model's data and fit (its own ``twin`` is replaced by ``twin``).
    orders : tuple of int
        The order check's orders (seed §III-A: beyond 4 "practically the same"); empty
        for none.
    ann : AnnSettings or None
        The networks (None: linear model only; the studies below need it).
    cases : CaseSettings
        Letters and airfoil.
    coupling : bool
        Train the both-axes networks (a second training).
    classic : bool
        Train networks on PRBS and chirp runs (a third training).
    """

    twin: TwinSettings = field(default_factory=TwinSettings)
    linear: LinearSettings = field(default_factory=LinearSettings)
    orders: tuple[int, ...] = (2, 3, 4, 5, 6, 7, 8)
    ann: AnnSettings | None = field(default_factory=AnnSettings)
    cases: CaseSettings = field(default_factory=CaseSettings)
    coupling: bool = True
    classic: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "orders", tuple(int(n) for n in self.orders))
        if any(n < 1 for n in self.orders):
            raise ValueError(f"orders must be >= 1, got {list(self.orders)}")
        if self.ann is None and (self.coupling or self.classic):
            raise ValueError("the coupling and classic studies need the networks (ann)")


@dataclass(frozen=True, kw_only=True, eq=False)
class ModelCurves:
    """What the report draws of the fitted models, computed in the run.

    Attributes
    ----------
    freq_hz : numpy.ndarray
        Frequencies of the responses, Hz, shape (k,).
    response : dict of str to numpy.ndarray
        ``"model"`` (the fitted linear model) and ``"twin (linear)"`` (the twin with its
        nonlinear parts off): complex response, shape (k, 2, 2).
    time_s : numpy.ndarray or None
        Sample times of the validation example, s (None without networks).
    measured : numpy.ndarray or None
        Its measured output, m, shape (n, 2).
    predictions : dict of str to (numpy.ndarray, numpy.ndarray)
        Per model (``"linear"`` at its decimated rate, ``"ANN"`` at every sample): times,
        s, and predicted output, m.
    """

    freq_hz: np.ndarray
    response: dict[str, np.ndarray]
    time_s: np.ndarray | None = None
    measured: np.ndarray | None = None
    predictions: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


def model_curves(
    twin: TwinSettings, linear: LinearFit, ann: StageAnnFit | None, rec: StageRecord | None
) -> ModelCurves:
    """The fitted models' curves for the report (`ModelCurves`).

    The frequency responses of the fitted model and of the linear twin; the validation
    example predicted by the linear model (from rest, at its decimated rate) and by the
    networks.
    """
    m = linear.model
    fs = np.geomspace(0.5, 0.45 / m.dt, 300)
    response = {
        "model": DiscreteLTI(A=m.a, B=m.b, C=m.c, D=m.d, dt=m.dt).frequency_response(fs),
        "twin (linear)": twin.twin().linear_model().frequency_response(fs),
    }
    if rec is None or ann is None:
        return ModelCurves(freq_hz=fs, response=response)
    q = linear.decimate
    dt = m.dt / q
    t = np.arange(rec.u.shape[0]) * dt
    ud = decimate(rec.u, q)
    y_lin = m.simulate(ud, rest_state(m, ud[0]))
    preds = {
        "linear": (np.arange(ud.shape[0]) * dt * q, y_lin),
        "ANN": (t, ann.model.predict(rec.u, at="10khz")),
    }
    return ModelCurves(freq_hz=fs, response=response, time_s=t, measured=rec.y,
                       predictions=preds)  # fmt: skip


@dataclass(frozen=True, eq=False)
class IdentifyStudy:
    """Everything `run_study` measured (see the module docstring).

    Attributes
    ----------
    settings : StudySettings
    linear : LinearFit
        The model and its error on its training data (Table II column 1).
    linear_limited : int
        Guard-limited samples over the linear data (0 within Table I).
    orders : tuple of OrderRow
    singular_values : numpy.ndarray
        Of the order check's projection (empty without it).
    ann : StageAnnFit or None
    ann_validation : RunErrors or None
        The networks' errors on the validation runs, samples kept (Fig. 8a).
    linear_on_validation : RunErrors or None
        The linear model on the same validation runs.
    coupled, classic : StageAnnFit or None
        The both-axes and the PRBS/chirp-trained networks.
    sizes : CaseSizes
    cases : tuple of CaseRun
    example_runs : tuple of (str, numpy.ndarray)
        Name and command (n, 2), m, of a few of the networks' runs (Fig. 6), or of the
        linear data's.
    validation_example : StageRecord or None
        One validation run (measured vs models figure).
    seconds : dict of str to float
        Wall time of each part.
    curves : ModelCurves or None
        The fitted models' frequency responses and their prediction of the validation
        run, computed here so that the report only draws.
    """

    settings: StudySettings
    linear: LinearFit
    linear_limited: int
    orders: tuple[OrderRow, ...]
    singular_values: np.ndarray
    ann: StageAnnFit | None
    ann_validation: RunErrors | None
    linear_on_validation: RunErrors | None
    coupled: StageAnnFit | None
    classic: StageAnnFit | None
    sizes: CaseSizes
    cases: tuple[CaseRun, ...]
    example_runs: tuple[tuple[str, np.ndarray], ...]
    validation_example: StageRecord | None
    seconds: dict[str, float]
    curves: ModelCurves | None = None

    def case(self, name: str, a_max: float) -> CaseRun:
        """The run of ``name`` at ``a_max``."""
        return case_run(self.cases, name, a_max)

    def letters(self, a_max: float, model: str = "linear") -> RunErrors | None:
        """One model's errors pooled over the four letters at ``a_max`` (Table II)."""
        return pooled_letters(self.cases, a_max, model)

    def durations(self, a_max: float) -> dict[str, float]:
        """Each case's command length at ``a_max``, s."""
        return {c.case: c.duration_s for c in self.cases if abs(c.a_max - a_max) < 1e-12}


def case_run(cases: Sequence[CaseRun], name: str, a_max: float) -> CaseRun:
    """The run of case ``name`` at ``a_max`` among ``cases``."""
    for c in cases:
        if c.case == name and abs(c.a_max - a_max) < 1e-12:
            return c
    raise KeyError(f"no run of case {name!r} at a_max {a_max:g} m/s²")


def pooled_letters(cases: Sequence[CaseRun], a_max: float, model: str) -> RunErrors | None:
    """``model``'s errors pooled over the four letters at ``a_max`` (Table II), or None."""
    parts = [case_run(cases, ch, a_max).errors.get(model) for ch in SEED002_LETTERS]
    if any(p is None for p in parts):
        return None
    return RunErrors.pooled(parts)


#: Folder of each trained model (and of its checkpoints) under a study's output folder.
MODEL_FOLDERS = {"ann": "ann", "coupled": "ann_coupled", "classic": "ann_classic"}


def _train_dir(out: Path | None, name: str) -> Path | None:
    return None if out is None else out / MODEL_FOLDERS[name] / "checkpoints"


def _ann_progress(progress: Progress, task: str, max_epochs: int) -> Any:
    def report(rec: Any) -> None:
        progress(f"{task}, axis {rec.axis}", int(rec.epoch), max_epochs)

    return report


def run_study(
    settings: StudySettings | None = None,
    out: str | Path | None = None,
    progress: Progress = no_progress,
) -> IdentifyStudy:
    """Run the study (module docstring); trainings checkpoint under ``out`` and resume.

    Raises
    ------
    ValueError
        From the fits (non-exciting data, unstable model) or the cases.
    """
    s = StudySettings() if settings is None else settings
    out_dir = None if out is None else Path(out)
    seconds: dict[str, float] = {}

    t0 = time.perf_counter()
    progress("linear model: data on the twin and subspace fit", 0, None)
    lin_s = dataclasses.replace(s.linear, twin=s.twin)
    played, linear = linear_study(lin_s)
    seconds["linear"] = time.perf_counter() - t0
    if s.orders:
        progress("linear model: order check", 0, None)
    orders, sv = order_check(played, lin_s, s.orders)
    seconds["order check"] = time.perf_counter() - t0 - seconds["linear"]
    example_runs = tuple((r.name, r.u) for r in played.records[:6])

    ann = coupled = classic = None
    ann_val = lin_val = None
    val_example = None
    if s.ann is not None:
        a = dataclasses.replace(s.ann, twin=s.twin)
        t1 = time.perf_counter()
        progress("networks: data on the twin", 0, None)
        train, val = ann_records(a)
        example_runs = _fig6_commands([*train.records, *val.records])
        ann = train_networks(
            train, val, a,
            checkpoint_dir=_train_dir(out_dir, "ann"),
            progress=_ann_progress(progress, "networks", a.max_epochs),
        )  # fmt: skip
        ann_val = ann.errors
        lin_val = linear.stage_model().errors(val.records, keep=True)
        val_example = val.records[0]
        seconds["networks"] = time.perf_counter() - t1
        if s.coupling:
            t1 = time.perf_counter()
            coupled = train_networks(
                train, val, a, inputs="both",
                checkpoint_dir=_train_dir(out_dir, "coupled"),
                progress=_ann_progress(progress, "coupling networks", a.max_epochs),
            )  # fmt: skip
            seconds["coupling networks"] = time.perf_counter() - t1
        if s.classic:
            t1 = time.perf_counter()
            progress("PRBS/chirp networks: data on the twin", 0, None)
            classic = train_networks(
                *classic_records(a), a,
                checkpoint_dir=_train_dir(out_dir, "classic"),
                progress=_ann_progress(progress, "PRBS/chirp networks", a.max_epochs),
            )  # fmt: skip
            seconds["PRBS/chirp networks"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    models = {"linear": linear.stage_model(), "ann": _stage(ann), "coupled": _stage(coupled),
              "classic": _stage(classic)}  # fmt: skip
    sizes, cases = study_cases(s, models, s.cases.a_max_values, progress=progress)
    seconds["test cases"] = time.perf_counter() - t1
    return IdentifyStudy(
        settings=s,
        linear=linear,
        linear_limited=int(sum(played.limited)),
        orders=orders,
        singular_values=sv,
        ann=ann,
        ann_validation=ann_val,
        linear_on_validation=lin_val,
        coupled=coupled,
        classic=classic,
        sizes=sizes,
        cases=cases,
        example_runs=example_runs,
        validation_example=val_example,
        seconds=seconds,
        curves=model_curves(s.twin, linear, ann, val_example),
    )


def study_cases(
    settings: StudySettings,
    models: dict[str, Any],
    a_values: Sequence[float],
    names: Sequence[str] | None = None,
    progress: Progress = no_progress,
) -> tuple[CaseSizes, tuple[CaseRun, ...]]:
    """The test cases of step 3 (module docstring): sized, planned, played, scored.

    ``models`` maps a name to a stage model (``errors(records, keep=True)``) or None;
    ``names`` defaults to every case. The twin's noise seeds sit 20 000 above the
    study's (assumed: apart from the training and validation runs').
    """
    s = settings
    progress("test cases: sizes", 0, None)
    sizes = case_sizes(s.cases.r_time_s, s.cases.airfoil_time_s)
    commands = case_commands(
        sizes, a_values, **({} if names is None else {"names": tuple(names)}),
        progress=lambda i, n: progress("test cases: references", i, n),
    )  # fmt: skip
    progress("test cases: on the twin", 0, None)
    twin = dataclasses.replace(s.twin, seed=s.twin.seed + 20_000)
    return sizes, play_cases(commands, twin, models)


def _fig6_commands(records: Sequence[StageRecord]) -> tuple[tuple[str, np.ndarray], ...]:
    """Five random runs and one shape (a spiral if any) of the networks' data (Fig. 6)."""
    rand = [r for r in records if r.name.startswith("random")][:5]
    shapes = [r for r in records if r.name.startswith("shape")]
    spiral = [r for r in shapes if "spiral" in r.name][:1] or shapes[:1]
    return tuple((r.name, r.u) for r in rand + spiral)


def _stage(fit: StageAnnFit | None) -> Any:
    """The networks of a training as a stage model, or None."""
    from microfab.identify.stage_ann import StageAnnModel

    return None if fit is None else StageAnnModel(fit.model)
