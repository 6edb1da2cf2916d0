"""One learning loop for the twin and for hardware: `learn`.

`learn` drives a `microfab.control.learning.Learner` on a `microfab.machines.base.Machine`
for a number of trials: apply the learner's command, measure one period, check the trial,
learn, check the next command against the machine's declared limits, publish it, save.
Resume, duplicate-trial detection and limit checks live here and nowhere else, so the
simulated run (``microfab run``) and the file workflow on hardware (``microfab ilc step``)
behave the same way.

Order of writes in one iteration: the next command is published first (for hardware, the
input file), the learner's state last, both atomically. An interruption or a refusal
therefore leaves the saved state as it was, and repeating the call is safe.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from microfab.control.ilc import Trial
from microfab.control.learning import Learner
from microfab.core.limits import AxisLimits, check_command
from microfab.io.schema import SchemaError, check_array
from microfab.machines.base import Machine, Measurement, Resumable

__all__ = ["LearnRecord", "TrialError", "learn", "trial_digest"]

#: Key of the loop's record in the learner's saved ``meta``.
RECORD_KEY = "learn"


class TrialError(ValueError):
    """A measured trial cannot be learned from (other reference, length, or seen before)."""


def _hash_update(h: Any, arr: np.ndarray) -> None:
    h.update(np.ascontiguousarray(arr, dtype=float).data)  # the bytes, without a copy


def trial_digest(trial: Trial, reference_hash: Any = None) -> str:
    """SHA-256 of a trial's reference, input and output (to refuse the same trial twice).

    Parameters
    ----------
    trial : Trial
        The trial.
    reference_hash : hashlib hash, optional
        A SHA-256 object that has already been fed ``trial.reference`` (it is copied, not
        changed): the loop hashes its reference, which does not change, once per call.
    """
    if reference_hash is None:
        h = hashlib.sha256()
        _hash_update(h, trial.reference)
    else:
        h = reference_hash.copy()
    _hash_update(h, trial.input)
    _hash_update(h, trial.output)
    return h.hexdigest()


def _limits_to_json(limits: Mapping[str, AxisLimits]) -> dict[str, dict[str, Any]]:
    return {
        a: {
            "position": v.position,
            "velocity": v.velocity,
            "acceleration": v.acceleration,
            "unit": v.unit,
        }
        for a, v in limits.items()
    }


@dataclass(kw_only=True, eq=False)
class LearnRecord:
    """What the loop keeps beside the learner's state (saved in its ``meta``).

    Attributes
    ----------
    digests : list of str
        `trial_digest` of every trial learned from.
    limits : dict of str to AxisLimits or None
        Declared limits every published command was checked against.
    first_output : numpy.ndarray or None
        Measured output of trial 1 (feedback only when ``u_1 = y_d``), shape (N, n_axes).
    last_output, last_input : numpy.ndarray or None
        Output and input of the latest trial, shape (N, n_axes).
    machine : dict or None
        Snapshot of a `microfab.machines.base.Resumable` machine after the latest trial
        (restored on resume, so a resumed run is bit-identical to an uninterrupted one).
    """

    digests: list[str] = field(default_factory=list)
    limits: dict[str, AxisLimits] | None = None
    first_output: np.ndarray | None = None
    last_output: np.ndarray | None = None
    last_input: np.ndarray | None = None
    machine: dict[str, Any] | None = None

    def to_meta(self) -> dict[str, Any]:
        """The form kept in a learner's ``meta``: `to_json` with the signals as arrays.

        The arrays are the record's own (not copied); a learner saves them as arrays
        (`microfab.control.ilc.FrequencyILC.save`), which costs their bytes, where the
        lists of `to_json` cost a Python float each.
        """
        return {
            "digests": list(self.digests),
            "limits": None if self.limits is None else _limits_to_json(self.limits),
            "first_output": self.first_output,
            "last_output": self.last_output,
            "last_input": self.last_input,
            "machine": self.machine,
        }

    def to_json(self) -> dict[str, Any]:
        """JSON-ready form."""

        def arr(a: np.ndarray | None) -> list[list[float]] | None:
            return None if a is None else np.asarray(a, dtype=float).tolist()

        return {
            "digests": list(self.digests),
            "limits": None if self.limits is None else _limits_to_json(self.limits),
            "first_output": arr(self.first_output),
            "last_output": arr(self.last_output),
            "last_input": arr(self.last_input),
            "machine": self.machine,
        }

    @classmethod
    def from_meta(
        cls, meta: Mapping[str, Any], shape: tuple[int, ...] | None = None
    ) -> LearnRecord:
        """Read the record from a learner's ``meta`` (also the flat layout of format 1).

        Parameters
        ----------
        meta : mapping
            The learner's ``meta``.
        shape : tuple of int, optional
            Shape (N, n_axes) of the learner's signals, which the saved ones must have.

        Raises
        ------
        microfab.io.schema.SchemaError
            A saved signal that is not a finite real array of ``shape``, digests that are
            not strings, or limits that are not valid.
        """
        raw = meta.get(RECORD_KEY)
        if not isinstance(raw, Mapping):  # format 1: flat keys
            raw = {
                "digests": meta.get("digests", []),
                "limits": meta.get("limits"),
                "first_output": meta.get("fb_output"),
                "last_output": meta.get("last_output"),
            }
        where = "the learning state's record"

        def arr(name: str) -> np.ndarray | None:
            v = raw.get(name)
            if v is None:
                return None
            v = np.asarray(v) if isinstance(v, list) else v
            if isinstance(v, np.ndarray) and v.dtype.kind in "iu":
                v = v.astype(float)
            return check_array(where, name, v, shape=shape or (None, None))

        digests = raw.get("digests") or []
        if not isinstance(digests, list) or not all(isinstance(d, str) for d in digests):
            raise SchemaError(f"{where}: digests must be a list of strings, got {digests!r}")
        lim = raw.get("limits")
        try:
            limits = None if not lim else {a: AxisLimits(**v) for a, v in lim.items()}
        except (AttributeError, TypeError, ValueError) as exc:
            raise SchemaError(f"{where}: limits are not valid: {exc}") from None
        return cls(
            digests=list(digests),
            limits=limits,
            first_output=arr("first_output"),
            last_output=arr("last_output"),
            last_input=arr("last_input"),
            machine=raw.get("machine"),
        )


def _check_trial(
    learner: Learner,
    trial: Trial,
    record: LearnRecord,
    ref: np.ndarray,
    ref_hash: Any,
) -> str:
    """Refuse a trial the learner cannot learn from; return its `trial_digest`.

    ``ref`` is the learner's reference and ``ref_hash`` a SHA-256 fed with it: a trial
    that carries ``ref`` itself (a twin reports none) needs no comparison, and its
    digest starts from ``ref_hash``.
    """
    if trial.axes != learner.axes:
        raise TrialError(f"axes {list(trial.axes)} differ from the learner's {list(learner.axes)}")
    if abs(trial.dt - learner.dt) > 1e-6 * learner.dt:
        raise TrialError(
            f"sample time {trial.dt:.9g} s differs from the learner's {learner.dt:.9g} s "
            "(sample rate changed)"
        )
    if trial.reference.shape != ref.shape:
        n = trial.reference.shape[0]
        raise TrialError(
            f"{n} samples ({n * trial.dt:.6g} s), but the period being learned is "
            f"{ref.shape[0]} samples ({ref.shape[0] * learner.dt:.6g} s)"
        )
    if trial.reference is not ref:
        tol = 1e-9 * max(1.0, float(np.max(np.abs(ref))))
        diff = float(np.max(np.abs(trial.reference - ref)))
        if diff > tol:
            raise TrialError(
                f"the reference changed since the first trial (max difference {diff:.3g}); "
                "start a new state directory for a new reference"
            )
    digest = trial_digest(trial, ref_hash if trial.reference is ref else None)
    if digest in record.digests:
        raise TrialError("this trial was already learned from")
    return digest


def learn(
    machine: Machine,
    learner: Learner,
    *,
    iterations: int,
    state_dir: str | Path | None = None,
    limits: Mapping[str, AxisLimits] | None = None,
    publish: Callable[[np.ndarray], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured: Callable[[int, Measurement], None] | None = None,
    save_every_s: float = 0.0,
) -> LearnRecord:
    """Run trials until the learner has learned from ``iterations`` of them.

    Parameters
    ----------
    machine : Machine
        Where each command is played (a twin, or `microfab.machines.files.FileMachine`).
    learner : Learner
        The learner, fresh or loaded from ``state_dir``; a learner that has already
        learned ``iterations`` trials runs nothing.
    iterations : int
        Total number of trials to have learned from when the call returns.
    state_dir : str or Path, optional
        Where the learner and the loop record are saved: after every trial, or as
        ``save_every_s`` says.
    limits : mapping of str to AxisLimits, optional
        Declared limits every published command must respect; the saved ones are used
        when omitted. Stored with the state.
    publish : callable, optional
        Called with each next command (shape (N, n_axes)) after its limit check and before
        the state is saved, e.g. to write the input file for hardware.
    progress : callable, optional
        ``progress(done, total)`` after each trial.
    measured : callable, optional
        ``measured(iteration, measurement)`` with each raw measurement (1-based).
    save_every_s : float
        With ``state_dir``: the least wall time, s, between two saves (0: after every
        trial, what hardware through files needs). The last trial is always saved, and so
        are the trials learned before an interruption that comes between trials
        (Ctrl-C in a machine run); a killed process loses at most the trials of the last
        ``save_every_s``, which a resumed run plays again with the same bits (the
        machine's snapshot is taken at every trial's end).

    Returns
    -------
    LearnRecord
        The loop's record (first and last trial, digests, limits).

    Raises
    ------
    TrialError
        A trial with other axes, sample time, length or reference, or one already learned.
    microfab.core.limits.LimitViolation
        The next command would exceed the limits: nothing is published or saved.
    """
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if not save_every_s >= 0:
        raise ValueError(f"save_every_s must be >= 0 s, got {save_every_s}")
    record = LearnRecord.from_meta(learner.meta, learner.current_input().shape)
    if limits is not None:
        record.limits = dict(limits)
    if record.machine is not None and isinstance(machine, Resumable):
        machine.restore(record.machine)  # where the machine stood after the last trial
    # Once per call, not per trial: the reference (the learner's copy, which trials from a
    # machine that reports none carry as is) and the SHA-256 of its bytes.
    ref = learner.reference
    ref_hash = hashlib.sha256()
    _hash_update(ref_hash, ref)
    # The record reaches the learner's meta with its signals as arrays (`to_meta`): saved
    # as archive members after each trial with a state directory, else once, when the
    # loop ends (also by an exception).
    learned = False
    pending = False  # trials learned since the last save
    updating = False  # between the learner's update and the record's: not a boundary
    last_save = time.monotonic()

    def save() -> None:
        nonlocal pending, last_save
        learner.save(state_dir, {RECORD_KEY: record.to_meta()})  # type: ignore[arg-type]
        pending, last_save = False, time.monotonic()

    try:
        while learner.iteration < iterations:
            u = learner.current_input()
            meas = machine.run(u)
            if measured is not None:
                measured(learner.iteration + 1, meas)
            trial = Trial(
                dt=meas.dt,
                reference=ref if meas.reference is None else meas.reference,
                input=meas.command,
                output=meas.output,
                axes=meas.axes,
            )
            digest = _check_trial(learner, trial, record, ref, ref_hash)
            updating = True
            u_next = learner.update(trial)
            if record.limits is not None:
                check_command(u_next, trial.dt, record.limits, trial.axes, periodic=True)
            if publish is not None:
                publish(u_next)
            record.digests.append(digest)
            if record.first_output is None:
                record.first_output = np.array(trial.output, dtype=float)
            record.last_output = np.array(trial.output, dtype=float)
            record.last_input = np.array(trial.input, dtype=float)
            learned = True
            if state_dir is not None:
                if isinstance(machine, Resumable):
                    record.machine = machine.snapshot()
                pending = True
                if learner.iteration >= iterations or time.monotonic() - last_save >= save_every_s:
                    save()
            updating = False
            if progress is not None:
                progress(learner.iteration, iterations)
    finally:
        if state_dir is not None and pending and not updating:
            save()  # interrupted between trials: keep what was learned
        if learned and state_dir is None:
            if isinstance(machine, Resumable):
                record.machine = machine.snapshot()
            learner.meta[RECORD_KEY] = record.to_meta()
    return record
