"""Experiment design for the black-box XY stage (seed 002 §III-C): command runs at 10 kHz.

A *run* (`ExcitationRun`, :mod:`~microfab.identify.excitation_run`) is one command record
for both axes, sampled at 10 kHz (seed 002 Table I: the built-in loop's rate), that
starts at rest at the origin (the twin's rest position, `excitation_random.HOME`) and
ends at rest there, so runs chain on a real machine.
Every run passes :func:`~microfab.core.limits.check_trajectory` against the seed's Table I
(`MachineLimits.seed002_stage`: workspace ``[-0.19, 0.19]²`` m, 1.5 m/s, 40 m/s²) when it
is built; a run that does not is refused, naming the check.

Kinds of run:

- ``random`` (`random_runs`): seeded random motion, the seed's data for the linear model
  (§III-C 1: 6×10⁶ points, i.e. 600 s; accelerations up to 5 m/s², §III-D). Construction
  in :mod:`microfab.identify.excitation_random`.
- ``shape`` (`shape_runs`): regular shapes (§III-C 2: "circles, polygons, and spirals",
  "each shape was traversed at varied speeds, constant for each trial"), including the
  Archimedean spiral of Fig. 1, each traced at constant speed by
  :func:`microfab.trajectory.cruise.cruise` (ramps, curvature slow-downs and corner stops
  within ``a_max``).
- ``prbs`` and ``chirp`` (`prbs_runs`, `chirp_runs`): the classic inputs the seed found
  inadequate (§III-C: "none of these proved adequate for the identification of the
  nonlinear system"). Within the limits they are small: a one-sample position step must
  satisfy ``2A/dt² ≤ 40 m/s²`` (A ≤ 0.2 µm), so the PRBS switches by quintic moves, and a
  chirp's amplitude is set by its top frequency (``A (2π f₁)² ≤ a_max``: 3.2 µm at
  200 Hz and 5 m/s²).

Shapes, PRBS and chirp live in :mod:`microfab.identify.excitation_signals`; this module
re-exports them and every public name a user needs.

`ann_dataset` mixes random runs (≈60 %) and shapes for the neural networks (§III-C 2);
`split_runs` splits whole runs 80/20 (§III-C 2). The seed counts ≈34 "data points per
parameter"; we count training windows (one per 10 kHz sample after the first 500 ms of a
run): 34 × 117 322 weights ≈ 4.0×10⁶ training windows need about 525 s of runs
(`ANN_TOTAL_S`). Its ANN generations 2-3 (the optimised inputs played and added) are
`microfab.machines.xy_stage.generations`.

`write_runs` writes the command files a user plays on a real machine (``time``,
``input_x``, ``input_y``; CSV or HDF5, each atomic) and an index JSON; nothing is written
if any run fails its check. `read_runs` reads them back.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path as FsPath
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from microfab.core.limits import LimitViolation
from microfab.core.validate import check_in_range, check_positive
from microfab.identify.excitation_random import RandomDesign, draw_levels, random_command
from microfab.identify.excitation_run import (
    AXES,
    DT,
    KINDS,
    LIMITS,
    SEED_A_MAX,
    ExcitationRun,
    check_a_max,
    command_digest,
    spawn_seeds,
)
from microfab.identify.excitation_signals import (
    FIG1_SPIRAL_B,
    chirp_runs,
    prbs_runs,
    shape_catalogue,
    shape_runs,
)
from microfab.io.atomic import atomic_write_json
from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import MAX_SAMPLES, inside, read_json, validated
from microfab.io.trace import read_columns, write_trace

__all__ = [
    "ANN_TOTAL_S",
    "AXES",
    "DT",
    "FIG1_SPIRAL_B",
    "INDEX_FILE",
    "KINDS",
    "LIMITS",
    "SEED_A_MAX",
    "ExcitationRun",
    "LimitViolation",
    "RandomDesign",
    "ann_dataset",
    "chirp_runs",
    "prbs_runs",
    "random_runs",
    "read_runs",
    "shape_catalogue",
    "shape_runs",
    "split_runs",
    "write_runs",
]

#: Total run length for the ANN data, s: seed 002 §III-C 2, ≈34 per weight × 117 322
#: weights (Fig. 5) = 3.99e6 training windows = 80 % of the 10 kHz samples, less 500 ms
#: of history per training run (≈40 of them: ≈12 random, the rest shorter shapes):
#: (3.99e6 + 40 × 5000) / 0.8 / 10 kHz ≈ 524 s.
ANN_TOTAL_S = 525.0
#: Most excitation asked for at once, s. Assumed: one hour of 10 kHz commands (3.6e7
#: samples, ~0.6 GB of CSV), six times the seed's 600 s; more is a unit mistake.
MAX_TOTAL_S = 3600.0
#: The index file `write_runs` writes next to the run files.
INDEX_FILE = "runs.json"
_FORMAT = 1
_SUFFIX = {"csv": ".csv", "h5": ".h5", "mat": ".mat"}
_SLACK_S = 1.0  # ann_dataset: stop adding shapes within this of the total, s


#: What `microfab.io.schema.read_json` calls the index.
INDEX_KIND = FILE_KINDS["run-list"].what


class _RunEntry(BaseModel):
    """One run of the index (what `write_runs` writes; other keys are kept aside)."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    name: str = Field(min_length=1)
    kind: str = Field(min_length=1)
    file: str = Field(min_length=1)
    seed: int = Field(ge=0)
    dt_s: float = Field(gt=0, le=1.0)
    n_samples: int = Field(ge=2, le=MAX_SAMPLES)
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$")
    params: dict[str, Any] = Field(default_factory=dict)


