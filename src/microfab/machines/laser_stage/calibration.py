"""``microfab calibrate laser``: the seed 004 stage twin fitted jointly to Fig. 3 (issue 45).

Seed 004 §IV.A (Fig. 3a/3b, the 30 µm circle under preview + DOB): the axis errors "are
generally lower than 0.5 µm, reaching 0.8 µm at the peak points for some instances
throughout the motion", and "can be characterized to be due to the sources of noise in the
system and due to the errors in the disturbance force estimation". Both numbers are fit
targets of one `microfab.calibrate.CalibrationProblem` (`problem`):

* the peak ``|error|``, the larger of the two axes, 0.8 µm: the sentence describes Fig. 3a
  and 3b together, and its "reaching 0.8 µm at the peak points for some instances" is the
  largest value either plot reaches (fitting it per axis would read a second 0.8 µm into
  the text that it does not state);
* the share of samples within ±0.5 µm, per axis, at least 95 % (the issue's reading of
  "generally"; each plot is "generally lower").

The run is `FIG3_JOB` (`laser_stage.play_contour`: 1 mm/s, three laps, noise on; axis
error ``r − y`` over the full-speed laps, `ContourPlay.axis_errors`). A peak of 0.8 µm
with 95 % of the samples under 0.5 µm needs a *peaky* error: short glitches at the
velocity reversals, where the friction force changes sign and the DOB (eq. 4) lags it.
Measured on the twin before this calibration (one disturbance scale fitted to the peak):
the glitches last about 10 ms, so 9-12 % of the samples lie above 0.5 µm; a ten times
larger cogging ripple changes neither number (the DOB rejects a force that varies this
slowly), and encoder noise is broad (it raises every sample alike). What sets the
glitch's shape is the friction law around zero velocity, so the free parameters are the
LuGre friction's magnitude and its shape at a reversal, with the noise as the broad term
(`PARAMETERS`):

``disturbance_scale``
    Magnitude of friction + cogging + cable (the data file's ``[disturbance]`` key).
``static_ratio``
    Break-away over Coulomb force ``F_s / F_c`` (both axes; the file's ``static_n`` is
    ``static_ratio × coulomb_n``): the Stribeck rise, a sharper force change at a reversal.
``stribeck_m_s``
    Stribeck velocity ``v_s`` (both axes): how long the rise lasts around a reversal.
``bristle_rate_per_m``
    ``σ0 / F_c``, the inverse of the pre-sliding displacement (both axes; the file's
    ``bristle_stiffness_n_per_m`` is ``bristle_rate_per_m × coulomb_n``): how fast the
    friction changes sign once the stage reverses.
``noise_rms_m``
    Encoder interpolation noise rms (both axes): the broad term.

A check held back (`CHECK_NAMES`): the rms motor force of the run within Table I's
continuous force, 3 N.

Each evaluation writes the candidate values into a copy of the twin's data file through the
same `TWIN_KEYS` that `write_twin` uses, so the model the search runs is the file it writes
(to the 5 significant digits written).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from microfab.calibrate import CalibrationProblem, CalibrationResult, FreeParameter, Target
from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.core.provenance import Calibration, quantity
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings, play_contour
from microfab.machines.twins import data_path
from microfab.measure.contour import AXIS_BAND_M
from microfab.plants.lmw_stage_params import AXES, LMWStageParams, load_params
from microfab.plants.sourced_toml import update_sourced
from microfab.trajectory.force_check import CONTINUOUS_FORCE_N  # seed 004 Table I: 3 N

__all__ = [
    "CALIBRATION",
    "CHECK_NAMES",
    "COMMAND",
    "DATA_FILE",
    "DEFAULT_BUDGET",
    "FIG3_JOB",
    "FIG3_PEAK_ERROR_M",
    "FIG3_PEAK_QUANTITY",
    "FIG3_SHARE",
    "FIG3_SHARE_QUANTITY",
    "FIT_NAMES",
    "FORCE_QUANTITY",
    "PARAMETERS",
    "TWIN_KEYS",
    "evaluate",
    "problem",
    "twin_keys",
    "write_twin",
]

COMMAND = "microfab calibrate laser"
DATA_FILE = "lmw_stage.toml"

FIG3_PEAK_ERROR_M = 0.8e-6  # seed 004 §IV.A: "reaching 0.8 µm at the peak points"
#: Share of samples within ±0.5 µm (`AXIS_BAND_M`, seed 004 §IV.A "generally lower than
#: 0.5 µm") per axis: the issue's reading of "generally" (issue 45 item 4).
FIG3_SHARE = 0.95

#: The Fig. 3 run: the seed's 30 µm circle under preview + DOB (the motion experiment of
#: §IV.A has no contour compensator), at 1 mm/s (assumed), noise on.
FIG3_JOB = ContourJob(control=ControlSettings(law="preview-dob"))

#: The published numbers (`microfab.core.provenance`): the two fit targets and the check.
FIG3_PEAK_QUANTITY = quantity("004", "§IV.A, Fig. 3", "peak error")
FIG3_SHARE_QUANTITY = quantity("004", "§IV.A, Fig. 3", "share of errors within 0.5 um")
FORCE_QUANTITY = quantity("004", "Table I", "continuous force")

#: What this calibration fits and holds back, for the rows' fitted / predicted labels.
CALIBRATION = Calibration(
    command=COMMAND,
    data_file=DATA_FILE,
    targets=frozenset({FIG3_PEAK_QUANTITY, FIG3_SHARE_QUANTITY}),
    checks=frozenset({FORCE_QUANTITY}),
    what="friction magnitude and shape (Stribeck rise and velocity, pre-sliding) and noise",
)

_FIG3 = "seed 004 §IV.A, Fig. 3a/3b (30 µm circle, preview + DOB)"
# Tolerances (assumed, beside the measured spread they must cover): at the calibrated
# answer the encoder-noise seed alone (seeds 0-5) moves the peak over 0.800-0.820 µm, the
# y share over 95.40-95.49 % and the x share over 96.32-96.41 %, so 0.05 µm (half the
# 0.1 µm step of the text) is over twice that spread and one percentage point ten times
# it; the force is far inside its bound (0.443-0.445 N for 3 N).
_PEAK_TOL_UM = 0.05
_SHARE_TOL = 0.01
_FORCE_TOL_N = 0.3

#: Fit target names (model output keys) and the check's.
FIT_NAMES = ("fig3_peak_um", "fig3_share_x", "fig3_share_y")
CHECK_NAMES = ("rms_force_n",)


def _targets() -> tuple[Target, ...]:
    share_src = (
        f"{_FIG3}: errors 'generally lower than 0.5 µm'; read as >= 95 % of samples per axis "
        f"within ±{AXIS_BAND_M * 1e6:g} µm "
        f"(issue 45). Tolerance {_SHARE_TOL:g} assumed: one percentage point of slack, the "
        "reading of 'generally' is itself no sharper"
    )
    return (
        Target(
            FIT_NAMES[0],
            FIG3_PEAK_ERROR_M * 1e6,
            _PEAK_TOL_UM,
            "µm",
            f"{_FIG3}: 'reaching 0.8 µm at the peak points', the larger of the two axes. "
            f"Tolerance {_PEAK_TOL_UM:g} µm assumed: half the 0.1 µm step to which the text "
            "states the value",
        ),
        Target(FIT_NAMES[1], FIG3_SHARE, _SHARE_TOL, "1", share_src, side="at least"),
        Target(FIT_NAMES[2], FIG3_SHARE, _SHARE_TOL, "1", share_src, side="at least"),
        Target(
            CHECK_NAMES[0],
            CONTINUOUS_FORCE_N,
            _FORCE_TOL_N,
            "N",
            "seed 004 Table I: continuous force 3 N; the larger axis's rms motor force over "
            f"the Fig. 3 laps stays within it. Tolerance {_FORCE_TOL_N:g} N assumed: 10 %",
            role="check",
            side="at most",
        ),
    )


#: The free parameters, bounds sourced or assumed (module notes).
PARAMETERS: tuple[FreeParameter, ...] = (
    FreeParameter(
        "disturbance_scale",
        0.5,
        10.0,
        "1",
        "assumed: the data file's friction (1 % of the stage weight, seed 004 §II.C 'very "
        "low friction force') halved, up to 10x (about 10 % of the weight, beyond a "
        "roller-cage slide)",
        log=True,
    ),
    FreeParameter(
        "static_ratio",
        1.0,
        3.0,
        "1",
        "assumed: LuGre break-away over Coulomb force, 1 (no Stribeck rise) to 3 (the "
        "high end of the ratios reported for lubricated guides)",
    ),
    FreeParameter(
        "stribeck_m_s",
        1.0e-5,
        1.0e-2,
        "m/s",
        "assumed: Stribeck velocities of lubricated sliding and rolling contacts, about "
        "0.01 to 10 mm/s",
        log=True,
    ),
    FreeParameter(
        "bristle_rate_per_m",
        3.0e5,
        1.0e8,
        "1/m",
        "assumed: sigma0 / F_c, the inverse pre-sliding displacement, from 3.3 µm (a soft "
        "rolling contact) to 10 nm (seed 004 Table I's encoder count: a stiffer contact "
        "is not resolved)",
        log=True,
    ),
    FreeParameter(
        "noise_rms_m",
        1.0e-9,
        1.0e-8,
        "m",
        "assumed: encoder interpolation noise from below the data file's 2.5 nm (a "
        "quarter of seed 004 Table I's 10 nm count) up to that count: an interpolator "
        "whose noise exceeded its count would not give the 10 nm resolution Table I states",
        log=True,
    ),
)

#: Evaluations of a real run (`calibrate`'s ``budget``). Measured: a `FIG3_JOB` run takes
#: 0.15-0.3 s on one core (more sub-steps with stiffer bristles), and `calibrate(problem(),
#: budget=400, seed=0)` asked for 343 points in 59 s (DE: 6 generations of 50, then the
#: polish; every fit target met at the 6th); a conflict sweep, when one runs, doubles it.
DEFAULT_BUDGET = 400


def twin_keys(params: LMWStageParams | None = None) -> tuple[TwinKey, ...]:
    """Where each free parameter goes in the twin's data file.

    Parameters
    ----------
    params : LMWStageParams, optional
        The data file the calibration starts from (default the packaged one): its Coulomb
        forces scale ``static_ratio`` and ``bristle_rate_per_m`` into each axis's
        ``static_n`` and ``bristle_stiffness_n_per_m``.
    """
    cfg = params if params is not None else load_params()
    keys = [TwinKey("disturbance_scale", "disturbance", "disturbance_scale")]
    for i, ax in enumerate(AXES):
        sec = f"axes.{ax}"
        fc = cfg.coulomb_n[i]
        keys += [
            TwinKey("static_ratio", sec, "static_n", scale=fc),
            TwinKey("stribeck_m_s", sec, "stribeck_m_s"),
            TwinKey("bristle_rate_per_m", sec, "bristle_stiffness_n_per_m", scale=fc),
            TwinKey("noise_rms_m", sec, "noise_rms_m"),
        ]
    return tuple(keys)


#: `twin_keys` of the packaged data file.
TWIN_KEYS: tuple[TwinKey, ...] = twin_keys()


def evaluate(
    values: Mapping[str, float],
    *,
    job: ContourJob,
    source: str | None,
    keys: tuple[TwinKey, ...],
) -> dict[str, float]:
    """Model values of every target at one parameter set (the model of `problem`).

    Parameters
    ----------
    values : mapping
        Parameter name -> value, in each `PARAMETERS` unit.
    job : ContourJob
        The Fig. 3 run; its twin's data file is replaced by the candidate's.
    source : str or None
        The twin data file the candidate starts from (None: the packaged one).
    keys : tuple of TwinKey
        Where each parameter goes (`twin_keys` of ``source``).

    Returns
    -------
    dict
        ``fig3_peak_um`` (µm), ``fig3_share_x`` / ``_y`` (fraction of samples within
        ±0.5 µm), ``rms_force_n`` (N, the larger axis).
    """
    updates = {
        (k.section, k.key): (float(f"{values[k.parameter] * k.scale:.{k.digits}g}"), "candidate")
        for k in keys
    }
    text = update_sourced(source, DATA_FILE, updates)
    with tempfile.TemporaryDirectory(prefix="microfab-laser-cal-") as tmp:
        path = Path(tmp) / DATA_FILE
        path.write_text(text, encoding="utf-8")
        tw = dataclasses.replace(job.twin, params_file=str(path))
        run = play_contour(job.with_(twin=tw))
    e = run.axis_errors()
    force = np.asarray(run.trace.force)[run.full_laps]
    return {
        FIT_NAMES[0]: max(e.peak_m) * 1e6,
        FIT_NAMES[1]: e.fraction_below[0],
        FIT_NAMES[2]: e.fraction_below[1],
        CHECK_NAMES[0]: float(np.max(np.sqrt(np.mean(force**2, axis=0)))),
    }


def problem(job: ContourJob = FIG3_JOB, *, source: str | Path | None = None) -> CalibrationProblem:
    """The joint calibration of the stage twin to seed 004 Fig. 3 (module notes).

    Parameters
    ----------
    job : ContourJob
        The run (default `FIG3_JOB`; a shorter one for a quick test). Its twin must not
        override the disturbance scale or name a data file (use ``source``).
    source : path-like, optional
        The twin data file to start from (default the packaged ``lmw_stage.toml``).

    Returns
    -------
    CalibrationProblem
        Fit targets `FIT_NAMES`, check `CHECK_NAMES`, free `PARAMETERS`; its identity holds
        the data file's SHA-256 and the job.

    Raises
    ------
    ValueError
        A job whose twin fixes what the calibration chooses or reads another file; a data
        file that does not load.
    """
    if job.twin.disturbance_scale is not None or job.twin.params_file is not None:
        raise ValueError(
            "the calibration job's twin must take its disturbance scale and data file from "
            "the calibration: leave disturbance_scale and params_file unset (give source=)"
        )
    src = None if source is None else str(source)
    keys = twin_keys(load_params(src))
    raw = (data_path(DATA_FILE) if src is None else Path(src)).read_bytes()
    digest = hashlib.sha256(raw).hexdigest()
    return CalibrationProblem(
        targets=_targets(),
        parameters=PARAMETERS,
        evaluate=functools.partial(evaluate, job=job, source=src, keys=keys),
        identity=f"{DATA_FILE} sha256 {digest}; job {job!r}",
    )


def write_twin(
    result: CalibrationResult, path: str | Path, *, source: str | Path | None = None
) -> Path:
    """Write the twin data file with the calibrated values (atomically).

    Parameters
    ----------
    result : CalibrationResult
        A calibration of `problem`.
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to start from (default the packaged ``lmw_stage.toml``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        A result without this problem's parameters, or a file without the keys
        (`microfab.plants.sourced_toml.update_sourced`); nothing is written then.
    """
    src = None if source is None else str(source)
    return write_calibrated(
        result,
        twin_keys(load_params(src)),
        command=COMMAND,
        data_file=DATA_FILE,
        path=path,
        source=src,
    )
