"""The one learning loop: twin and files give the same learning; resume; refusals."""

from __future__ import annotations

import hashlib
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from microfab.control.ilc import STATE_FILE, FrequencyILC, Trial
from microfab.control.learning import Learner
from microfab.core.limits import AxisLimits, LimitViolation
from microfab.io.trace import read_columns, write_columns
from microfab.machines.files import FileMachine
from microfab.machines.galvo.machine import galvo_twin
from microfab.machines.learning import RECORD_KEY, LearnRecord, TrialError, learn, trial_digest
from microfab.trajectory.periodic import square_scan

DT = 1e-6


@pytest.fixture(scope="module")
def ref() -> np.ndarray:
    return square_scan(500, (1.0, 1.44), 1e6)


def test_frequency_ilc_is_a_learner(ref):
    assert isinstance(FrequencyILC(ref, DT, ("x", "y")), Learner)


def test_learn_on_the_twin_converges_and_keeps_its_record(ref, tmp_path):
    ilc = FrequencyILC(ref, DT, ("x", "y"))
    seen = []
    rec = learn(
        galvo_twin(seed=1),
        ilc,
        iterations=6,
        state_dir=tmp_path,
        progress=lambda d, t: seen.append((d, t)),
    )
    assert seen == [(k, 6) for k in range(1, 7)]
    rms = ilc.rms_history
    assert rms.shape == (6, 2)
    assert np.all(rms[-1] < rms[0] / 5)
    assert len(set(rec.digests)) == 6
    saved = LearnRecord.from_meta(FrequencyILC.load(tmp_path).meta)
    np.testing.assert_array_equal(saved.first_output, rec.first_output)
    np.testing.assert_array_equal(saved.last_input, rec.last_input)
    # fully learned: a second call runs nothing
    again = FrequencyILC.load(tmp_path)
    rec2 = learn(galvo_twin(seed=1), again, iterations=6, state_dir=tmp_path)
    assert again.iteration == 6 and rec2.digests == rec.digests


def test_the_digest_from_the_hashed_reference_is_the_full_digest(ref):
    """The loop hashes its reference once per call: the digests are those of format 3."""
    meas = galvo_twin(seed=3).run(ref)
    tr = Trial(dt=DT, reference=ref, input=meas.command, output=meas.output, axes=("x", "y"))
    h = hashlib.sha256()
    h.update(ref.data)
    full = trial_digest(tr)
    assert trial_digest(tr, h) == full
    assert trial_digest(tr, h) == full  # the hash given is copied, not fed
    whole = hashlib.sha256(b"".join(a.tobytes() for a in (ref, meas.command, meas.output)))
    assert full == whole.hexdigest()


def test_the_record_keeps_its_signals_as_arrays(ref, tmp_path):
    """Saved after each trial as archive members, not JSON lists; the same without a state."""
    learn(galvo_twin(seed=1), FrequencyILC(ref, DT, ("x", "y")), iterations=2, state_dir=tmp_path)
    with np.load(tmp_path / STATE_FILE) as z:
        assert len(str(z["meta"])) < 10_000  # a JSON list of one signal alone: ~80 kB
    saved = LearnRecord.from_meta(FrequencyILC.load(tmp_path).meta)
    ilc = FrequencyILC(ref, DT, ("x", "y"))
    rec = learn(galvo_twin(seed=1), ilc, iterations=2)
    assert isinstance(ilc.meta[RECORD_KEY]["last_output"], np.ndarray)
    for name in ("first_output", "last_output", "last_input"):
        assert getattr(saved, name).tobytes() == getattr(rec, name).tobytes()
    assert saved.digests == rec.digests and saved.machine == rec.machine


def test_the_same_trial_twice_is_refused(ref):
    class Replay:
        axes, dt = ("x", "y"), DT

        def __init__(self) -> None:
            self.meas = galvo_twin(seed=2).run(ref)

        def run(self, command):
            return self.meas

    ilc = FrequencyILC(ref, DT, ("x", "y"))
    with pytest.raises(TrialError, match="already learned"):
        learn(Replay(), ilc, iterations=2)
    assert ilc.iteration == 1


def test_a_command_beyond_the_limits_is_never_published(ref, tmp_path):
    published = []
    tight = {a: AxisLimits(position=1.2, velocity=5e4, acceleration=2e10) for a in "xy"}
    ilc = FrequencyILC(ref, DT, ("x", "y"))
    with pytest.raises(LimitViolation):
        learn(
            galvo_twin(seed=0),
            ilc,
            iterations=3,
            state_dir=tmp_path,
            limits=tight,
            publish=published.append,
        )
    assert published == []
    assert not FrequencyILC.exists(tmp_path)


def _write_trial(path: Path, ref: np.ndarray, u: np.ndarray, y: np.ndarray) -> None:
    cols = {"time": np.arange(ref.shape[0]) * DT}
    for i, a in enumerate("xy"):
        cols |= {f"reference_{a}": ref[:, i], f"input_{a}": u[:, i], f"output_{a}": y[:, i]}
    write_columns(path, cols)