class _RunIndex(BaseModel):
    """The schema of `INDEX_FILE`."""

    model_config = ConfigDict(strict=True, extra="allow", allow_inf_nan=False)

    format: Literal[1]
    runs: list[_RunEntry] = Field(min_length=1)
    unit: Literal["m"] = "m"
    total_samples: int | None = Field(None, ge=0)


# --- random --------------------------------------------------------------------------------


def random_runs(
    total_s: float = 600.0,
    *,
    a_max: float = SEED_A_MAX,
    seed: int = 0,
    design: RandomDesign | None = None,
    python: bool = False,
) -> list[ExcitationRun]:
    """Seeded random runs totalling ``total_s`` (seed 002 §III-C 1).

    Run lengths are drawn in ``design.run_s``; the last takes what is left (so it may
    be up to ``run_s[0] + run_s[1]`` long), and the runs hold ``round(total_s / dt)``
    samples in all. Each run's levels (``a_peak``, ``v_cap``, brake
    ramp) are drawn from its own seed; see :mod:`microfab.identify.excitation_random`.

    Parameters
    ----------
    total_s : float
        Total, s (default 600 s = 6×10⁶ samples at 10 kHz, seed 002 §III-C 1).
    a_max : float
        Largest acceleration, m/s² (default 5, the seed's training range, §III-D);
        at most Table I's 40.
    seed : int
        Seed; the same seed gives the same runs.
    design : RandomDesign, optional
        Segment and level distributions (defaults assumed, see `RandomDesign`).
    python : bool
        Use the pure Python knot loop (the reference; slow).

    Returns
    -------
    list of ExcitationRun
        Named ``random_000``, ``random_001``, …; ``params`` hold the levels.
    """
    total = check_positive("total_s", total_s, "s")
    if total > MAX_TOTAL_S:
        raise ValueError(
            f"total_s = {total:g} s of random runs is more than {MAX_TOTAL_S:g} s "
            f"({MAX_TOTAL_S * 1e4:.3g} samples at 10 kHz); ask for less"
        )
    a_max = check_a_max(a_max)
    design = design if design is not None else RandomDesign()
    master = np.random.default_rng(spawn_seeds(seed, 1)[0])
    runs: list[ExcitationRun] = []
    done = 0.0
    while total - done > 0.5 * DT:
        run_seed = int(master.integers(0, 2**63 - 1))
        levels = draw_levels(np.random.default_rng(run_seed), design, a_max)
        left = total - done
        if left - levels["run_s"] < design.run_s[0]:  # the last run takes what is left
            levels["run_s"] = float(left)
        cmd, facts = random_command(
            levels, run_seed, design=design, workspace=LIMITS.workspace, dt=DT, python=python
        )
        run = ExcitationRun(
            kind="random",
            name=f"random_{len(runs):03d}",
            dt=DT,
            command=cmd,
            seed=run_seed,
            params={**levels, **facts, "a_max": a_max},
        )
        runs.append(run)
        done += run.duration
    return runs


# --- data sets --------------------------------------------------------------------------------


