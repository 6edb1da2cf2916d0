"""Figures of merit of a measured contouring trace against its drawing (``microfab laser analyze``).

A trace is a file (``.csv``, ``.mat``, ``.h5``: `microfab.io.trace.read_trace`) with the
columns ``time`` (s), ``ref_x``, ``ref_y`` (the reference the controller was given, m)
and ``x``, ``y`` (the encoder, m), and optionally ``current_x``, ``current_y`` (A) — any
other column is kept aside. The drawing the reference came from is given separately
(`microfab.geometry.load.load_drawing`), and the analysis compares against the *exact*
contour:

* the reference must follow the drawing: its largest distance to the contour may not
  exceed ``reference_tol_m`` (default 1 µm: a time-based spline through the drawing's
  points keeps to a few picometres on smooth contours; a corner rounded by the planner
  may need more, and the message says how far it strays and where);
* axis errors ``ref − encoder`` (Fig. 3) over the whole trace;
* contour error of the encoder against the contour (foot point, signed), per lap, the laps
  counted along the reference's arc length on the contour (a partial last lap is not
  counted; a trace under one lap is one lap).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import Any

import numpy as np

from microfab.core.signals import Trace
from microfab.core.validate import check_positive
from microfab.geometry.path import Path
from microfab.geometry.project import project_points
from microfab.measure.contour import (
    AxisErrors,
    ContourErrors,
    axis_errors,
    contour_errors,
    laps_along,
)

__all__ = [
    "REF_TOL_M",
    "REQUIRED",
    "TraceAnalysis",
    "analyze_file",
    "analyze_trace",
]

#: Columns a trace must hold besides ``time`` (m).
REQUIRED = ("ref_x", "ref_y", "x", "y")
#: Largest distance of the reference to the drawing, m (assumed default, module notes).
REF_TOL_M = 1e-6


@dataclass(frozen=True, kw_only=True, eq=False)
class TraceAnalysis:
    """The figures of merit of a measured trace.

    Attributes
    ----------
    path : Path
        The exact contour, m.
    time : numpy.ndarray
        Sample times, s, shape (n,).
    reference, measured : numpy.ndarray
        Reference and encoder positions, m, shape (n, 2).
    current : numpy.ndarray or None
        Currents, A, shape (n, 2), when the trace has them.
    reference_deviation_m : float
        Largest distance of the reference to the contour, m.
    laps : tuple of slice
        Samples of each full lap.
    axis : AxisErrors
        Axis errors over the trace.
    contour : ContourErrors
        Contour error of the encoder per lap.
    """

    path: Path
    time: np.ndarray
    reference: np.ndarray
    measured: np.ndarray
    current: np.ndarray | None
    reference_deviation_m: float
    laps: tuple[slice, ...]
    axis: AxisErrors
    contour: ContourErrors

    def summary(self) -> dict[str, Any]:
        """The numbers, JSON-ready."""
        return {
            "samples": int(self.time.size),
            "dt_s": float(self.time[1] - self.time[0]) if self.time.size > 1 else None,
            "laps": len(self.laps),
            "reference_deviation_nm": self.reference_deviation_m * 1e9,
            "axis_fraction_below_0p5um": list(self.axis.fraction_below),
            "axis_peak_um": [v * 1e6 for v in self.axis.peak_m],
            "axis_rms_um": [v * 1e6 for v in self.axis.rms_m],
            "contour_lap_max_nm": (self.contour.lap_max_m * 1e9).tolist(),
            "contour_lap_rms_nm": (self.contour.lap_rms_m * 1e9).tolist(),
        }


def analyze_trace(trace: Trace, path: Path, *, reference_tol_m: float = REF_TOL_M) -> TraceAnalysis:
    """Analyse a measured trace against the exact contour (module notes).

    Raises
    ------
    ValueError
        On a missing column, or a reference that strays from the drawing by more than
        ``reference_tol_m`` (naming how far, where and when).
    """
    check_positive("reference_tol_m", reference_tol_m, "m")
    missing = [c for c in REQUIRED if c not in trace.axes]
    if missing:
        raise ValueError(
            f"the trace lacks the column(s) {', '.join(missing)}; it needs time, "
            f"{', '.join(REQUIRED)} (m) and optionally current_x, current_y (A); it has "
            f"{', '.join(trace.axes)}"
        )
    col = {name: k for k, name in enumerate(trace.axes)}
    v = np.asarray(trace.values, dtype=float)
    ref = v[:, [col["ref_x"], col["ref_y"]]]
    meas = v[:, [col["x"], col["y"]]]
    cur = None
    if "current_x" in col and "current_y" in col:
        cur = v[:, [col["current_x"], col["current_y"]]]
    time = trace.t0 + np.arange(v.shape[0]) * trace.dt
    dev = np.abs(np.asarray(project_points(path, ref).distance))
    i = int(np.argmax(dev))
    if dev[i] > reference_tol_m:
        raise ValueError(
            f"the reference does not follow the drawing: it is {dev[i] * 1e6:.3g} µm from "
            f"the contour at t = {time[i]:.6g} s (ref = ({ref[i, 0]:.6g}, {ref[i, 1]:.6g}) "
            f"m), more than {reference_tol_m * 1e6:g} µm; check the drawing, its units and "
            "its placement, or raise the tolerance"
        )
    laps = laps_along(path, ref)
    return TraceAnalysis(
        path=path,
        time=time,
        reference=ref,
        measured=meas,
        current=cur,
        reference_deviation_m=float(dev[i]),
        laps=laps,
        axis=axis_errors(ref, meas),
        contour=contour_errors(path, meas, laps),
    )


def analyze_file(
    trace_file: str | FilePath,
    drawing: str,
    contour: int = 0,
    *,
    reference_tol_m: float = REF_TOL_M,
) -> TraceAnalysis:
    """`analyze_trace` of a trace file against contour ``contour`` of a drawing source."""
    from microfab.io.trace import read_trace
    from microfab.trajectory.contour_laps import contour_path

    path = contour_path(drawing, contour)
    return analyze_trace(read_trace(trace_file), path, reference_tol_m=reference_tol_m)
