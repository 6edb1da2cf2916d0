"""Real hardware through files: `FileMachine`, and `ilc_step` (trial in, next input out).

A trial file (CSV, MATLAB ``.mat`` or HDF5, same names as variables) holds one period:
a ``time`` column in s and, per axis ``<a>``, ``reference_<a>``, ``input_<a>`` and
``output_<a>``. `FileMachine` is the `microfab.machines.base.Machine` of such hardware:
``run(command)`` writes the command file and returns the measurement read from the trial
file (waiting for a fresh one when asked to). `ilc_step` is one iteration of the learning
loop `microfab.machines.learning.learn` on a `FileMachine` that reads the trial the user
just measured: it learns with `microfab.control.ilc.FrequencyILC`, keeps the learning
state in a directory, and writes the next input file (``time`` and ``input_<a>``). Every
check runs before anything is written; the input file is written first and the state
last, both atomically, so an interrupted or refused step leaves the state as it was and
repeating the call is safe. A step holds the state's lock (`microfab.io.lock`) from reading
the state to saving it: a second step on the same state meanwhile is refused.
"""

from __future__ import annotations

import re
import time as _time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.control.ilc import FrequencyILC, ILCConfig, Trial
from microfab.core.limits import AxisLimits
from microfab.io.frf import read_frf
from microfab.io.lock import folder_lock
from microfab.io.trace import read_columns, write_columns
from microfab.machines.base import Measurement
from microfab.machines.learning import TrialError, learn

__all__ = [
    "FileMachine",
    "StepReport",
    "TrialFileError",
    "ilc_step",
    "read_trial_file",
    "write_input_file",
]


_AXIS = re.compile(r"[A-Za-z0-9_]+")


class TrialFileError(TrialError):
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
    events : tuple of str
        What the divergence monitor did in this step (usually nothing).
    """

    iteration: int
    rms: dict[str, float]
    out_path: Path
    harmonics: dict[str, int]
    events: tuple[str, ...] = ()


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
    if not any(k.startswith("reference_") for k in cols):
        raise TrialFileError(f"{p}: no 'reference_<axis>' column (found: {', '.join(cols)})")
    # every axis any column names (an axis with an input and an output but no reference
    # was dropped without a word; now it is refused below)
    prefixes = ("reference_", "input_", "output_")
    named = (k.split("_", 1)[1] for k in cols if k.startswith(prefixes))
    axes = tuple(dict.fromkeys(named))
    for a in axes:
        if not _AXIS.fullmatch(a):
            col = next(k for k in cols if k.startswith(prefixes) and k.split("_", 1)[1] == a)
            raise TrialFileError(
                f"{p}: column {col!r} names no valid axis: write "
                "reference_<axis> with an axis name of letters, digits and underscores, "
                "e.g. reference_x"
            )
    for a in axes:
        for kind in ("reference", "input", "output"):
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


class FileMachine:
    """A machine reached through files: command file out, trial file in.

    Parameters
    ----------
    trial_path : str or Path
        The measured trial file (see module doc) that ``run`` returns.
    command_path : str or Path, optional
        Where ``run`` writes the command (``time`` and ``input_<a>``) first; ``None``
        writes nothing (the trial was measured already, as in `ilc_step`).
    timeout_s : float
        With a ``command_path``: how long ``run`` waits for a trial file newer than the
        command it wrote (an automated rig: dSpace, Speedgoat, LabVIEW watching a folder),
        s. ``0`` reads the trial file as it is.
    poll_s : float
        Polling interval while waiting, s.

    Notes
    -----
    The returned `Measurement` carries the trial's ``input_<a>`` columns as the command
    actually applied and its ``reference_<a>`` columns as ``reference``, so the learning
    loop checks them against what it expects.
    """

    def __init__(
        self,
        trial_path: str | Path,
        command_path: str | Path | None = None,
        *,
        timeout_s: float = 0.0,
        poll_s: float = 0.2,
    ) -> None:
        if not (timeout_s >= 0 and poll_s > 0):
            raise ValueError(f"timeout_s must be >= 0 and poll_s > 0, got {timeout_s}, {poll_s} s")
        self.trial_path = Path(trial_path)
        self.command_path = None if command_path is None else Path(command_path)
        self.timeout_s = float(timeout_s)
        self.poll_s = float(poll_s)
        self._trial: Trial | None = None

    def peek(self) -> Trial:
        """The trial file as it is now (checked, cached until the next ``run``)."""
        if self._trial is None:
            self._trial = read_trial_file(self.trial_path)
        return self._trial

    @property
    def axes(self) -> tuple[str, ...]:
        """Axis names of the trial file."""
        return self.peek().axes

    @property
    def dt(self) -> float:
        """Sample time of the trial file, s."""
        return self.peek().dt

    def run(self, command: np.ndarray) -> Measurement:
        """Write ``command`` (when a command file is set) and read the measured trial.

        Raises
        ------
        TrialFileError
            Bad trial file (see `read_trial_file`).
        TimeoutError
            No fresh trial file within ``timeout_s``.
        """
        if self.command_path is not None:
            trial = self.peek() if self._trial is not None else None
            dt = trial.dt if trial is not None else self.dt
            axes = trial.axes if trial is not None else self.axes
            started = _time.time()
            write_input_file(self.command_path, dt, np.asarray(command, dtype=float), axes)
            if self.timeout_s > 0:
                self._wait_newer_than(started)
        self._trial = None
        trial = self.peek()
        return Measurement(
            dt=trial.dt,
            command=trial.input,
            output=trial.output,
            axes=trial.axes,
            reference=trial.reference,
        )

    def run_once(self, command: np.ndarray, *, settle_s: float | None = None) -> Measurement:
        """One-shot run through files: write ``command``, read the recorded trial.

        The rig plays the command from rest and holds it; how long it records the hold is
        the rig's setting (``settle_s`` is not used). The trial file holds the whole record.
        """
        return self.run(command)

    def _wait_newer_than(self, t0: float) -> None:
        deadline = _time.monotonic() + self.timeout_s
        while _time.monotonic() < deadline:
            if self.trial_path.is_file() and self.trial_path.stat().st_mtime >= t0:
                return
            _time.sleep(self.poll_s)
        raise TimeoutError(
            f"no measured trial in {self.trial_path} within {self.timeout_s:g} s of writing "
            f"{self.command_path}"
        )


def _check_learnable(ilc: FrequencyILC, trial_path: str | Path) -> None:
    """Raise `TrialFileError` when the first trial leaves nothing to learn.

    That is a period too short for any harmonic at or below the cutoff (only the mean
    could be learned: the motion never), or no harmonic at all, the mean included, with
    content in the input and out of the noise in the output.
    """
    f_r = 1.0 / ilc.period_s
    cutoff = ilc.config.cutoff_hz
    period = f"the period of {ilc.n_samples} samples ({ilc.period_s:.6g} s, {f_r:.6g} Hz)"
    if f_r > cutoff:
        why = (
            f"{period} has no harmonic at or below the cutoff {cutoff:g} Hz; record a "
            "longer period or raise the cutoff (--cutoff-hz)"
        )
    elif not any(h.size for h in ilc.harmonics):
        why = (
            f"no harmonic of {period} up to the cutoff {cutoff:g} Hz has content in the "
            "input and stands out of the noise in the output"
        )
    else:
        return
    raise TrialFileError(f"{trial_path}: nothing can be learned: {why}; nothing was written")


def ilc_step(
    trial_path: str | Path,
    state_dir: str | Path,
    out_path: str | Path,
    config: ILCConfig | None = None,
    limits: Mapping[str, AxisLimits] | None = None,
    frf_path: str | Path | None = None,
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
    frf_path : str or Path, optional
        A measured FRF file (`microfab.io.frf`) to invert instead of the first trial
        (first call only; the model is kept in the state).

    Returns
    -------
    StepReport

    Raises
    ------
    TrialFileError
        Bad trial: see `read_trial_file`; also sample time, length or axes that differ from
        the state's, a reference that changed, a trial already learned from, or a first
        trial in which no harmonic above the mean can be learned (a period too short for
        any harmonic below the cutoff, or no content above the noise).
    microfab.core.limits.LimitViolation
        The next input would exceed the declared limits (nothing is written).
    microfab.io.lock.FolderLockedError
        Another process is writing the state (nothing is read or written): steps on one
        state run one at a time, each holding its lock from reading the state to saving it.
    """
    with folder_lock(state_dir, what="learning state"):
        return _ilc_step(trial_path, state_dir, out_path, config, limits, frf_path)