def ann_dataset(
    total_s: float = ANN_TOTAL_S,
    *,
    random_share: float = 0.6,
    seed: int = 0,
    a_max: float = SEED_A_MAX,
    speed_range: tuple[float, float] = (0.02, 1.0),
) -> list[ExcitationRun]:
    """Runs for the neural networks: ≈``random_share`` random, the rest shapes (§III-C 2).

    The random part is `random_runs` of ``random_share · total_s``; shapes are then added
    (the catalogue with fresh seeded rotations, each at a speed drawn log-uniform in
    ``speed_range``), skipping a run that would overshoot ``total_s`` by more than is
    left, until less than 1 s is left. The shares hold to within one run.

    Parameters
    ----------
    total_s : float
        Total length, s (default `ANN_TOTAL_S`, the seed's ≈4×10⁶ training windows).
    random_share : float
        Share of random runs, in [0, 1] (seed 002 §III-C 2: "about 60 %").
    seed : int
        Seed of everything.
    a_max : float
        Acceleration limit, m/s² (default 5).
    speed_range : tuple of float
        Shape speeds, m/s (assumed 0.02-1 m/s: slow fine cuts to fast contours).
    """
    total = check_positive("total_s", total_s, "s")
    share = check_in_range("random_share", random_share, 0.0, 1.0)
    lo, hi = speed_range
    check_in_range("speed_range[1]", hi, 0.0, LIMITS.velocity[0], "m/s", low_closed=False)
    check_in_range("speed_range[0]", lo, 0.0, hi, "m/s", low_closed=False)
    s_random, s_shape, s_speed = spawn_seeds(seed, 3)
    runs = random_runs(share * total, a_max=a_max, seed=s_random) if share > 0 else []
    done = sum(r.duration for r in runs)
    rng = np.random.default_rng(s_speed)
    shape_seeds = np.random.default_rng(s_shape)
    k = 0
    while total - done > _SLACK_S:
        catalogue = shape_catalogue(int(shape_seeds.integers(0, 2**63 - 1)))
        skipped: list[ExcitationRun] = []
        for i in rng.permutation(len(catalogue)):
            left = total - done
            if left <= _SLACK_S:
                break
            v = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
            (run,) = shape_runs([v], a_max=a_max, shapes=[catalogue[i]])
            if run.duration - left > max(_SLACK_S, left):  # would overshoot by more than is left
                skipped.append(run)
                continue
            runs.append(_renamed(run, f"shape_{k:03d}_{run.name.removeprefix('shape_')}", seed))
            done += run.duration
            k += 1
        else:
            if skipped and total - done > _SLACK_S and len(catalogue) == len(skipped):
                run = min(skipped, key=lambda r: r.duration)  # none fitted: the shortest
                runs.append(_renamed(run, f"shape_{k:03d}_{run.name.removeprefix('shape_')}", seed))
                done += run.duration
                k += 1
    return runs


def _renamed(run: ExcitationRun, name: str, seed: int) -> ExcitationRun:
    return ExcitationRun(
        kind=run.kind, name=name, dt=run.dt, command=run.command, seed=seed, params=run.params
    )


def split_runs(
    runs: Sequence[ExcitationRun], validation: float = 0.2, *, seed: int = 0
) -> tuple[list[ExcitationRun], list[ExcitationRun]]:
    """Split whole runs into training and validation (seed 002 §III-C 2: 80 %/20 %).

    Per kind, the runs are visited in a seeded random order and each moves to validation
    while the kind's validation samples stay within ``validation`` of its samples; then
    the shortest run left moves too if that brings the share closer. No run is cut, and
    each kind's share is off by at most half its shortest run left over.
    Each set keeps the input order.

    Returns
    -------
    (list of ExcitationRun, list of ExcitationRun)
        Training, validation.
    """
    frac = check_in_range("validation", validation, 0.0, 1.0, high_closed=False)
    names = [r.name for r in runs]
    if len(set(names)) != len(names):
        raise ValueError("run names must be unique to split them")
    rng = np.random.default_rng(spawn_seeds(seed, 1)[0])
    chosen: set[int] = set()
    for kind in KINDS:
        idx = [i for i, r in enumerate(runs) if r.kind == kind]
        if not idx or frac == 0.0:
            continue
        goal = frac * sum(runs[i].n_samples for i in idx)
        got = 0
        rest = []
        for j in rng.permutation(len(idx)):
            n = runs[idx[j]].n_samples
            if got + n <= goal:  # first fit
                chosen.add(idx[j])
                got += n
            else:
                rest.append(idx[j])
        if rest:  # then the shortest left over, if it brings the share closer
            i = min(rest, key=lambda i: runs[i].n_samples)
            if abs(got + runs[i].n_samples - goal) < goal - got:
                chosen.add(i)
    train = [r for i, r in enumerate(runs) if i not in chosen]
    valid = [r for i, r in enumerate(runs) if i in chosen]
    return train, valid


# --- files -------------------------------------------------------------------------------------


