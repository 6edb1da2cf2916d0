"""The seed 001 nanomanipulator on hardware through files: the plug-in RC step.

`rc_file_step` (``microfab rc step``) is one period of the plug-in RC (seed 001 §3.3,
Fig. 6) on hardware: one measured period in (a trace of `microfab.io.xy_trace`, columns
``time, ref_x, ref_y, x, y``), the next command (``r + c``) out, the
`microfab.control.rc_memory.RCMemory` kept in a state directory in the same format as the
simulated RC's (`microfab.control.repetitive.PluginRC.save_state`). Every check runs
before anything is written; the contour (first call only), the command file and the
state are then written in that order, each atomically, so a refused or interrupted step
leaves the state as it was. A step holds the state's lock (`microfab.io.lock`) from reading
the state to saving it: a second step on the same state meanwhile is refused.
"""

from __future__ import annotations

import dataclasses
import math
import os
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microfab.control.rc_memory import RCMemory
from microfab.control.repetitive import RCConfig, period_samples
from microfab.io.atomic import atomic_save_npz
from microfab.io.lock import folder_lock
from microfab.io.schema import SchemaError, check_array, check_npz, describe_file
from microfab.io.trace import write_columns
from microfab.io.xy_trace import REF_TOL_MM, largest_deviation, read_measured

__all__ = ["CONTOUR_FILE", "STATE_FILE", "RCStepReport", "rc_file_step", "read_contour"]

#: RC state file in the state directory (`RCMemory.save`, as `PluginRC.save_state`).
STATE_FILE = "rc_state.npz"
#: The contour reference of the first trial, kept to check later trials' ``ref_x, ref_y``.
CONTOUR_FILE = "contour.npz"


@dataclass(frozen=True, kw_only=True)
class RCStepReport:
    """What one `rc_file_step` did.

    Attributes
    ----------
    period : int
        The state's sample counter in periods (1 after the first call of a new state).
    rms_nm : tuple of float
        RMS error ``r − y`` of the trial per axis (x, y), nm.
    correction_rms_nm : tuple of float
        RMS of the next correction per axis, nm.
    out_path : Path
        The command file written.
    created : bool
        Whether this call created the state.
    """

    period: int
    rms_nm: tuple[float, float]
    correction_rms_nm: tuple[float, float]
    out_path: Path
    created: bool


_OUT_SUFFIXES = (".csv", ".mat", ".h5", ".hdf5")


#: Fewest samples a measured period may hold: as the learning loop's trials (a period
#: below it holds no harmonic to learn; assumed, as `microfab.machines.files`' 8).
MIN_PERIOD_SAMPLES = 8


def _same(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)


def _load_state(sd: Path) -> RCMemory | None:
    return RCMemory.load(sd / STATE_FILE) if (sd / STATE_FILE).is_file() else None


def _at_boundary(cfg: RCConfig, samples: int) -> bool:
    """Whether a state's sample counter sits at a period boundary of its RC."""
    n = cfg.period_samples
    if cfg.windows is None:
        return samples % n == 0
    for s, k in cfg.windows:
        if s < samples < s + k * n:
            return (samples - s) % n == 0
    return True  # outside every window (or at its end): nothing half-learned


def _check_options(
    mem: RCMemory, tau_s: float | None, gain: float | None, lead_samples: int | None
) -> None:
    cfg = mem.config
    for opt, given, kept in (
        ("--tau-ms", None if tau_s is None else tau_s * 1e3, cfg.tau_s * 1e3),
        ("--gain", gain, cfg.gain),
        ("--lead-samples", lead_samples, cfg.lead_samples),
    ):
        if given is not None and not _same(float(given), float(kept)):
            raise ValueError(
                f"{opt} {given:g} differs from the state's {kept:g}: the RC settings are "
                "fixed on the first call (leave the option out, or start a new state "
                "directory)"
            )


