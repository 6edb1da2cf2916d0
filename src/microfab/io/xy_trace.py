"""Measured XY traces of a contour job through files: read, checked, compared.

Columns of a measured file (CSV, MAT or HDF5, `microfab.io.trace.read_columns`; other
columns are ignored):

``time``
    Sample time, s, uniformly spaced (one sample rate for the whole file).
``ref_x``, ``ref_y``
    The contour reference, mm: the pattern the job asked for, **without** the RC's
    correction (the RC learns from ``e = r − y`` against it, seed 001 Fig. 6).
``x``, ``y``
    Measured stage position, mm.
``laser``
    Laser command, 0 (off) or 1 (on): traces of a whole job only.

`read_measured` reads and checks such a file: the plug-in RC step on hardware
(`microfab.machines.nanomanipulator.files.rc_file_step`, ``microfab rc step``) reads one
period, ``microfab nanomanipulator analyze`` (`microfab.measure.circle_trace`) a whole job.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.core.signals import check_time_base
from microfab.io.trace import read_columns

__all__ = [
    "LASER",
    "REF_TOL_MM",
    "TRACE_COLUMNS",
    "MeasuredTrace",
    "largest_deviation",
    "read_measured",
]

#: Columns of a trial period (`rc_file_step`); a whole job's trace adds `LASER`.
TRACE_COLUMNS = ("time", "ref_x", "ref_y", "x", "y")
LASER = "laser"
#: Largest reference deviation taken as the same reference, mm (assumed 1 nm: 1/1000 of
#: the 1 µm gate threshold, above the ~0.1 nm rounding of a ≤ 1.5 mm position in float32).
REF_TOL_MM = 1e-6
#: Relative tolerance on sample-time steps (as `microfab.core.signals.check_time_base`).
_DT_RTOL = 1e-6


@dataclass(frozen=True, kw_only=True, eq=False)
class MeasuredTrace:
    """A checked measured file.

    Attributes
    ----------
    path : Path
        Where it was read.
    time : numpy.ndarray
        Sample times, s, shape (n,).
    dt : float
        Sample time, s.
    reference, output : numpy.ndarray
        ``(ref_x, ref_y)`` and ``(x, y)``, mm, shape (n, 2).
    laser : numpy.ndarray or None
        Laser on, bool, shape (n,), when read with ``laser=True``.
    """

    path: Path
    time: np.ndarray
    dt: float
    reference: np.ndarray
    output: np.ndarray
    laser: np.ndarray | None

    @property
    def n_samples(self) -> int:
        """Samples in the file."""
        return int(self.time.size)


def read_measured(path: str | Path, *, laser: bool = False) -> MeasuredTrace:
    """Read a measured file (columns: module docstring) and check it.

    Parameters
    ----------
    path : str or Path
        CSV, MAT or HDF5 file.
    laser : bool
        Also require the ``laser`` column (0 or 1 per sample).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Unreadable; missing columns (named); no or one sample; NaN or inf (naming column,
        sample and time); a sample rate that changes within the file (naming where); a
        laser value other than 0 and 1.
    """
    p = Path(path)
    cols = read_columns(p)
    need = (*TRACE_COLUMNS, LASER) if laser else TRACE_COLUMNS
    missing = [c for c in need if c not in cols]
    if missing:
        raise ValueError(
            f"{p}: missing column(s) {', '.join(missing)} (found: "
            f"{', '.join(cols) or 'none'}); a trace holds {', '.join(need)}"
        )
    t = cols["time"]
    if t.size == 0:
        raise ValueError(f"{p}: the file holds no samples (only its header)")
    if t.size < 2:
        raise ValueError(f"{p}: one sample gives no sample rate; record at least two")
    for name in need:
        bad = np.flatnonzero(~np.isfinite(cols[name]))
        if bad.size:
            k = int(bad[0])
            at = f" (t = {t[k]:g} s)" if np.isfinite(t[k]) else ""
            raise ValueError(
                f"{p}: column {name!r} holds {cols[name][k]} at sample {k}{at}; "
                "every value must be finite"
            )
    steps = np.diff(t)
    dt0 = float(steps[0])
    if dt0 <= 0:
        raise ValueError(f"{p}: time must increase, got {t[0]:g} s then {t[1]:g} s")
    off = np.flatnonzero(np.abs(steps - dt0) > _DT_RTOL * dt0)
    if off.size:
        k = int(off[0])
        raise ValueError(
            f"{p}: the sample rate changes at sample {k + 1} (t = {t[k + 1]:g} s): step "
            f"{steps[k]:.9g} s after {dt0:.9g} s; record at one rate"
        )
    try:
        _, dt = check_time_base(t)  # also refuses a slow drift the step check lets through
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}; record at one rate") from exc
    on = None
    if laser:
        v = cols[LASER]
        wrong = np.flatnonzero((v != 0.0) & (v != 1.0))
        if wrong.size:
            k = int(wrong[0])
            raise ValueError(
                f"{p}: column 'laser' holds {v[k]:g} at sample {k}; write 0 (off) or 1 (on)"
            )
        on = v == 1.0
    return MeasuredTrace(
        path=p,
        time=t,
        dt=dt,
        reference=np.column_stack([cols["ref_x"], cols["ref_y"]]),
        output=np.column_stack([cols["x"], cols["y"]]),
        laser=on,
    )


def largest_deviation(a: np.ndarray, b: np.ndarray) -> tuple[float, int, int]:
    """``(|a − b| max, sample, axis)`` of two (n, 2) arrays."""
    d = np.abs(np.asarray(a) - np.asarray(b))
    k, j = np.unravel_index(int(np.argmax(d)), d.shape)
    return float(d[k, j]), int(k), int(j)