def write_runs(runs: Sequence[ExcitationRun], out_dir: str | FsPath, fmt: str = "csv") -> FsPath:
    """Write command files to play on a real machine, and an index; all or nothing checked.

    Every run is checked again (``check_trajectory`` against Table I) and the names must be
    unique before anything is written. Then each run goes to ``<name>.csv`` (or ``.h5``,
    ``.mat``) with columns ``time`` (s), ``input_x``, ``input_y`` (m), atomically, and last
    `INDEX_FILE` (JSON, atomic): format, limits, columns, and per run its file, kind,
    seed, params, samples, duration, sampled peaks and the SHA-256 of its command.

    Parameters
    ----------
    runs : sequence of ExcitationRun
        The runs, at least one.
    out_dir : str or pathlib.Path
        Directory (created if missing).
    fmt : str
        ``"csv"``, ``"h5"`` or ``"mat"``.

    Returns
    -------
    pathlib.Path
        The index file.

    Raises
    ------
    ValueError, microfab.core.limits.LimitViolation
        Before anything is written.
    """
    if fmt not in _SUFFIX:
        raise ValueError(f"fmt must be one of {sorted(_SUFFIX)}, got {fmt!r}")
    if not runs:
        raise ValueError("no runs to write")
    names = [r.name for r in runs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"run names must be unique; repeated: {dup}; nothing was written")
    for r in runs:
        if not isinstance(r, ExcitationRun):
            raise ValueError(f"expected ExcitationRun, got {type(r).__name__}; nothing written")
        r.check()
    out = FsPath(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for r in runs:
        file = r.name + _SUFFIX[fmt]
        write_trace(r.to_trace(), out / file)
        entries.append(
            {
                "name": r.name,
                "kind": r.kind,
                "file": file,
                "seed": r.seed,
                "dt_s": r.dt,
                "n_samples": r.n_samples,
                "duration_s": r.duration,
                "sha256": r.digest,
                "peaks": r.peaks(),
                "params": dict(r.params),
            }
        )
    index = out / INDEX_FILE
    atomic_write_json(
        index,
        {
            "format": _FORMAT,
            "what": "microfab excitation runs (seed 002 §III-C): set-points from rest at the "
            "origin back to rest there",
            "columns": ["time", *AXES],
            "unit": "m",
            "limits": {
                "workspace_m": [list(w) for w in LIMITS.workspace],
                "velocity_m_s": list(LIMITS.velocity),
                "acceleration_m_s2": list(LIMITS.acceleration),
            },
            "total_samples": sum(r.n_samples for r in runs),
            "total_s": sum(r.duration for r in runs),
            "runs": entries,
        },
    )
    return index


def read_runs(out_dir: str | FsPath) -> list[ExcitationRun]:
    """Read the runs `write_runs` wrote (the index and every file; digests compared).

    Raises
    ------
    ValueError
        Another format, an index that does not follow its schema (strict types: a
        ``dt_s`` of ``true`` or an ``n_samples`` of ``"100"`` is refused; a run file
        outside the folder; counts that disagree with the files), a missing column, or a
        command whose SHA-256 differs from the index's (the message names the file).
    """
    out = FsPath(out_dir)
    where = str(out / INDEX_FILE)
    doc = read_json(out / INDEX_FILE, INDEX_KIND)
    if isinstance(doc, dict) and doc.get("format") != _FORMAT:
        raise ValueError(f"{where}: format {doc.get('format')!r}, expected {_FORMAT}")
    index = validated(_RunIndex, doc, where)
    total = sum(e.n_samples for e in index.runs)
    if index.total_samples is not None and index.total_samples != total:
        raise ValueError(f"{where}: total_samples is {index.total_samples}, the runs hold {total}")
    names = [e.name for e in index.runs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"{where}: run names must be unique; repeated: {dup}")
    runs = []
    for k, e in enumerate(index.runs):
        path = inside(out, e.file, f"{where}: runs.{k}.file")
        cols = read_columns(path)
        missing = [c for c in ("time", *AXES) if c not in cols]
        if missing:
            raise ValueError(f"{path}: missing columns {missing}")
        if cols["time"].size != e.n_samples:
            raise ValueError(
                f"{path}: {cols['time'].size} samples, the index says n_samples {e.n_samples}"
            )
        step = np.diff(cols["time"])
        if np.max(np.abs(step - e.dt_s)) > 1e-6 * e.dt_s:
            raise ValueError(f"{path}: the time column does not step by dt_s {e.dt_s:g} s")
        cmd = np.column_stack([cols[c] for c in AXES])
        if command_digest(cmd) != e.sha256:
            raise ValueError(f"{path}: command differs from the index (SHA-256)")
        runs.append(
            ExcitationRun(
                kind=e.kind, name=e.name, dt=e.dt_s, command=cmd, seed=e.seed, params=e.params
            )
        )
    return runs
