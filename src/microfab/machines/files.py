"""Real hardware through files: one measured trial in, the next input out.

A trial file (CSV, MATLAB ``.mat`` or HDF5, same names as variables) holds one period:
a ``time`` column in s and, per axis ``<a>``, ``reference_<a>``, ``input_<a>`` and
``output_<a>``. `ilc_step` learns from it with `microfab.control.ilc.FrequencyILC`, keeps
the learning state in a directory, and writes the next input file (``time`` and
``input_<a>``). Every check runs before anything is written; the input file is written
first and the state last, both atomically, so an interrupted or refused step leaves the
state as it was and repeating the call is safe.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.control.ilc import FrequencyILC, ILCConfig, Trial
from microfab.core.limits import AxisLimits, check_command
from microfab.io.trace import read_columns, write_columns

__all__ = ["StepReport", "TrialFileError", "ilc_step", "read_trial_file", "write_input_file"]


class TrialFileError(ValueError):
    """A trial file is unusable (missing columns, NaN, bad timing, changed reference...)."""


@dataclass(frozen=True)
class StepReport:
    """What one `ilc_step` did.

    Attributes
    ----------
    iteration : int
        Trials learned from so far (1 after the first call).
    rms : dict of str to float
        RMS error of the trial just read, per axis, in the file's unit.
    out_path : Path
        The input file written.
    harmonics : dict of str to int
        Number of learned harmonics per axis.
    """

    iteration: int
    rms: dict[str, float]
    out_path: Path
    harmonics: dict[str, int]


def read_trial_file(path: str | Path) -> Trial:
    """Read and check one trial file.

    Raises
    ------
    TrialFileError
        Missing ``time`` or axis columns, NaN/inf (naming column and sample), fewer than
        8 samples, or a time column that is not uniformly increasing.
    FileNotFoundError
        The file does not exist.
    """
    p = Path(path)
    try:
        cols = read_columns(p)
    except ValueError as exc:
        raise TrialFileError(f"{p}: {exc}") from exc
    if "time" not in cols:
        raise TrialFileError(f"{p}: no 'time' column (found: {', '.join(cols) or 'none'})")
    axes = tuple(k[len("reference_") :] for k in cols if k.startswith("reference_"))
    if not axes:
        raise TrialFileError(f"{p}: no 'reference_<axis>' column (found: {', '.join(cols)})")
    for a in axes:
        for kind in ("input", "output"):
            if f"{kind}_{a}" not in cols:
                raise TrialFileError(f"{p}: axis {a!r} has no '{kind}_{a}' column")
    t = cols["time"]
    for name in ("time", *(f"{k}_{a}" for a in axes for k in ("reference", "input", "output"))):
        bad = np.nonzero(~np.isfinite(cols[name]))[0]
        if bad.size:
            raise TrialFileError(f"{p}: column {name!r} holds NaN/inf at sample {bad[0]}")
    if t.size < 8:
        raise TrialFileError(f"{p}: a trial needs at least 8 samples, got {t.size}")
    d = np.diff(t)
    dt = float(np.mean(d))
    if dt <= 0 or np.max(np.abs(d - dt)) > 1e-6 * dt:
        raise TrialFileError(f"{p}: 'time' is not uniformly increasing (one period expected)")
    stack = lambda kind: np.column_stack([cols[f"{kind}_{a}"] for a in axes])  # noqa: E731
    return Trial(
        dt=dt,
        reference=stack("reference"),
        input=stack("input"),
        output=stack("output"),
        axes=axes,
    )


def write_input_file(
    path: str | Path, dt: float, inputs: np.ndarray, axes: tuple[str, ...]
) -> None:
    """Write ``time`` and ``input_<a>`` columns (atomically; format from the suffix)."""
    n = inputs.shape[0]
    cols = {"time": np.arange(n) * dt}
    cols |= {f"input_{a}": inputs[:, i] for i, a in enumerate(axes)}
    write_columns(path, cols)


def _digest(trial: Trial) -> str:
    h = hashlib.sha256()
    for arr in (trial.reference, trial.input, trial.output):
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def ilc_step(
    trial_path: str | Path,
    state_dir: str | Path,
    out_path: str | Path,
    config: ILCConfig | None = None,
    limits: Mapping[str, AxisLimits] | None = None,
) -> StepReport:
    """Learn from one measured trial and write the next input.

    Parameters
    ----------
    trial_path : str or Path
        The measured trial (one period, see module doc).
    state_dir : str or Path
        Learning-state directory; created on the first call, which takes the model inverse
        from this trial (seed 000 eq. 7).
    out_path : str or Path
        Where the next input is written (``.csv``, ``.mat``, ``.h5``).
    config : ILCConfig, optional
        Used on the first call only (kept in the state afterwards).
    limits : mapping of str to AxisLimits, optional
        Declared machine limits the next input must respect; stored in the state on the
        first call and used on later calls when not given again.

    Returns
    -------
    StepReport

    Raises
    ------
    TrialFileError
        Bad trial: see `read_trial_file`; also sample time, length or axes that differ from
        the state's, a reference that changed, or a trial already learned from.
    microfab.core.limits.LimitViolation
        The next input would exceed the declared limits (nothing is written).
    """
    trial = read_trial_file(trial_path)
    sd = Path(state_dir)
    digest = _digest(trial)
    if FrequencyILC.exists(sd):
        ilc = FrequencyILC.load(sd)
        st = ilc.state
        if trial.axes != st.axes:
            raise TrialFileError(
                f"{trial_path}: axes {list(trial.axes)} differ from the state's {list(st.axes)}"
            )
        if abs(trial.dt - st.dt) > 1e-6 * st.dt:
            raise TrialFileError(
                f"{trial_path}: sample time {trial.dt:.9g} s differs from the state's "
                f"{st.dt:.9g} s (sample rate changed)"
            )
        if trial.reference.shape != st.reference.shape:
            raise TrialFileError(
                f"{trial_path}: {trial.reference.shape[0]} samples "
                f"({trial.reference.shape[0] * trial.dt:.6g} s), but the period in the state "
                f"is {st.reference.shape[0]} samples ({ilc.period_s:.6g} s)"
            )
        tol = 1e-9 * max(1.0, float(np.max(np.abs(st.reference))))
        diff = np.max(np.abs(trial.reference - st.reference))
        if diff > tol:
            raise TrialFileError(
                f"{trial_path}: the reference changed since the first trial (max difference "
                f"{diff:.3g}); start a new state directory for a new reference"
            )
        if digest in st.meta.get("digests", []):  # type: ignore[operator]
            raise TrialFileError(f"{trial_path}: this trial was already learned from")
        stored = st.meta.get("limits")
        if limits is None and isinstance(stored, dict):
            limits = {a: AxisLimits(**v) for a, v in stored.items()}
    else:
        ilc = FrequencyILC(trial.reference, trial.dt, trial.axes, config)
    next_input = ilc.update(trial)
    if limits is not None:
        check_command(next_input, trial.dt, limits, trial.axes, periodic=True)
    write_input_file(out_path, trial.dt, next_input, trial.axes)
    seen = list(ilc.state.meta.get("digests", []))  # type: ignore[call-overload]
    extra: dict[str, object] = {"digests": [*seen, digest]}
    if limits is not None:
        extra["limits"] = {
            a: {
                "position": v.position,
                "velocity": v.velocity,
                "acceleration": v.acceleration,
                "unit": v.unit,
            }
            for a, v in limits.items()
        }
    ilc.save(sd, extra)
    rms = ilc.rms_history[-1]
    return StepReport(
        iteration=ilc.iteration,
        rms={a: float(rms[i]) for i, a in enumerate(trial.axes)},
        out_path=Path(out_path),
        harmonics={a: int(h.size) for a, h in zip(trial.axes, ilc.harmonics, strict=True)},
    )