def _ilc_step(
    trial_path: str | Path,
    state_dir: str | Path,
    out_path: str | Path,
    config: ILCConfig | None,
    limits: Mapping[str, AxisLimits] | None,
    frf_path: str | Path | None,
) -> StepReport:
    """`ilc_step` once the state's lock is held."""
    machine = FileMachine(trial_path)
    trial = machine.peek()
    sd = Path(state_dir)
    if FrequencyILC.exists(sd):
        if frf_path is not None:
            raise TrialFileError(
                f"{sd} already holds a learning state: an FRF file is used on the first "
                "call only (start a new state directory to learn from it)"
            )
        ilc = FrequencyILC.load(sd)
    else:
        model = None if frf_path is None else read_frf(frf_path).model(trial.axes)
        ilc = FrequencyILC(trial.reference, trial.dt, trial.axes, config, model=model)
    seen = len(ilc.events)
    first = ilc.iteration == 0

    def publish(u: np.ndarray) -> None:
        if first:  # the harmonics are chosen from the first trial: say if there are none
            _check_learnable(ilc, trial_path)
        write_input_file(out_path, trial.dt, u, trial.axes)

    try:
        learn(
            machine,
            ilc,
            iterations=ilc.iteration + 1,
            state_dir=sd,
            limits=limits,
            publish=publish,
        )
    except TrialError as exc:
        if isinstance(exc, TrialFileError):
            raise
        raise TrialFileError(f"{trial_path}: {exc}") from exc
    rms = ilc.rms_history[-1]
    return StepReport(
        iteration=ilc.iteration,
        rms={a: float(rms[i]) for i, a in enumerate(trial.axes)},
        out_path=Path(out_path),
        harmonics={a: int(h.size) for a, h in zip(trial.axes, ilc.harmonics, strict=True)},
        events=tuple(ilc.events[seen:]),
    )
