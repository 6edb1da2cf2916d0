"""Seed 004 through files: export for a target, replay of a trace, controller replay."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.core.signals import Trace
from microfab.experiments.catalog import load_job
from microfab.io.trace import read_trace, write_trace
from microfab.machines.laser_stage.contour import run_contour
from microfab.machines.laser_stage.files import export_job, replay_trace
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings
from microfab.machines.laser_stage.machine import controller as make_controller
from microfab.machines.laser_stage.machine import twin as make_stage
from microfab.sim.replay import replay_controller
from microfab.trajectory.contour_laps import ContourMotion


@pytest.fixture(scope="module")
def contour_run():
    return run_contour(ContourJob(motion=ContourMotion(laps=2)))


def _trace(run, derivatives: bool) -> Trace:
    tr = run.reference.trajectory
    pos, vel, acc = (np.asarray(a) for a in (tr.position, tr.velocity, tr.acceleration))
    cols = {"ref_x": pos[:, 0], "ref_y": pos[:, 1], "x": run.measured[:, 0],
            "y": run.measured[:, 1], "current_x": run.command[:, 0],
            "current_y": run.command[:, 1]}  # fmt: skip
    if derivatives:
        cols |= {"ref_vx": vel[:, 0], "ref_vy": vel[:, 1], "ref_ax": acc[:, 0],
                 "ref_ay": acc[:, 1]}  # fmt: skip
    return Trace(dt=run.dt, values=np.column_stack(list(cols.values())), axes=tuple(cols))


def test_replay_controller_reproduces_the_closed_loop_commands(contour_run):
    stage = make_stage(contour_run.job.twin)
    ctrl = make_controller(contour_run.job.control, stage)
    tr = contour_run.reference.trajectory
    u, _ = replay_controller(ctrl, tr.position, contour_run.measured,
                             (tr.velocity, tr.acceleration))  # fmt: skip
    np.testing.assert_array_equal(u, contour_run.command)


def test_replay_of_a_trace_matches_the_recorded_current(tmp_path, contour_run):
    path = tmp_path / "t.h5"
    write_trace(_trace(contour_run, derivatives=True), path)
    r = replay_trace(read_trace(path))
    assert r.exact_derivatives
    assert max(r.max_difference_a) == 0.0
    # without the derivatives the central differences leave a small difference
    rd = replay_trace(_trace(contour_run, derivatives=False))
    assert not rd.exact_derivatives and 0.0 < max(rd.rms_difference_a) < 1e-2
    # another controller does not match
    other = replay_trace(_trace(contour_run, True), ControlSettings(law="pd"))
    assert max(other.rms_difference_a) > 100 * max(rd.rms_difference_a)


def test_replay_needs_the_currents(contour_run):
    t = _trace(contour_run, True)
    keep = [i for i, a in enumerate(t.axes) if not a.startswith("current")]
    with pytest.raises(ValueError, match="missing current_x, current_y"):
        replay_trace(Trace(dt=t.dt, values=t.values[:, keep], axes=tuple(t.axes[i] for i in keep)))


def test_export_writes_the_reference_and_the_discrete_controller(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('[job]\nkind = "laser-micromachining"\n[trajectory]\nlaps = 1\n',
                   encoding="utf-8")  # fmt: skip
    out = tmp_path / "target"
    res = CliRunner().invoke(app, ["laser", "export", str(job), "--out", str(out)])
    assert res.exit_code == 0, res.output
    ref = read_trace(out / "reference.csv")
    assert ref.axes == ("ref_x", "ref_y", "ref_vx", "ref_vy", "ref_ax", "ref_ay")
    spec = json.loads((out / "controller.json").read_text(encoding="utf-8"))
    assert spec["format"] == 1 and spec["law"] == "contour" and spec["dt_s"] == 1e-4
    assert spec["add_on"]["k_pc"] > 0 and spec["reference"]["samples"] == ref.values.shape[0]
    # the exported x-axis model reproduces the kernel's current on a random input
    a = spec["axes"]["x"]
    A, B, C, D = (np.array(a[k]) for k in "ABCD")
    cfg = load_job(job).config
    ctrl = make_controller(cfg.run.control, make_stage(cfg.run.twin)).inner
    m = ctrl.linear_model(0)
    np.testing.assert_array_equal(A, m.A)
    np.testing.assert_array_equal(D, m.D)
    assert B.shape == (A.shape[0], 4) and C.shape == (1, A.shape[0])
    # export of another kind is refused
    other = tmp_path / "other.toml"
    other.write_text('[job]\nkind = "msl-ilc"\n', encoding="utf-8")
    bad = CliRunner().invoke(app, ["laser", "export", str(other), "--out", str(tmp_path / "o")])
    assert bad.exit_code == 2 and "not a laser-micromachining job" in bad.output


def test_cli_analyze_replay(tmp_path, contour_run):
    path = tmp_path / "t.csv"
    write_trace(_trace(contour_run, derivatives=True), path)
    js = tmp_path / "a.json"
    args = ["laser", "analyze", str(path), "--drawing", "circle:radius=30e-6", "--replay"]
    res = CliRunner().invoke(app, [*args, "--json", str(js)])
    assert res.exit_code == 0, res.output
    assert "replay (exported derivatives)" in res.output
    assert json.loads(js.read_text(encoding="utf-8"))["replay"]["max_difference_a"] == [0.0, 0.0]


def test_export_of_the_example_job(tmp_path):
    example = Path(__file__).parents[3] / "examples" / "laser_micromachining.toml"
    ref, spec = export_job(load_job(example).config, tmp_path)
    assert read_trace(ref).values.shape[0] == json.loads(spec.read_text())["reference"]["samples"]
