"""``microfab rc step``: the plug-in RC of seed 001 on hardware through files.

The file-based step and the simulated `PluginRC` are one computation on one state format:
a loop closed through files equals the simulated RC, and a simulated state continues
through files (and back).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import control
from microfab.cli import app
from microfab.control.pid import PID
from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import PluginRC, RCConfig
from microfab.io.trace import read_columns, write_columns
from microfab.machines.nanomanipulator.files import CONTOUR_FILE, STATE_FILE
from microfab.plants.base import LTIPlant
from microfab.plants.lti import block_diag, discretize
from microfab.sim.loop import simulate

runner = CliRunner()
DT = 1e-4  # assumed 10 kHz (the seed 001 twin's)
N = 100  # samples per period (a 100 Hz contour keeps the test short)
PX = ((548248.13,), (1.0, 14.88, 101793.23))  # seed 001 eq. (9), mm/V
PY = ((319852.42,), (1.0, 18.52, 99664.23))
CFG = RCConfig(period_s=N * DT, dt=DT, tau_s=5e-4, lead_samples=4)
OPTS = ["--tau-ms", "0.5", "--lead-samples", "4"]


def _plant() -> LTIPlant:
    return LTIPlant(block_diag(discretize(control.tf(*PX), DT), discretize(control.tf(*PY), DT)))


def _pid() -> PID:
    return PID.tuned([PX, PY], bandwidth_hz=200.0, phase_margin_deg=45.0, dt=DT)


def _circle(periods: int) -> tuple[np.ndarray, ...]:
    t = np.arange(periods * N) * DT
    w = 2 * np.pi / (N * DT)
    pos = 0.075 * np.column_stack([np.cos(w * t), np.sin(w * t)])
    vel = 0.075 * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    return pos, vel, -(w**2) * pos


def _write_trial(path: Path, ref: np.ndarray, measured: np.ndarray, t0: float = 0.0) -> None:
    t = t0 + np.arange(ref.shape[0]) * DT
    write_columns(
        path,
        {
            "time": t,
            "ref_x": ref[:, 0],
            "ref_y": ref[:, 1],
            "x": measured[:, 0],
            "y": measured[:, 1],
        },
    )


def _step(trial: Path, state: Path, out: Path, *extra: str) -> object:
    return runner.invoke(
        app, ["rc", "step", str(trial), "--state", str(state), "--out", str(out), *extra]
    )


def _command(out: Path) -> np.ndarray:
    cols = read_columns(out)
    return np.column_stack([cols["command_x"], cols["command_y"]])


def test_a_loop_closed_through_files_is_the_simulated_rc(tmp_path: Path) -> None:
    periods = 8
    pos, vel, acc = _circle(periods)
    sim = simulate(_plant(), PluginRC(_pid(), CFG), pos, derivatives=(vel, acc))
    sim_e = pos - sim.measured
    # the same loop on "hardware": the PID runs the command file, the RC runs through files
    plant, pid, st = _plant(), _pid(), None
    command = pos[:N].copy()  # the first period runs on the plain contour
    state, rms = tmp_path / "state", []
    for j in range(periods):
        sl = slice(j * N, (j + 1) * N)
        res = simulate(plant, pid, command, state=st, derivatives=(vel[sl], acc[sl]))
        st = res.final_state
        e = pos[sl] - res.measured
        np.testing.assert_allclose(e, sim_e[sl], rtol=0, atol=1e-12)
        rms.append(np.sqrt(np.mean(np.sum(e**2, axis=1))))
        _write_trial(tmp_path / "trial.csv", pos[sl], res.measured, t0=j * N * DT)
        r = _step(tmp_path / "trial.csv", state, tmp_path / "next.csv", *(OPTS if not j else ()))
        assert r.exit_code == 0, r.output
        assert f"period {j + 1}" in r.output and ("new state" in r.output) == (j == 0)
        command = _command(tmp_path / "next.csv")
    # the saved memory is the simulated RC's at the same sample
    sim_mem = PluginRC(_pid(), CFG).memory_of(sim.final_state.controller)
    mem = RCMemory.load(state / STATE_FILE)
    assert mem.config == CFG and mem.samples == sim_mem.samples == periods * N
    np.testing.assert_allclose(mem.memory, sim_mem.memory, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mem.error, sim_mem.error, rtol=0, atol=1e-12)
    assert rms[-1] < rms[0] / 5  # the RC at work (seed 001 Fig. 10 target: >= 5x)


def test_a_simulated_state_continues_through_files_and_back(tmp_path: Path) -> None:
    pos, vel, acc = _circle(4)
    rc = PluginRC(_pid(), CFG)
    first = simulate(_plant(), rc, pos[: 2 * N], derivatives=(vel[: 2 * N], acc[: 2 * N]))
    state = tmp_path / "state"
    rc.save_state(first.final_state.controller, state / STATE_FILE)
    sl = slice(2 * N, 3 * N)
    third = simulate(_plant(), rc, pos[sl], state=first.final_state, derivatives=(vel[sl], acc[sl]))
    _write_trial(tmp_path / "trial.h5", pos[sl], third.measured)
    r = _step(tmp_path / "trial.h5", state, tmp_path / "next.mat")
    assert r.exit_code == 0, r.output
    assert "period 3:" in r.output and (state / CONTOUR_FILE).is_file()
    # the file-based state is the simulated one; the hardware's inner loop is not known
    sim_mem = rc.memory_of(third.final_state.controller)
    mem = RCMemory.load(state / STATE_FILE)
    np.testing.assert_array_equal(mem.memory, sim_mem.memory)
    np.testing.assert_array_equal(mem.error, sim_mem.error)
    assert mem.samples == sim_mem.samples and mem.config == sim_mem.config
    assert mem.inner.size == 0 and sim_mem.inner.size == 6
    # ... the command file holds the correction the simulated RC applies next ...
    np.testing.assert_allclose(
        _command(tmp_path / "next.mat"), pos[sl] + sim_mem.next_correction(), rtol=0, atol=1e-15
    )
    # ... and the simulated RC takes it back: its own RC state, the inner PID at rest
    rc2 = PluginRC(_pid(), CFG)
    back = rc2.load_state(state / STATE_FILE)
    rc_part = 1 + 3 * N * 2  # counter, memory, last and current period's error
    np.testing.assert_array_equal(back[:rc_part], third.final_state.controller[:rc_part])
    np.testing.assert_array_equal(back[-sim_mem.inner.size :], _pid().init())
    # a fresh state made through files is read by the simulated RC as well
    trial = tmp_path / "first.csv"
    _write_trial(trial, pos[:N], first.measured[:N])
    r = _step(trial, tmp_path / "fresh", tmp_path / "n1.csv", *OPTS)
    assert r.exit_code == 0, r.output
    fresh = rc2.load_state(tmp_path / "fresh" / STATE_FILE)
    np.testing.assert_array_equal(fresh[1 : 1 + 2 * N], np.zeros(2 * N))  # c_1 = 0
    assert fresh[0] == N


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())} if d.exists() else {}


def _refused(tmp_path: Path, trial: Path, *extra: str, says: tuple[str, ...]) -> None:
    state, out = tmp_path / "state", tmp_path / "next.csv"
    before = _files(state)
    r = _step(trial, state, out, *extra)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error:"), r.output
    for s in says:
        assert s in lines[0], lines[0]
    assert not out.exists() and _files(state) == before  # nothing written


def test_refusals_are_one_line_and_write_nothing(tmp_path: Path) -> None:
    pos, _, _ = _circle(1)
    y = 0.9 * pos
    trial = tmp_path / "trial.csv"
    write_columns(trial, {"time": np.arange(N) * DT, "ref_x": pos[:, 0], "x": y[:, 0]})
    _refused(tmp_path, trial, says=("missing column(s) ref_y, y",))
    y_nan = y.copy()
    y_nan[17, 1] = np.nan
    _write_trial(trial, pos, y_nan)
    _refused(tmp_path, trial, says=("column 'y' holds nan at sample 17",))
    _write_trial(trial, pos, y)
    _refused(tmp_path, trial, "--period-s", "0.01005", says=("whole number",))
    _refused(tmp_path, trial, "--period-s", "0.02", says=("holds 100 samples", "200 samples"))
    # issue 32: an OverflowError traceback (1e308 s / dt samples)
    _refused(tmp_path, trial, "--period-s", "1e308", says=("outside the allowed range (0, 60] s",))
    # issue 32: learned from a 2-row period, or from a reference that does not move
    _write_trial(trial, pos[:2], y[:2])
    _refused(tmp_path, trial, says=("a period of 2 samples is too short",))
    _write_trial(trial, np.zeros_like(pos), np.zeros_like(y))
    _refused(tmp_path, trial, says=("the reference does not move",))
    _write_trial(trial, pos, y)
    _refused(
        tmp_path, trial, "--gain", "3", says=("'--gain': 3 is outside the allowed range (0, 2]",)
    )
    _refused(tmp_path, trial, "--tau-ms", "0", says=("'--tau-ms': 0 ms is outside",))
    _refused(tmp_path, trial, "--lead-samples", "-1", says=("'--lead-samples': -1 samples is",))
    _refused(tmp_path, trial, "--lead-samples", "100", says=("--lead-samples 100 is not below",))
    _refused(tmp_path, trial, "--colour", "red", says=("No such option: --colour",))
    r = _step(trial, tmp_path / "state", tmp_path / "next.txt")
    assert r.exit_code == 2 and "must be a file ending in .csv" in r.output
    assert not (tmp_path / "state").exists()
    # a good first step, then trials that do not fit the state
    r = _step(trial, tmp_path / "state", tmp_path / "first.csv", *OPTS)
    assert r.exit_code == 0, r.output
    _refused(tmp_path, trial, says=("learned from already",))
    y2 = 0.95 * pos
    _write_trial(trial, pos[:-1], y2[:-1])
    _refused(tmp_path, trial, says=("holds 99 samples, the RC state's period 100",))
    write_columns(
        trial,
        {
            "time": np.arange(N) * 2 * DT,
            "ref_x": pos[:, 0],
            "ref_y": pos[:, 1],
            "x": y2[:, 0],
            "y": y2[:, 1],
        },
    )
    _refused(tmp_path, trial, says=("sampled at 0.0002 s, the RC state at 0.0001 s",))
    _write_trial(trial, pos, y2)
    _refused(tmp_path, trial, "--gain", "0.5", says=("--gain has no effect on a later step",))
    _refused(tmp_path, trial, "--tau-ms", "2", says=("--tau-ms has no effect on a later step",))
    # the command of the last step written as the reference: refused, naming the fix
    cmd = _command(tmp_path / "first.csv")
    _write_trial(trial, cmd, y2)
    _refused(tmp_path, trial, says=("differs from the first trial's contour", "uncorrected"))
    (tmp_path / "state" / STATE_FILE).write_bytes(b"not an npz")
    _write_trial(trial, pos, y2)
    _refused(tmp_path, trial, says=("not a readable RC state",))


def test_mid_period_simulated_state_is_refused(tmp_path: Path) -> None:
    pos, vel, acc = _circle(2)
    rc = PluginRC(_pid(), CFG)
    cut = N + 17
    res = simulate(_plant(), rc, pos[:cut], derivatives=(vel[:cut], acc[:cut]))
    rc.save_state(res.final_state.controller, tmp_path / "state" / STATE_FILE)
    _write_trial(tmp_path / "trial.csv", pos[:N], 0.9 * pos[:N])
    _refused(tmp_path, tmp_path / "trial.csv", says=("saved mid-period (sample 117",))


@pytest.mark.parametrize("windows", [((50, 2),), None])
def test_boundary_rule_follows_the_windows(tmp_path: Path, windows: tuple | None) -> None:
    cfg = RCConfig(period_s=N * DT, dt=DT, windows=windows)
    mem = RCMemory.initial(cfg, 2)
    samples = 150 if windows else 200  # one period into the window / two periods
    RCMemory(
        config=cfg,
        memory=mem.memory,
        error=mem.error + 1e-6,
        error_current=mem.error,
        samples=samples,
        inner=(),
    ).save(tmp_path / "state" / STATE_FILE)
    pos, _, _ = _circle(1)
    _write_trial(tmp_path / "trial.csv", pos, 0.9 * pos)
    r = _step(tmp_path / "trial.csv", tmp_path / "state", tmp_path / "next.csv")
    assert r.exit_code == 0, r.output
    assert RCMemory.load(tmp_path / "state" / STATE_FILE).samples == samples + N


def test_the_commands_are_listed() -> None:
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0
    rows = {ln.split()[0] for ln in res.output.splitlines() if ln.startswith("  ") and ln.split()}
    assert {"rc", "nanomanipulator"} <= rows, res.output
    res = runner.invoke(app, ["rc", "step", "--help"])
    assert res.exit_code == 0 and "--tau-ms" in res.output and "╭" not in res.output