def rc_file_step(
    trial: str | Path,
    state_dir: str | Path,
    out: str | Path,
    *,
    tau_s: float | None = None,
    gain: float | None = None,
    lead_samples: int | None = None,
    period_s: float | None = None,
) -> RCStepReport:
    """One plug-in RC period on hardware: measured period in, next command out.

    The first call (no state) creates an `RCConfig` whose period is the trial's length
    times its sample time (``period_s`` if given, which must then be a whole number of
    samples and equal the trial's length) and whose ``tau_s``, ``gain`` and
    ``lead_samples`` are given or `RCConfig`'s defaults; that first trial must have run
    on the plain contour (no correction). Every call then takes
    ``c_{j+1} = rc_update(c_j, e_j)`` with ``e_j = r − y`` of the trial and writes
    ``command = r + c_{j+1}`` (seed 001 Fig. 6: the RC output added to the reference).

    Parameters
    ----------
    trial : str or Path
        One measured period (`microfab.io.xy_trace.TRACE_COLUMNS`).
    state_dir : str or Path
        State directory: `STATE_FILE` (an `RCMemory`, also one saved by
        `PluginRC.save_state` of a simulated run) and `CONTOUR_FILE`.
    out : str or Path
        Command file (``.csv``, ``.mat``, ``.h5``): ``time, command_x, command_y``
        (mm) and ``correction_x, correction_y`` (mm).
    tau_s, gain, lead_samples : optional
        RC settings for a new state; on later calls, if given, they must equal the
        state's.
    period_s : float, optional
        The contour period, s, to check the trial against.

    Returns
    -------
    RCStepReport

    Raises
    ------
    ValueError
        On a bad trial (`read_measured`), a period that is not a whole number of samples
        or not the trial's length, a trial whose length or sample time differs from the
        state's, a reference that is not the state's contour, a trial learned from
        already, settings that differ from the state's, or an unreadable state.
    microfab.io.lock.FolderLockedError
        Another process is writing the state (nothing is read or written; also a
        `ValueError`).
    """
    with folder_lock(state_dir, what="RC state"):
        return _rc_file_step(
            trial,
            state_dir,
            out,
            tau_s=tau_s,
            gain=gain,
            lead_samples=lead_samples,
            period_s=period_s,
        )