def test_file_machine_in_the_loop_matches_the_twin(ref, tmp_path):
    """A rig watching a folder: learn() writes the command, the rig answers with a trial."""
    twin, mirror = galvo_twin(seed=4), galvo_twin(seed=4)
    cmd, trial = tmp_path / "command.csv", tmp_path / "trial.csv"
    stop = threading.Event()

    def rig() -> None:
        last = None
        while not stop.is_set():
            if cmd.is_file() and cmd.stat().st_mtime_ns != last:
                last = cmd.stat().st_mtime_ns
                c = read_columns(cmd)
                u = np.column_stack([c["input_x"], c["input_y"]])
                _write_trial(trial, ref, u, twin.run(u).output)
            time.sleep(0.01)

    th = threading.Thread(target=rig, daemon=True)
    th.start()
    try:
        _write_trial(trial, ref, ref, np.zeros_like(ref))  # a stale file: must be waited out
        time.sleep(0.05)
        files = FileMachine(trial, cmd, timeout_s=20.0, poll_s=0.01)
        ilc_files = FrequencyILC(ref, DT, ("x", "y"))
        learn(files, ilc_files, iterations=4)
    finally:
        stop.set()
        th.join()
    ilc_twin = FrequencyILC(ref, DT, ("x", "y"))
    learn(mirror, ilc_twin, iterations=4)
    np.testing.assert_allclose(ilc_files.rms_history, ilc_twin.rms_history, rtol=1e-9)


def test_file_machine_is_a_machine(ref, tmp_path):
    from microfab.machines.base import Machine

    trial = tmp_path / "trial.csv"
    _write_trial(trial, ref, ref, ref)
    fm = FileMachine(trial)
    assert isinstance(fm, Machine)
    assert fm.axes == ("x", "y") and fm.dt == pytest.approx(DT)
    np.testing.assert_array_equal(fm.run_once(ref).reference, ref)


def test_file_machine_times_out_with_a_clear_message(ref, tmp_path):
    trial = tmp_path / "trial.csv"
    _write_trial(trial, ref, ref, ref)
    time.sleep(0.02)
    fm = FileMachine(trial, tmp_path / "cmd.csv", timeout_s=0.2, poll_s=0.05)
    fm.peek()
    old = trial.stat().st_mtime
    import os

    os.utime(trial, (old - 60, old - 60))
    with pytest.raises(TimeoutError, match="no measured trial"):
        fm.run(ref)


class _Interrupting:
    """A twin that raises KeyboardInterrupt in its ``n``-th run (a Ctrl-C mid-trial)."""

    def __init__(self, machine, n: int) -> None:
        self.machine, self.n, self.runs = machine, n, 0
        self.axes, self.dt = machine.axes, machine.dt

    def run(self, command):
        self.runs += 1
        if self.runs == self.n:
            raise KeyboardInterrupt
        return self.machine.run(command)

    def snapshot(self):
        return self.machine.snapshot()

    def restore(self, snap):
        self.machine.restore(snap)


def test_saving_every_few_seconds_resumes_bit_identical(ref, tmp_path, monkeypatch):
    """Saves spaced in time: only some trials write the state; an interruption between
    trials keeps every learned one; a resumed run gives the uninterrupted run's bits."""
    import microfab.machines.learning as learning_mod

    whole = FrequencyILC(ref, DT, ("x", "y"))
    learn(galvo_twin(seed=1), whole, iterations=7, state_dir=tmp_path / "whole")
    clock = iter(np.arange(0.0, 1000.0, 0.4))  # each reading 0.4 s later
    monkeypatch.setattr(learning_mod.time, "monotonic", lambda: float(next(clock)))
    saves = []
    real_save = FrequencyILC.save
    monkeypatch.setattr(
        FrequencyILC,
        "save",
        lambda self, d, extra=None: saves.append(self.iteration) or real_save(self, d, extra),
    )
    part = FrequencyILC(ref, DT, ("x", "y"))
    with pytest.raises(KeyboardInterrupt):
        learn(_Interrupting(galvo_twin(seed=1), 6), part, iterations=7,
              state_dir=tmp_path / "part", save_every_s=1.0)  # fmt: skip
    assert saves[-1] == 5 and len(saves) < 5, saves  # spaced saves, then the 5 learned kept
    again = FrequencyILC.load(tmp_path / "part")
    assert again.iteration == 5
    learn(
        galvo_twin(seed=99), again, iterations=7, state_dir=tmp_path / "part", save_every_s=1.0
    )  # fmt: skip  (the twin is restored from the saved snapshot)
    np.testing.assert_array_equal(np.stack(again.state.inputs), np.stack(whole.state.inputs))
    np.testing.assert_array_equal(again.rms_history, whole.rms_history)
    with pytest.raises(ValueError, match="save_every_s"):
        learn(galvo_twin(seed=1), FrequencyILC(ref, DT, ("x", "y")), iterations=1,
              save_every_s=-1.0)  # fmt: skip
