"""Measured traces: a twin run written as a trace gives the run's own numbers; bad traces."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from microfab.cli import app
from microfab.core.signals import Trace
from microfab.io.trace import write_trace
from microfab.machines.laser_stage.contour import run_contour
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings
from microfab.measure.contour_trace import analyze_file, analyze_trace
from microfab.trajectory.contour_laps import ContourMotion, contour_path


@pytest.fixture(scope="module")
def twin_run():
    return run_contour(ContourJob(motion=ContourMotion(laps=3),
                                  control=ControlSettings(law="preview-dob")))  # fmt: skip


def _trace(run, **extra) -> Trace:
    ref = np.asarray(run.reference.trajectory.position)
    cols = {"ref_x": ref[:, 0], "ref_y": ref[:, 1], "x": run.measured[:, 0],
            "y": run.measured[:, 1], **extra}  # fmt: skip
    return Trace(dt=run.dt, values=np.column_stack(list(cols.values())), axes=tuple(cols))


def test_a_twin_run_analysed_as_a_trace_gives_its_numbers(tmp_path, twin_run):
    path = tmp_path / "run.csv"
    write_trace(_trace(twin_run, current_x=twin_run.command[:, 0],
                       current_y=twin_run.command[:, 1]), path)  # fmt: skip
    a = analyze_file(path, "circle:radius=30e-6")
    # the laps are found along the reference: the three full-speed laps plus the ramps
    assert len(a.laps) >= 3
    assert a.reference_deviation_m < 1e-9
    assert a.current is not None
    # the whole-trace contour error equals the twin's measured contour error
    np.testing.assert_allclose(a.contour.error_m, twin_run.contour_measured.error_m,
                               rtol=0, atol=1e-12)  # fmt: skip
    ref = twin_run.reference
    full = slice(int(ref.lap_starts[0]), int(ref.lap_starts[-1]) + ref.lap_samples)
    e = np.abs(np.asarray(twin_run.reference.trajectory.position) - twin_run.measured)
    assert max(a.axis.peak_m) >= max(np.max(e[full], axis=0)) - 1e-15


def test_missing_columns_and_a_foreign_reference_are_refused(twin_run):
    path = contour_path("circle:radius=30e-6")
    t = _trace(twin_run)
    bad = Trace(dt=t.dt, values=t.values[:, :3], axes=t.axes[:3])
    with pytest.raises(ValueError, match="lacks the column"):
        analyze_trace(bad, path)
    with pytest.raises(ValueError, match=r"does not follow the drawing: it is 10 µm"):
        analyze_trace(t, contour_path("circle:radius=40e-6"))


def test_cli_writes_the_report_and_json(tmp_path, twin_run):
    trace = tmp_path / "run.csv"
    write_trace(_trace(twin_run), trace)
    out, js = tmp_path / "report", tmp_path / "a.json"
    args = ["laser", "analyze", str(trace), "--drawing", "circle:radius=30e-6"]
    res = CliRunner().invoke(app, [*args, "--out", str(out), "--json", str(js)])
    assert res.exit_code == 0, res.output
    assert (out / "report.html").exists() and (out / "ballbar.png").exists() and js.exists()
    bad = CliRunner().invoke(app, ["laser", "analyze", str(trace), "--drawing",
                                   "circle:radius=40e-6"])  # fmt: skip
    assert bad.exit_code == 2 and "error:" in bad.output
