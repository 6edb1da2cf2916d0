"""Measured runs of the black-box XY stage and the linear model fitted to them (seed 002).

What ``microfab identify linear`` and ``identify validate`` (`cli/identify.py`) do on
measured data, as a library:

* `stage_record`: one run read from a trace (``time``, ``input_x``, ``input_y``,
  ``output_x``, ``output_y``, m), checked: a rate that is a multiple of 400 Hz (the ANN's
  rate, seed 002 §III-B, so the same files serve both models), at least 500 ms (the ANN's
  input history, §III-B), every input inside Table I's workspace, every output within 1 m.
  The trace itself has already refused NaN and a non-uniform or non-increasing time
  (`Trace.from_columns`). With `StageRecord` and `RunErrors` it lives in
  `microfab.identify.stage_runs`, below this module and `microfab.identify.stage_ann`,
  and is re-exported here.
* `decimate`: the anti-alias filter and down-sampling applied identically to inputs and
  outputs before the fit.
* `fit_linear`: seed 002 eq. (6) by `identify_subspace` on the decimated runs, default
  order 4, decimation to about 1 kHz (`default_decimate`: 10 for 10 kHz runs) and
  feed-through on.
* `run_errors`: the simulation error ``y - y_model`` of a model from rest, per axis
  (Table II's μ, σ).
* `StageLinearModel`, `write_stage_model`, `read_stage_model`: the model file (JSON),
  which carries the rate of the runs it was fitted to and its decimation (so that
  `StageLinearModel.continuous` converts to continuous time for inputs held at the runs'
  rate, not at the decimated one: `microfab.identify.subspace_model`), and whose
  reader dispatches on ``"kind"`` (`MODEL_KINDS`): ``"linear"`` (this file's JSON) or
  ``"ann"`` (a directory written by ``identify ann``, read by `microfab.identify.stage_ann`).

Why decimate by 10, and why feed-through (both measured on the twin, 20-600 s of random
runs): at 10 kHz the slowest poles sit within 5e-3 of z = 1 and the order-4 fit is
ill-conditioned (A came out unstable on 600 s); at 1 kHz the same data give the twin's
poles. With D = 0 (MATLAB ``n4sid``'s default, ``'Feedthrough'`` false) the order-4 fit
misses by σ ≈ 210-330 µm on data where the output follows the input within 9/17 µm;
with D, as eq. (6b) writes it, σ ≈ 8/15-17 µm. A 4-state model cannot hold both the
near-unit static path (the built-in loop's feedforward makes y ≈ ρ) and the slow modes
without it.

Anti-alias filter (`decimate`): the FIR of ``scipy.signal.decimate(x, q, ftype="fir",
zero_phase=True)``, order ``20 q`` (``firwin(20 q + 1, 1 / q)``, Hamming window, cut-off
at the new Nyquist frequency), applied zero-phase by ``scipy.signal.resample_poly``; the
ends are held (edge padding) instead of scipy's zeros, since a run starts and ends at
rest, possibly away from the origin. Sample ``k`` of the result is at input sample
``k q``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
import scipy.signal
from pydantic import BaseModel, ConfigDict, Field

from microfab.core.validate import check_int, check_positive
from microfab.identify.stage_runs import (
    AXES,
    BASE_RATE_HZ,
    COLUMNS,
    MIN_RUN_S,
    RunErrors,
    StageRecord,
    check_rate,
    stage_record,
)
from microfab.identify.subspace import SubspaceConfig, identify_subspace
from microfab.identify.subspace_data import IORun
from microfab.identify.subspace_model import ContinuousModel, SubspaceModel
from microfab.io.atomic import atomic_write_json
from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import read_json, validated

__all__ = [
    "AXES",
    "BASE_RATE_HZ",
    "COLUMNS",
    "FIT_RATE_HZ",
    "FORMAT",
    "MIN_RUN_S",
    "MODEL_KINDS",
    "STAGE_MODEL_KIND",
    "VERSION",
    "RunErrors",
    "StageLinearDoc",
    "StageLinearModel",
    "StageRecord",
    "check_decimate",
    "decimate",
    "default_decimate",
    "fit_linear",
    "read_stage_model",
    "rest_state",
    "run_errors",
    "stage_model_from_dict",
    "stage_record",
    "write_stage_model",
]

#: Rate the linear fit runs at by default, Hz: runs are decimated to about this (measured
#: on the twin: at 10 kHz the 20 ms modes sit at z ~ 0.995 and the 4-state fit is
#: ill-conditioned; at 1 kHz it is not; module docstring). 10 kHz runs: decimate by 10.
FIT_RATE_HZ = 1000.0
#: Slowest rate a linear model is fitted at, Hz (assumed: the ANN's 400 Hz; the twin's
#: built-in loop pair at 25 Hz and its 150 Hz y resonance stay below its Nyquist).
MIN_MODEL_RATE_HZ = BASE_RATE_HZ
FORMAT = "microfab.identify.StageModel"
VERSION = 1


def default_decimate(rate_hz: float) -> int:
    """The decimation that takes runs at ``rate_hz`` to about `FIT_RATE_HZ` (at least 1)."""
    return max(1, round(rate_hz / FIT_RATE_HZ))


def check_decimate(q: int, rate_hz: float) -> int:
    """``q`` if a whole number >= 1 leaving at least `MIN_MODEL_RATE_HZ`; else ValueError."""
    check_int("decimate", q, 1)
    if rate_hz / q < MIN_MODEL_RATE_HZ * (1.0 - 1e-9):
        raise ValueError(
            f"decimate {q} takes {rate_hz:.6g} Hz to {rate_hz / q:.6g} Hz, below "
            f"{MIN_MODEL_RATE_HZ:g} Hz; use decimate <= {int(rate_hz // MIN_MODEL_RATE_HZ)}"
        )
    return int(q)


def decimate(x: np.ndarray, q: int) -> np.ndarray:
    """Anti-alias filter and keep every ``q``-th sample, zero phase, ends held.

    Parameters
    ----------
    x : numpy.ndarray
        Samples, shape (n,) or (n, channels).
    q : int
        Factor (>= 1; 1 returns a copy).

    Returns
    -------
    numpy.ndarray
        Shape ``(ceil(n / q), ...)``; sample ``k`` at input sample ``k q``. The filter is
        the FIR of ``scipy.signal.decimate(ftype="fir", zero_phase=True)`` (module
        docstring), with edge padding.
    """
    check_int("q", q, 1)
    a = np.asarray(x, dtype=np.float64)
    if q == 1:
        return a.copy()
    taps = scipy.signal.firwin(20 * q + 1, 1.0 / q, window="hamming")
    return scipy.signal.resample_poly(a, 1, q, axis=0, window=taps, padtype="edge")


def _decimated(records: Sequence[StageRecord], q: int) -> list[IORun]:
    return [IORun(decimate(r.u, q), decimate(r.y, q)) for r in records]


def _as_records(records: Any) -> list[StageRecord]:
    if isinstance(records, StageRecord | tuple):
        records = [records]
    out = []
    for i, r in enumerate(records):
        if isinstance(r, StageRecord):
            out.append(r)
        else:
            u, y = r
            out.append(StageRecord(name=f"run {i}", u=u, y=y))
    if not out:
        raise ValueError("no runs given: at least one measured run is needed")
    return out


def fit_linear(
    records: Any,
    dt: float,
    *,
    order: int = 4,
    decimate: int | None = None,
    feedthrough: bool = True,
    block_rows: int | None = None,
    weighting: str = "moesp",
    workers: int = 2,
) -> SubspaceModel:
    """Seed 002 eq. (6) fitted to measured runs, after the anti-alias decimation.

    Parameters
    ----------
    records : StageRecord, (u, y) pair, or a sequence of them
        Runs from rest, u and y shapes (n, 2), m, all at ``dt``.
    dt : float
        Sample time of the runs, s (its rate a multiple of 400 Hz).
    order : int
        States (seed 002 §III-A: 4).
    decimate : int, optional
        Factor applied identically to inputs and outputs first (default
        `default_decimate`: to about `FIT_RATE_HZ`, 10 for 10 kHz runs; module docstring).
    feedthrough : bool
        Estimate D (default True: eq. (6b) writes it; MATLAB ``n4sid`` defaults to D = 0).
    block_rows, weighting, workers
        As `SubspaceConfig` (block rows default ``2 order + 2``, MOESP).

    Returns
    -------
    SubspaceModel
        Discrete, at ``dt * decimate``.

    Raises
    ------
    ValueError
        A bad rate or factor, an order below 1 or above the block rows, a non-exciting
        input, an unstable identified A.
    """
    recs = _as_records(records)
    rate = check_rate(dt)
    q = check_decimate(default_decimate(rate) if decimate is None else decimate, rate)
    cfg = SubspaceConfig(
        order=order,
        block_rows=block_rows,
        weighting=weighting,  # type: ignore[arg-type]
        feedthrough=feedthrough,
        workers=workers,
    )
    return identify_subspace(_decimated(recs, q), dt * q, cfg)


def rest_state(model: SubspaceModel, u0: np.ndarray) -> np.ndarray:
    """The model's steady state under a constant input ``u0`` (a run from rest), shape (n,).

    ``x = (I - A)^{-1} B u0``; A is stable (the fit refuses an unstable one).
    """
    eye = np.eye(model.order)
    return np.linalg.solve(eye - model.a, model.b @ np.asarray(u0, dtype=np.float64))


def run_errors(
    model: SubspaceModel, records: Any, decimate: int, *, keep: bool = False
) -> RunErrors:
    """Simulation error of a linear model on runs from rest, at the model's own rate.

    Each run is decimated by ``decimate`` (as in `fit_linear`) and simulated from the
    model's steady state under its first input (`rest_state`).

    Parameters
    ----------
    model : SubspaceModel
        At ``dt * decimate`` of the runs.
    records : StageRecord, (u, y) pair, or a sequence of them
        Runs from rest, m.
    decimate : int
        Factor the model was fitted after.
    keep : bool
        Keep every error sample (`RunErrors.samples`).

    Returns
    -------
    RunErrors
    """
    recs = _as_records(records)
    check_int("decimate", decimate, 1)
    errors = (
        (rec.name, model.prediction_error(run.u, run.y, rest_state(model, run.u[0])))
        for rec, run in zip(recs, _decimated(recs, decimate), strict=True)
    )
    return RunErrors.of(errors, 1.0 / model.dt, keep=keep)


@dataclass(frozen=True, eq=False)
class StageLinearModel:
    """A linear model of the stage with what it was fitted to (the model file's content).

    Attributes
    ----------
    model : SubspaceModel
        Discrete, at ``input_dt * decimate``.
    input_dt : float
        Sample time of the runs it was fitted to, s.
    decimate : int
        Factor applied before the fit (runs are decimated the same way to validate).
    """

    model: SubspaceModel
    input_dt: float
    decimate: int
    kind: ClassVar[str] = "linear"

    def __post_init__(self) -> None:
        check_positive("input_dt", self.input_dt, "s")
        check_int("decimate", self.decimate, 1)
        if abs(self.model.dt / (self.input_dt * self.decimate) - 1.0) > 1e-9:
            raise ValueError(
                f"the model's dt {self.model.dt:g} s is not input_dt {self.input_dt:g} s x "
                f"decimate {self.decimate}"
            )

    @property
    def input_rate_hz(self) -> float:
        """Rate of the runs the model reads, Hz."""
        return 1.0 / self.input_dt

    def continuous(self) -> ContinuousModel:
        """Seed 002 eq. (6) in continuous time, for data held at the runs' rate.

        `SubspaceModel.to_continuous` with ``hold_dt = input_dt``: the machine held each
        set-point for one sample of the runs (10 kHz), not for one sample of the
        decimated model, so the inverse ZOH at the model's rate would add a lead of half
        the difference (module docstring of `microfab.identify.subspace_model`).

        Raises
        ------
        ValueError
            A real discrete pole at or below zero (no real logarithm).
        """
        return self.model.to_continuous(hold_dt=self.input_dt)

    def errors(self, records: Any, *, keep: bool = False) -> RunErrors:
        """`run_errors` at the model's rate."""
        return run_errors(self.model, records, self.decimate, keep=keep)

    def to_dict(self) -> dict[str, Any]:
        """JSON form: format, version, kind, rates, decimation, the `SubspaceModel`."""
        return {
            "format": FORMAT,
            "version": VERSION,
            "kind": self.kind,
            "axes": list(AXES),
            "unit": "m",
            "input_rate_hz": self.input_rate_hz,
            "decimate": self.decimate,
            "model_rate_hz": 1.0 / self.model.dt,
            "anti_alias": "scipy.signal.decimate FIR (order 20 q, Hamming), zero phase, ends held",
            "model": self.model.to_dict(),
        }


_LINEAR_KEYS = frozenset(
    {"format", "version", "kind", "axes", "unit", "input_rate_hz", "decimate",
     "model_rate_hz", "anti_alias", "model"}
)  # fmt: skip


def _linear_from_dict(data: dict[str, Any]) -> StageLinearModel:
    if set(data) != _LINEAR_KEYS:
        extra, missing = sorted(set(data) - _LINEAR_KEYS), sorted(_LINEAR_KEYS - set(data))
        raise ValueError(f"linear stage model keys: unknown {extra}, missing {missing}")
    rate = check_positive("input_rate_hz", data["input_rate_hz"], "Hz")
    model = SubspaceModel.from_dict(data["model"])
    if model.n_inputs != 2 or model.n_outputs != 2:
        raise ValueError(
            f"a stage model maps 2 inputs to 2 outputs, this one {model.n_inputs} to "
            f"{model.n_outputs}"
        )
    if data["axes"] != list(AXES) or data["unit"] != "m":
        raise ValueError(f"axes {data['axes']!r} in {data['unit']!r}: expected {list(AXES)} in 'm'")
    out = StageLinearModel(model=model, input_dt=1.0 / rate, decimate=data["decimate"])
    if abs(float(data["model_rate_hz"]) * model.dt - 1.0) > 1e-9:
        raise ValueError(
            f"model_rate_hz {data['model_rate_hz']} disagrees with the model's dt {model.dt} s"
        )
    return out


def _ann_from_dict(data: dict[str, Any]) -> Any:
    """The network model in directory ``data["path"]`` (`read_stage_model` of a directory)."""
    try:
        from microfab.identify.stage_ann import read_ann_stage_model
    except ImportError as exc:  # PyTorch missing (extra ``ann``)
        raise ValueError(f"reading a network model needs PyTorch (extra 'ann'): {exc}") from None
    return read_ann_stage_model(data["path"])


#: Readers of a stage model by its ``"kind"``. What a reader returns must offer what
#: ``identify validate`` uses: ``kind``, ``input_rate_hz`` (the rate of the runs it reads)
#: and ``errors(records) -> RunErrors``, as `StageLinearModel`. ``"linear"`` reads the
#: model file's JSON; ``"ann"`` is a directory written by ``identify ann``
#: (`AnnModel.save`), handed over as ``{"kind": "ann", "path": ...}`` by
#: `read_stage_model` and read by `microfab.identify.stage_ann` (PyTorch imported then).
MODEL_KINDS: dict[str, Callable[[dict[str, Any]], Any]] = {
    "linear": _linear_from_dict,
    "ann": _ann_from_dict,
}


def stage_model_from_dict(data: Any) -> Any:
    """A stage model from its JSON form, by its ``"kind"`` (`MODEL_KINDS`).

    Raises
    ------
    ValueError
        Not a mapping, another format or version, an unknown kind, or the kind's own
        refusals (keys, shapes, rates).
    """
    if not isinstance(data, dict):
        raise ValueError(f"a stage model must be a JSON object, got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise ValueError(f"not a stage model: format {data.get('format')!r}, expected {FORMAT!r}")
    if data.get("version") != VERSION:
        raise ValueError(
            f"stage model version {data.get('version')!r} is not supported (this microfab "
            f"reads version {VERSION}); fit it again"
        )
    kind = data.get("kind")
    if kind == "ann":  # MODEL_KINDS: a directory, never a JSON file
        raise ValueError(
            "stage model kind 'ann' is not known in a model file: a network model is the "
            "directory that `identify ann` wrote; give that directory"
        )
    if kind not in MODEL_KINDS:
        raise ValueError(
            f"stage model kind {kind!r} is not known (known: {', '.join(sorted(MODEL_KINDS))})"
        )
    return MODEL_KINDS[str(kind)](data)


def write_stage_model(path: str | Path, model: StageLinearModel) -> None:
    """Write the model file (JSON, atomic)."""
    atomic_write_json(path, model.to_dict())


def read_stage_model(path: str | Path) -> Any:
    """Read a stage model and dispatch on its kind: a file (JSON), or a directory (ANN).

    Raises
    ------
    ValueError
        Unreadable, not JSON, or refused by `stage_model_from_dict`; a directory that
        holds no network model, or one of another version, rate or history
        (`microfab.identify.stage_ann.read_ann_stage_model`); the message names the file.
    """
    p = Path(path)
    if p.is_dir():  # a network model of `identify ann` (MODEL_KINDS)
        return MODEL_KINDS["ann"]({"kind": "ann", "path": str(p)})
    try:
        data = read_json(p, STAGE_MODEL_KIND)
    except FileNotFoundError:
        raise ValueError(f"{p}: cannot read a stage model: no such file") from None
    if isinstance(data, dict) and (data.get("kind"), data.get("format"), data.get("version")) == (
        "linear",
        FORMAT,
        VERSION,
    ):  # another format, version or kind: stage_model_from_dict names it
        validated(StageLinearDoc, data, str(p))
    try:
        return stage_model_from_dict(data)
    except (ValueError, TypeError, KeyError) as exc:
        raise ValueError(f"{p}: {exc}") from None


# --------------------------------------------------------------------------- the schema
#: What `microfab.io.schema.read_json` calls a stage model file.
STAGE_MODEL_KIND = FILE_KINDS["stage-model"].what
#: Largest model order read (assumed: the seed 002 fits are of order 4 to 20; 200 states
#: are 40 000 numbers in A, and refuse a file that lists samples where a model belongs).
MAX_ORDER = 200
_STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)
_Row = Annotated[list[float], Field(max_length=MAX_ORDER)]


class SubspaceDoc(BaseModel):
    """``model`` of a linear stage model: `SubspaceModel.to_dict` (dt in s, rate in Hz)."""

    model_config = _STRICT

    format: str
    version: int
    dt: float = Field(gt=0, le=1.0)
    rate_hz: float = Field(gt=0, le=1e7)
    order: int = Field(ge=1, le=MAX_ORDER)
    block_rows: int = Field(ge=1, le=10_000)
    weighting: str
    a: list[_Row] = Field(max_length=MAX_ORDER)
    b: list[_Row] = Field(max_length=MAX_ORDER)
    c: list[_Row] = Field(max_length=MAX_ORDER)
    d: list[_Row] = Field(max_length=MAX_ORDER)
    x0: list[_Row] = Field(max_length=10_000)
    singular_values: list[float] = Field(max_length=100_000)
    fit_mean: list[float] = Field(max_length=MAX_ORDER)
    fit_std: list[float] = Field(max_length=MAX_ORDER)


class StageLinearDoc(BaseModel):
    """A linear stage model file (`StageLinearModel.to_dict`), m and Hz."""

    model_config = _STRICT

    format: Literal["microfab.identify.StageModel"]
    version: Literal[1]
    kind: Literal["linear"]
    axes: list[Literal["x", "y"]] = Field(min_length=2, max_length=2)
    unit: Literal["m"]
    input_rate_hz: float = Field(gt=0, le=1e7)  # assumed: above 10 MHz is a unit mistake
    decimate: int = Field(ge=1, le=10_000)
    model_rate_hz: float = Field(gt=0, le=1e7)
    anti_alias: str
    model: SubspaceDoc
