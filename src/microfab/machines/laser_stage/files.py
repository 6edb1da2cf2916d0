"""The seed 004 stage on hardware, through files: export for a real-time target, replay a trace.

``microfab laser export`` and ``microfab laser analyze --replay``. `export_job` writes what
a real-time target (the seed's dSPACE, or any controller board) needs to run a contour job
(`microfab.machines.laser_stage.ContourJob`, e.g. a ``laser-micromachining`` job's run),
each file atomically:

``reference.csv``
    ``time`` (s) and per sample the reference position, velocity and acceleration of
    both axes (``ref_x, ref_y`` m, ``ref_vx, ref_vy`` m/s, ``ref_ax, ref_ay`` m/s²): the
    time-based spline of the drawing, already checked against the stage's limits.
``controller.json``
    The sample time, the law and its gains, the nominal model, and per axis the discrete
    preview + DOB controller as a state-space model ``[x_ref, ẋ_ref, ẍ_ref, x_fb] -> i``
    (`PreviewDOB.linear_model`; a target runs ``x ← A x + B w``, ``i = C x + D w``); the
    contour compensator's or cross-coupled controller's gains where the law has one
    (their law is in `microfab.control.contour` / `microfab.control.cross_coupled`).

`replay_trace` runs our controller over a measured trace (the encoder it recorded) and
compares the current it would have sent with the recorded ``current_x, current_y``: the
check that the target runs the controller simulated here. The trace's reference
derivatives (``ref_vx`` ... ``ref_ay``, as exported) are used when present, else central
differences of the reference positions (then expect differences of the order of the
difference error).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from microfab.core.signals import Trace
from microfab.io.atomic import atomic_write_json
from microfab.io.trace import write_trace
from microfab.machines.laser_stage.machine import (
    ContourJob,
    ControlSettings,
    TwinSettings,
    controller,
    twin,
)
from microfab.sim.replay import replay_controller
from microfab.trajectory.contour_laps import contour_path, contour_reference

__all__ = ["EXPORT_FORMAT", "Replay", "export_job", "replay_trace"]

#: Version of ``controller.json``.
EXPORT_FORMAT = 1
_DERIVS = ("ref_vx", "ref_vy", "ref_ax", "ref_ay")


def _axis_model(ctrl: Any, axis: int) -> dict[str, Any]:
    inner = getattr(ctrl, "inner", ctrl)
    m = inner.linear_model(axis)
    return {
        "inputs": ["x_ref", "xdot_ref", "xddot_ref", "x_fb"],
        "output": "i_ref",
        "A": m.A.tolist(),
        "B": m.B.tolist(),
        "C": m.C.tolist(),
        "D": m.D.tolist(),
    }


class HoldsRun(Protocol):
    """A job config that holds its contour run (the ``laser-micromachining`` job's)."""

    @property
    def run(self) -> ContourJob: ...


def export_job(job: ContourJob | HoldsRun, out: str | Path) -> tuple[Path, Path]:
    """Write ``reference.csv`` and ``controller.json`` of a job into ``out`` (module notes).

    Parameters
    ----------
    job : ContourJob or a config holding one as ``run``
        The contour run, expected checked (`microfab.experiments.catalog.load_job` refuses
        a reference beyond the stage's limits before this runs).
    out : path-like
        The folder.

    Returns
    -------
    tuple of pathlib.Path
        The two files.
    """
    run = job if isinstance(job, ContourJob) else job.run
    out = Path(out)
    path = contour_path(run.drawing, run.contour)
    ref = contour_reference(path, run.motion)
    tr = ref.trajectory
    pos, vel, acc = (np.asarray(a) for a in (tr.position, tr.velocity, tr.acceleration))
    cols = {"ref_x": pos[:, 0], "ref_y": pos[:, 1], "ref_vx": vel[:, 0], "ref_vy": vel[:, 1],
            "ref_ax": acc[:, 0], "ref_ay": acc[:, 1]}  # fmt: skip
    trace = Trace(dt=ref.dt, values=np.column_stack(list(cols.values())), axes=tuple(cols),
                  unit="m")  # fmt: skip
    stage = twin(run.twin)
    ctrl = controller(run.control, stage)
    nom = stage.nominal()
    cfg = getattr(ctrl, "config", None)
    add_on: dict[str, Any] = {}
    if run.control.law == "contour":
        add_on = {"k_pc": cfg.k_pc, "k_vc": cfg.k_vc, "min_speed_m_s": cfg.min_speed_m_s,
                  "fade_in_s": cfg.fade_in_s}  # fmt: skip
    elif run.control.law == "cross-coupled":
        add_on = {"k_p": cfg.k_p, "k_d": cfg.k_d, "min_speed_m_s": cfg.min_speed_m_s}
    spec = {
        "format": EXPORT_FORMAT,
        "kind": "laser-micromachining",
        "dt_s": stage.dt,
        "law": run.control.law,
        "settings": {
            "bandwidth_hz": run.control.bandwidth_hz,
            "dob_bandwidth_hz": run.control.dob_bandwidth_hz,
            "k_a": run.control.k_a,
            "contour_bandwidth_hz": run.control.contour_bandwidth_hz,
        },
        "nominal": {
            "mass_kg": list(nom.mass_kg),
            "force_constant_n_per_a": list(nom.force_constant_n_per_a),
        },
        "axes": {name: _axis_model(ctrl, a) for a, name in enumerate("xy")},
        "add_on": add_on,
        "reference": {"file": "reference.csv", "samples": int(pos.shape[0])},
    }
    ref_file, spec_file = out / "reference.csv", out / "controller.json"
    write_trace(trace, ref_file)
    atomic_write_json(spec_file, spec)
    return ref_file, spec_file


@dataclass(frozen=True, kw_only=True, eq=False)
class Replay:
    """Our controller's current on a measured trace against the recorded one.

    Attributes
    ----------
    command : numpy.ndarray
        The current our controller sends for the recorded encoder, A, shape (n, 2).
    recorded : numpy.ndarray
        The recorded current, A, shape (n, 2).
    rms_difference_a, max_difference_a : tuple of float
        Per axis, A.
    exact_derivatives : bool
        Whether the trace carried the reference derivatives (else central differences).
    """

    command: np.ndarray
    recorded: np.ndarray
    rms_difference_a: tuple[float, float]
    max_difference_a: tuple[float, float]
    exact_derivatives: bool


def replay_trace(
    trace: Trace,
    control: ControlSettings | None = None,
    settings: TwinSettings | None = None,
) -> Replay:
    """Run our controller over a trace's encoder and compare currents (module notes).

    Parameters
    ----------
    trace : Trace
        The measured run: ``ref_x, ref_y, x, y`` (m), ``current_x, current_y`` (A) and
        optionally ``ref_vx, ref_vy`` (m/s), ``ref_ax, ref_ay`` (m/s²), shape (n, columns).
    control : ControlSettings, optional
        The controller the target ran (default `ControlSettings`).
    settings : TwinSettings, optional
        The twin whose nominal model the controller was given (default `TwinSettings`).

    Raises
    ------
    ValueError
        When the trace lacks ``ref_x, ref_y, x, y`` or the recorded currents.
    """
    need = ("ref_x", "ref_y", "x", "y", "current_x", "current_y")
    missing = [c for c in need if c not in trace.axes]
    if missing:
        raise ValueError(
            f"replay needs the columns {', '.join(need)}; missing {', '.join(missing)}"
        )
    col = {n: k for k, n in enumerate(trace.axes)}
    v = np.asarray(trace.values)

    def two(a: str, b: str) -> np.ndarray:
        return np.ascontiguousarray(v[:, [col[a], col[b]]])

    pos, meas, rec = two("ref_x", "ref_y"), two("x", "y"), two("current_x", "current_y")
    exact = all(c in col for c in _DERIVS)
    if exact:
        vel, acc = two("ref_vx", "ref_vy"), two("ref_ax", "ref_ay")
    else:
        vel = np.gradient(pos, trace.dt, axis=0)
        acc = np.gradient(vel, trace.dt, axis=0)
    stage = twin(settings or TwinSettings())
    if abs(stage.dt - trace.dt) > 1e-9 * stage.dt:
        raise ValueError(
            f"the trace's sample time {trace.dt:g} s differs from the controller's "
            f"{stage.dt:g} s; record at the controller's rate"
        )
    ctrl = controller(control or ControlSettings(), stage)
    u, _ = replay_controller(ctrl, pos, meas, (vel, acc))
    d = u - rec
    return Replay(
        command=u,
        recorded=rec,
        rms_difference_a=tuple(float(x) for x in np.sqrt(np.mean(d**2, axis=0))),  # type: ignore[arg-type]
        max_difference_a=tuple(float(x) for x in np.max(np.abs(d), axis=0)),  # type: ignore[arg-type]
        exact_derivatives=exact,
    )