def _rc_file_step(
    trial: str | Path,
    state_dir: str | Path,
    out: str | Path,
    *,
    tau_s: float | None,
    gain: float | None,
    lead_samples: int | None,
    period_s: float | None,
) -> RCStepReport:
    """`rc_file_step` once the state's lock is held."""
    o = Path(out)
    if o.suffix.lower() not in _OUT_SUFFIXES or o.is_dir():
        raise ValueError(
            f"--out {o} must be a file ending in {', '.join(_OUT_SUFFIXES)} (the format)"
        )
    tr = read_measured(trial)
    n, dt = tr.n_samples, tr.dt
    if n < MIN_PERIOD_SAMPLES:
        raise ValueError(
            f"{tr.path}: a period of {n} samples is too short to learn from; record one "
            f"whole period of at least {MIN_PERIOD_SAMPLES} samples"
        )
    if not np.ptp(tr.reference, axis=0).max() > 0.0:
        raise ValueError(
            f"{tr.path}: the reference does not move (every ref_x, ref_y sample is the same): "
            "there is no contour to learn; record a period of the contour"
        )
    if period_s is not None:
        n_p = period_samples(period_s, dt)
        if n_p != n:
            raise ValueError(
                f"{tr.path}: the trial holds {n} samples, the period {period_s:g} s is {n_p} "
                f"samples at {dt:g} s; give exactly one period"
            )
    sd = Path(state_dir)
    if sd.exists() and not sd.is_dir():
        raise ValueError(f"--state {sd} is a file; give a directory")
    mem = _load_state(sd)
    created = mem is None
    if mem is None:
        kw: dict[str, float | int] = {}
        if tau_s is not None:
            kw["tau_s"] = tau_s
        if gain is not None:
            kw["gain"] = gain
        if lead_samples is not None:
            kw["lead_samples"] = lead_samples
        mem = RCMemory.initial(RCConfig(period_s=n * dt, dt=dt, **kw), 2)  # type: ignore[arg-type]
    else:
        cfg = mem.config
        if not _same(cfg.dt, dt):
            raise ValueError(
                f"{tr.path}: sampled at {dt:.9g} s, the RC state at {cfg.dt:.9g} s; record "
                "at the state's rate or start a new state directory"
            )
        if cfg.period_samples != n:
            raise ValueError(
                f"{tr.path}: holds {n} samples, the RC state's period {cfg.period_samples}; "
                "give exactly one period of the contour"
            )
        if mem.memory.shape[1] != 2:
            raise ValueError(
                f"the RC state in {sd} has {mem.memory.shape[1]} axes; this step needs x, y"
            )
        _check_options(mem, tau_s, gain, lead_samples)
        if not _at_boundary(cfg, mem.samples):
            raise ValueError(
                f"the RC state in {sd} was saved mid-period (sample {mem.samples}, period "
                f"{n}); save the simulated state at a period boundary"
            )
    contour = sd / CONTOUR_FILE
    if not created and contour.is_file():
        ref0 = read_contour(contour, n)
        dev, k, j = largest_deviation(tr.reference, ref0)
        if dev > REF_TOL_MM:
            raise ValueError(
                f"{tr.path}: ref_{'xy'[j]} differs from the first trial's contour by "
                f"{dev * 1e6:.1f} nm at t = {tr.time[k]:g} s; ref_x, ref_y must be the "
                "uncorrected contour (not the command of the last step)"
            )
    err = tr.reference - tr.output
    if not created and mem.samples > 0 and np.array_equal(err, mem.error):
        raise ValueError(
            f"{tr.path}: this trial was learned from already (its error equals the state's "
            "last period); measure the command written by the last step"
        )
    # the hardware's inner controller is not known here: the file-based memory holds none
    # (a simulation resumed from it starts its inner controller at rest)
    new = dataclasses.replace(mem.after_period(err), inner=np.zeros(0))
    corr = new.next_correction()
    command = tr.reference + corr
    if not np.all(np.isfinite(command)):  # pragma: no cover - finite inputs, finite update
        raise ValueError("the next command is not finite; nothing was written")
    if created or not contour.is_file():
        sd.mkdir(parents=True, exist_ok=True)
        atomic_save_npz(contour, reference=tr.reference, dt=np.array(dt))
    write_columns(
        out,
        {
            "time": tr.time,
            "command_x": command[:, 0],
            "command_y": command[:, 1],
            "correction_x": corr[:, 0],
            "correction_y": corr[:, 1],
        },
        unit="mm",
    )
    new.save(sd / STATE_FILE)
    rms = np.sqrt(np.mean(err**2, axis=0)) * 1e6
    crms = np.sqrt(np.mean(corr**2, axis=0)) * 1e6
    return RCStepReport(
        period=new.samples // new.config.period_samples,
        rms_nm=(float(rms[0]), float(rms[1])),
        correction_rms_nm=(float(crms[0]), float(crms[1])),
        out_path=Path(out),
        created=created,
    )


def read_contour(path: str | os.PathLike[str], n: int) -> np.ndarray:
    """The first trial's contour of an RC state folder (`CONTOUR_FILE`), mm.

    Its member ``reference`` is checked from the archive's header before it is read
    (`microfab.io.schema.check_npz`: size, dtype, shape ``(n, 2)``) and then for finite
    values.

    Parameters
    ----------
    path : path
        The ``.npz`` file.
    n : int
        Samples of one period (the state's).

    Returns
    -------
    numpy.ndarray
        Shape (n, 2), float64, mm.

    Raises
    ------
    ValueError
        (`microfab.io.schema.SchemaError`) Unreadable, another kind of file (named), no
        ``reference``, another shape or dtype, or a NaN or infinite value.
    """
    p = Path(path)
    try:
        members = check_npz(p)
        if "reference" not in members:
            raise SchemaError(f"{p}: member 'reference' is missing (the contour, mm)")
        shape, dtype = members["reference"]
        if shape != (n, 2) or dtype.kind != "f":
            raise SchemaError(
                f"{p}: the contour 'reference' must be float of shape {(n, 2)}, got {dtype} {shape}"
            )
        with np.load(p, allow_pickle=False) as z:
            raw = np.array(z["reference"])
            if "dt" in members:  # written beside the contour: its sample time, s
                check_array(str(p), "dt", np.array(z["dt"]), shape=(), low=1e-9, high=1.0, unit="s")
    except SchemaError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        other = describe_file(p)
        if other is not None and other != "a zip archive":
            raise SchemaError(f"{p}: this is {other}, not the contour of an RC state") from None
        raise SchemaError(f"{p}: cannot read the contour ({exc})") from None
    return check_array(str(p), "the contour 'reference'", raw, shape=(n, 2), unit="mm")
