"""Hardware-through-files ILC: `ilc_step` against the in-memory learner and bad inputs."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import microfab.io.checkpoint as checkpoint_mod
from microfab.control.ilc import FrequencyILC, ILCConfig, Trial
from microfab.core.limits import AxisLimits, LimitViolation
from microfab.io.trace import read_columns, write_columns
from microfab.machines.files import TrialFileError, ilc_step
from microfab.machines.galvo.machine import galvo_twin
from microfab.trajectory.periodic import square_scan

AXES = ("x", "y")
DT = 1e-6
Columns = dict[str, np.ndarray]


@pytest.fixture(scope="module")
def ref() -> np.ndarray:
    return square_scan(400, (1.0, 1.44), 1e6)


def trial_columns(ref: np.ndarray, u: np.ndarray, y: np.ndarray, dt: float = DT) -> Columns:
    n = ref.shape[0]
    cols: Columns = {"time": np.arange(n) * dt}
    for i, a in enumerate(AXES):
        cols[f"reference_{a}"] = ref[:, i].copy()
        cols[f"input_{a}"] = u[:, i].copy()
        cols[f"output_{a}"] = y[:, i].copy()
    return cols


def read_next(path: Path) -> np.ndarray:
    cols = read_columns(path)
    assert list(cols) == ["time", "input_x", "input_y"]
    return np.column_stack([cols["input_x"], cols["input_y"]])


def dir_hashes(d: Path) -> dict[str, str]:
    if not d.exists():
        return {}
    return {
        str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(d.rglob("*"))
        if p.is_file()
    }


def assert_close_rel(a: np.ndarray, b: np.ndarray, rtol: float = 1e-12) -> None:
    scale = max(float(np.max(np.abs(b))), 1e-300)
    assert float(np.max(np.abs(a - b))) <= rtol * scale


def run_workflow(tmp: Path, ref: np.ndarray, steps: int, suffix: str) -> None:
    """Learn through files and in memory from the same measurements; compare each step."""
    machine = galvo_twin(seed=3)
    mem = FrequencyILC(ref, DT, AXES)
    state, nxt = tmp / "state", tmp / f"next{suffix}"
    u = mem.initial_input()
    for k in range(steps):
        y = machine.run(u).output
        trial = tmp / f"trial_{k:02d}{suffix}"
        write_columns(trial, trial_columns(ref, u, y))
        rep = ilc_step(trial, state, nxt)
        u_file = read_next(nxt)
        u_mem = mem.update(Trial(dt=DT, reference=ref, input=u, output=y, axes=AXES))
        assert rep.iteration == k + 1 == mem.iteration
        assert rep.out_path == nxt
        assert_close_rel(u_file, u_mem)
        np.testing.assert_allclose(
            [rep.rms[a] for a in AXES], mem.rms_history[-1], rtol=1e-12, atol=0
        )
        assert rep.harmonics == {a: int(h.size) for a, h in zip(AXES, mem.harmonics, strict=True)}
        u = u_file
    saved = FrequencyILC.load(state)
    assert saved.iteration == steps
    np.testing.assert_allclose(saved.rms_history, mem.rms_history, rtol=1e-12, atol=0)
    np.testing.assert_allclose(saved.pp_history, mem.pp_history, rtol=1e-12, atol=0)


def test_csv_workflow_reproduces_simulated_learning_curve(tmp_path, ref):
    run_workflow(tmp_path, ref, 12, ".csv")
    rms = FrequencyILC.load(tmp_path / "state").rms_history
    assert rms.shape == (12, 2)
    assert np.all(rms[11] < rms[0] / 10), rms


def test_mat_workflow(tmp_path, ref):
    run_workflow(tmp_path, ref, 3, ".mat")
    rms = FrequencyILC.load(tmp_path / "state").rms_history
    assert np.all(rms[2] < rms[0])


# ---------------------------------------------------------------------------- bad inputs
@pytest.fixture
def after_one_step(tmp_path, ref):
    """A state after step 1, the trial-1 file, and valid columns of trial 2."""
    machine = galvo_twin(seed=3)
    u1 = ref.copy()
    t1 = tmp_path / "trial_01.csv"
    write_columns(t1, trial_columns(ref, u1, machine.run(u1).output))
    state, nxt = tmp_path / "state", tmp_path / "next.csv"
    ilc_step(t1, state, nxt)
    u2 = read_next(nxt)
    cols2 = trial_columns(ref, u2, machine.run(u2).output)
    return tmp_path, state, t1, cols2


def _nan(c: Columns) -> Columns:
    c["output_x"][17] = np.nan
    return c


def _short(c: Columns) -> Columns:
    return {k: v[:-100] for k, v in c.items()}


def _rate(c: Columns) -> Columns:
    c["time"] = np.arange(c["time"].size) * 2 * DT
    return c


def _drop(*names: str) -> Callable[[Columns], Columns]:
    return lambda c: {k: v for k, v in c.items() if k not in names}


def _ref_changed(c: Columns) -> Columns:
    c["reference_x"] = c["reference_x"] * 1.01
    return c


def _nonuniform(c: Columns) -> Columns:
    c["time"][100] += 0.3 * DT
    return c


def _axes(c: Columns) -> Columns:
    return {k.replace("_y", "_z"): v for k, v in c.items()}


BAD_LATER = {
    "nan": (_nan, r"'output_x'.*sample 17"),
    "short": (_short, r"2400 samples.*2500 samples"),
    "rate": (_rate, r"sample (time|rate)"),
    "no_output_y": (_drop("output_y"), r"output_y"),
    "no_time": (_drop("time"), r"'time'"),
    "no_reference": (_drop("reference_x", "reference_y"), r"reference_"),
    "reference_changed": (_ref_changed, r"reference changed"),
    "nonuniform_time": (_nonuniform, r"uniform"),
    "other_axes": (_axes, r"axes"),
    "fewer_axes": (_drop("reference_y", "input_y", "output_y"), r"axes"),
}


def _assert_refused(
    trial: Path,
    state: Path,
    out_dir: Path,
    exc: type[Exception],
    match: str,
    **kwargs: object,
) -> Exception:
    before = dir_hashes(state)
    existed = state.exists()
    fresh = out_dir / "never_written.csv"
    old = out_dir / "old_next.csv"
    old.write_bytes(b"sentinel\n")
    for out in (fresh, old):
        with pytest.raises(exc, match=match) as info:
            ilc_step(trial, state, out, **kwargs)  # type: ignore[arg-type]
        assert "\n" not in str(info.value), str(info.value)
    assert not fresh.exists()
    assert old.read_bytes() == b"sentinel\n"
    assert state.exists() == existed
    assert dir_hashes(state) == before
    return info.value


@pytest.mark.parametrize("case", list(BAD_LATER))
def test_bad_trial_leaves_state_and_next_alone(after_one_step, case):
    tmp, state, _, cols2 = after_one_step
    mutate, match = BAD_LATER[case]
    bad = tmp / f"bad_{case}.csv"
    write_columns(bad, mutate({k: v.copy() for k, v in cols2.items()}))
    _assert_refused(bad, state, tmp, TrialFileError, match)
    # the good trial 2 is still accepted afterwards
    good = tmp / "good.csv"
    write_columns(good, cols2)
    assert ilc_step(good, state, tmp / "n2.csv").iteration == 2


def test_same_trial_twice_is_refused(after_one_step):
    tmp, state, t1, _ = after_one_step
    _assert_refused(t1, state, tmp, TrialFileError, "already learned")


def test_missing_file(after_one_step):
    tmp, state, _, _ = after_one_step
    _assert_refused(tmp / "nope.csv", state, tmp, FileNotFoundError, "nope.csv")


@pytest.mark.parametrize(
    "case", ["nan", "no_output_y", "no_time", "no_reference", "nonuniform_time"]
)
def test_bad_first_trial_creates_no_state(tmp_path, ref, case):
    mutate, match = BAD_LATER[case]
    cols = trial_columns(ref, ref, ref + 0.01 * np.sin(np.arange(ref.shape[0]))[:, None])
    bad = tmp_path / "bad.csv"
    write_columns(bad, mutate(cols))
    _assert_refused(bad, tmp_path / "state", tmp_path, TrialFileError, match)


# ------------------------------------------------------------------------------ limits
TINY = {a: AxisLimits(position=0.5, velocity=1e9, acceleration=1e20) for a in AXES}


def test_limit_refusal_on_first_step_writes_nothing(tmp_path, ref):
    machine = galvo_twin(seed=3)
    trial = tmp_path / "trial.csv"
    write_columns(trial, trial_columns(ref, ref, machine.run(ref).output))
    err = _assert_refused(
        trial, tmp_path / "state", tmp_path, LimitViolation, "position", limits=TINY
    )
    assert "nothing was emitted" in str(err)


def test_limit_refusal_on_later_step_keeps_state(after_one_step):
    tmp, state, _, cols2 = after_one_step
    trial = tmp / "trial_02.csv"
    write_columns(trial, cols2)
    before = dir_hashes(state)
    nxt = tmp / "next2.csv"
    with pytest.raises(LimitViolation, match="position"):
        ilc_step(trial, state, nxt, limits=TINY)
    assert not nxt.exists()
    assert dir_hashes(state) == before


# --------------------------------------------------------------------- interrupted write
def test_interrupted_state_write_is_recoverable(tmp_path, ref, monkeypatch):
    machine = galvo_twin(seed=3)
    u1 = ref.copy()
    t1 = tmp_path / "trial_01.csv"
    write_columns(t1, trial_columns(ref, u1, machine.run(u1).output))
    a_state, a_next = tmp_path / "a_state", tmp_path / "a_next.csv"
    ilc_step(t1, a_state, a_next)
    u2 = read_next(a_next)
    t2 = tmp_path / "trial_02.csv"
    write_columns(t2, trial_columns(ref, u2, machine.run(u2).output))
    ref_rep = ilc_step(t2, a_state, a_next)
    ref_next = a_next.read_bytes()
    ref_ilc = FrequencyILC.load(a_state)

    b_state, b_next = tmp_path / "b_state", tmp_path / "b_next.csv"
    ilc_step(t1, b_state, b_next)
    after_step1 = dir_hashes(b_state)
    calls = []

    def broken(*args, **kwargs):
        calls.append(args)
        raise OSError("disk full (simulated)")

    with monkeypatch.context() as mp:
        mp.setattr(checkpoint_mod, "atomic_save_npz", broken)
        with pytest.raises(OSError, match="disk full"):
            ilc_step(t2, b_state, b_next)
    assert calls, "the patched writer was not used"
    assert dir_hashes(b_state) == after_step1
    assert FrequencyILC.load(b_state).iteration == 1

    rep = ilc_step(t2, b_state, b_next)
    assert rep.iteration == ref_rep.iteration == 2
    assert rep.rms == ref_rep.rms
    assert b_next.read_bytes() == ref_next
    got = FrequencyILC.load(b_state)
    for name in ("reference", "pinv", "mask"):
        np.testing.assert_array_equal(getattr(got.state, name), getattr(ref_ilc.state, name))
    np.testing.assert_array_equal(np.stack(got.state.inputs), np.stack(ref_ilc.state.inputs))
    np.testing.assert_array_equal(got.rms_history, ref_ilc.rms_history)
    np.testing.assert_equal(got.state.meta, ref_ilc.state.meta)  # signals kept as arrays


def test_older_trial_fed_again_is_refused(after_one_step):
    tmp, state, t1, cols2 = after_one_step
    t2 = tmp / "trial_02.csv"
    write_columns(t2, cols2)
    ilc_step(t2, state, tmp / "next2.csv")
    _assert_refused(t1, state, tmp, TrialFileError, "already learned")


# ---------------------------------------------------------------------- issue 13 cases
def test_axis_with_an_empty_name_is_refused(tmp_path):
    # header time,reference_,input_,output_ was taken as an axis '' and wrote 'input_'
    t = np.arange(64) * 1e-5
    r = np.sin(2 * np.pi * t / (64e-5))
    trial = tmp_path / "t.csv"
    write_columns(trial, {"time": t, "reference_": r, "input_": r, "output_": 0.9 * r})
    _assert_refused(trial, tmp_path / "st", tmp_path, TrialFileError, r"'reference_' names no")


def _short_period(tmp_path: Path, n: int = 10, dt: float = 1e-5) -> Path:
    t = np.arange(n) * dt
    r = np.sin(2 * np.pi * t / (n * dt))
    trial = tmp_path / "short.csv"
    cols = {"time": t}
    for a in AXES:
        cols |= {f"reference_{a}": r, f"input_{a}": r, f"output_{a}": 0.9 * np.roll(r, 1)}
    write_columns(trial, cols)
    return trial


def test_period_too_short_for_any_harmonic_is_refused(tmp_path):
    # 10 samples at 10 us: 10 kHz, above the 8 kHz cutoff; printed "harmonics x 0", exit 0
    trial = _short_period(tmp_path)
    err = _assert_refused(trial, tmp_path / "st", tmp_path, TrialFileError, "nothing can be")
    assert "no harmonic at or below the cutoff 8000 Hz" in str(err)
    assert "--cutoff-hz" in str(err)
    # with the cutoff above the repetition rate there is something to learn
    rep = ilc_step(trial, tmp_path / "st", tmp_path / "n.csv", config=ILCConfig(cutoff_hz=2e4))
    assert all(n >= 1 for n in rep.harmonics.values())


def test_first_trial_without_learnable_content_is_refused(tmp_path):
    n = 100
    cols = {"time": np.arange(n) * 1e-5}
    for a in AXES:  # nothing commanded: no harmonic, not even the mean, has content
        cols |= {f"reference_{a}": np.zeros(n), f"input_{a}": np.zeros(n)}
        cols[f"output_{a}"] = 1e-4 * np.sin(np.arange(n))
    trial = tmp_path / "idle.csv"
    write_columns(trial, cols)
    err = _assert_refused(trial, tmp_path / "st", tmp_path, TrialFileError, "nothing can be")
    assert "has content in the input" in str(err)


def test_a_constant_reference_learns_its_mean(tmp_path):
    n = 100
    cols = {"time": np.arange(n) * 1e-5}
    for a in AXES:  # an offset to hold: the mean is learned, nothing else has content
        cols |= {f"reference_{a}": np.full(n, 0.2), f"input_{a}": np.full(n, 0.2)}
        cols[f"output_{a}"] = np.full(n, 0.19)
    trial = tmp_path / "flat.csv"
    write_columns(trial, cols)
    rep = ilc_step(trial, tmp_path / "st", tmp_path / "n.csv")
    assert rep.harmonics == {"x": 1, "y": 1}


def test_an_axis_without_its_reference_is_refused_not_dropped(tmp_path) -> None:
    """Issue 32: a trial with input_x, output_x but no reference_x lost axis x silently."""
    from microfab.machines.files import TrialFileError, read_trial_file

    n = 16
    t = np.arange(n) * 1e-5
    r = np.sin(2 * np.pi * np.arange(n) / n)
    cols = {"time": t, "reference_y": r, "input_y": r, "output_y": r, "input_x": r,
            "output_x": r}  # fmt: skip
    write_columns(tmp_path / "t.csv", cols)
    with pytest.raises(TrialFileError, match="axis 'x' has no 'reference_x' column"):
        read_trial_file(tmp_path / "t.csv")
    cols["reference_x"] = r
    write_columns(tmp_path / "t.csv", cols)
    assert set(read_trial_file(tmp_path / "t.csv").axes) == {"x", "y"}
