"""``microfab calibrate nanomanipulator``: seed 001's twin fitted jointly on the calibration core.

Seed 001 §4.2 (``shared/seeds/001_44fdd8e8f587fd7f.txt``) measures, on the four-circle job,
axial tracking errors of 485.8 nm (x) and 885.8 nm (y) (Fig. 13a), a contour error of
769.5 nm RMS (Fig. 13b) and a laser that switches on once the error "reaches submicrons in
3–4 periods". It names no sensor, noise or disturbance beyond eq. (1)'s bound ``d0``.

`problem` declares these as a `microfab.calibrate.CalibrationProblem` on the job itself
(`microfab.machines.nanomanipulator.job.run_job`, whatever controller it runs):

* **fit**: the axial RMS of x and y (the only two numbers the twin is chosen on);
* **check** (held back, predicted): the contour RMS and the gate period.

The free parameters are what the seed leaves open about the error's sources: the sensor
noise rms per axis, its colour (one first-order low-pass time constant for both axes,
`microfab.plants.nanomanipulator.colour_noise`) and the disturbance bound ``d0`` per axis.
Five parameters for two fit targets: the fit is not unique, and the sensitivity says which
parameter pins which target; the checks say whether the point chosen predicts the rest.

**Why the contour RMS is hard to reach** (measured, see the module's tests and the issue's
note). The metrics are taken on the measured error. An error source that is independent of
the circle's phase (sensor noise of any colour, correlated between the axes or not; the
disturbance, whose sinusoids are incommensurate with the 1 Hz circles) adds the same to
the contour's mean square as the mean of the axial mean squares; over whole periods a
correlation between the axes cancels (``mean(sin 2θ) = 0``). So with such sources alone the
contour RMS stays at or below ``sqrt((485.8² + 885.8²)/2) = 714.3`` nm once the axial RMS
are fitted, while seed 001 measures 769.5 nm: the paper's error is biased towards the
radius, which only an error locked to the path's phase (a radius or gain error, not a lag)
can give. The twin's own path-locked error is the first period's start-up transient, which
is mostly tangential (a lag) and pulls the contour below 714 nm.

Measured on the seed's network (the job before issue 45's learning controller):
the axial RMS were met and the contour RMS was predicted at 606 nm (−21 %); over 570
points, with the contour RMS as a third fit target too, it never exceeded 0.98 of
``sqrt((ax² + ay²)/2)``: the seed's network left a path-locked error that was mostly a lag.
On the job's default, proposed controller (`microfab calibrate nanomanipulator`, budget
240, seed 0, 251 points, 2 min 23 s with 2 workers) the axial RMS are met (485.8 / 885.8
nm) and the contour RMS is predicted at 714.3 nm (−7.2 %, the check met): exactly the
phase-independent value, since the learning controller removes the path-locked error.
The remaining −7.2 % is the paper's own path-locked radial error, 404.5 nm
(`radial_share_nm`; Fig. 13b's "relatively uniform" contour error over the phase fits a
radius or gain error at the circle's frequency), which no noise or disturbance gives;
`contour_finding` says so when the check is missed. The gate check is not met: the
proposed controller is submicron from the first period, so the gate opens in period 2
against the paper's 3–4.

`write_twin` writes a calibration's values into a twin data file through
`microfab.calibrate.twin_file.write_calibrated` (sources naming the targets and checks).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from collections.abc import Mapping
from pathlib import Path

from microfab.calibrate import CalibrationProblem, CalibrationResult, FreeParameter, Target
from microfab.calibrate.twin_file import TwinKey, write_calibrated
from microfab.core.provenance import Calibration, quantity
from microfab.data import read_text as read_data_text
from microfab.machines.nanomanipulator.job import JobConfig, job_reference, make_twin, run_job
from microfab.measure.circle_tracking import SEED_AXIAL_RMS_NM as _SEED_AXIAL
from microfab.measure.circle_tracking import SEED_CONTOUR_RMS_NM, SEED_GATE_PERIODS

__all__ = [
    "AXIAL_TOLERANCE",
    "CALIBRATION",
    "CONTOUR_TOLERANCE",
    "DATA_FILE",
    "DEFAULT_BUDGET",
    "SEED_AXIAL_RMS_NM",
    "SEED_CONTOUR_RMS_NM",
    "TWIN_KEYS",
    "axial_quantity",
    "contour_finding",
    "evaluate",
    "free_parameters",
    "problem",
    "radial_share_nm",
    "targets",
    "write_twin",
]

#: seed 001 §4.2 / Fig. 13a: axial tracking errors (x, y), nm, read as RMS: the fit targets.
SEED_AXIAL_RMS_NM = (_SEED_AXIAL["x"], _SEED_AXIAL["y"])
#: The twin data file the calibration writes.
DATA_FILE = "nanomanipulator_twin.toml"
#: Relative tolerance of the axial RMS fit targets: assumed ±3 %. The paper reports one
#: run with no spread; the twin's own spread over noise seeds 0-7 is 0.12 % (x and y, one
#: standard deviation, measured on the default job), so ±3 % is set by the paper's unknown
#: repeatability, not by the twin's noise.
AXIAL_TOLERANCE = 0.03
#: Relative tolerance of the contour RMS check: ±15 % (issue 45's acceptance).
CONTOUR_TOLERANCE = 0.15
#: Points the search may ask for by default. One job run costs about 0.45 s on one core
#: (measured, default job, numba compiled), so the search, the sensitivity (10 points)
#: and a conflict sweep of the same size stay within about 5 minutes on one core.
DEFAULT_BUDGET = 240


def axial_quantity(axis: str) -> str:
    """Id of seed 001 §4.2's axial RMS of ``axis`` (``"x"`` or ``"y"``)."""
    return quantity("001", "§4.2", "axial RMS", axis)


CONTOUR_QUANTITY = quantity("001", "§4.2", "contour RMS")
GATE_QUANTITY = quantity("001", "§4.2", "gate period")

#: The fit's targets (the axial RMS of both axes) and the checks held back (the contour
#: RMS and the gate period).
CALIBRATION = Calibration(
    command="microfab calibrate nanomanipulator",
    data_file=DATA_FILE,
    targets=frozenset(axial_quantity(a) for a in ("x", "y")),
    what="sensor noise rms per axis and its colour, disturbance bound d0 per axis",
    checks=frozenset((CONTOUR_QUANTITY, GATE_QUANTITY)),
)

#: Where each free parameter goes in the twin's data file (nm -> mm, ms -> s).
TWIN_KEYS = (
    TwinKey("noise_x_nm", "axes.x", "noise_rms_mm", scale=1e-6),
    TwinKey("noise_y_nm", "axes.y", "noise_rms_mm", scale=1e-6),
    TwinKey("noise_time_constant_ms", "axes.x", "noise_time_constant_s", scale=1e-3),
    TwinKey("noise_time_constant_ms", "axes.y", "noise_time_constant_s", scale=1e-3),
    TwinKey("d0_x_mm_s2", "axes.x", "disturbance_mm_s2"),
    TwinKey("d0_y_mm_s2", "axes.y", "disturbance_mm_s2"),
)


def targets() -> tuple[Target, ...]:
    """The seed 001 §4.2 targets: axial RMS x, y (fit); contour RMS, gate period (check)."""
    lo, hi = SEED_GATE_PERIODS
    out = [
        Target(
            axial_quantity(ax),
            value,
            AXIAL_TOLERANCE * value,
            "nm",
            f"seed 001 §4.2 / Fig. 13a: axial tracking error {ax} {value} nm (read as RMS); "
            "tolerance assumed ±3 % (the paper gives no spread)",
        )
        for ax, value in zip("xy", SEED_AXIAL_RMS_NM, strict=True)
    ]
    out.append(
        Target(
            CONTOUR_QUANTITY,
            SEED_CONTOUR_RMS_NM,
            CONTOUR_TOLERANCE * SEED_CONTOUR_RMS_NM,
            "nm",
            "seed 001 §4.2 / Fig. 13b: contour error 769.5 nm RMS; ±15 % (issue 45's acceptance)",
            role="check",
        )
    )
    out.append(
        Target(
            GATE_QUANTITY,
            (lo + hi) / 2.0,
            (hi - lo) / 2.0,
            "period",
            "seed 001 §4.2: the laser is switched on once the error 'reaches submicrons in "
            "3-4 periods'; ours: the period in which the gate opened (1-based), the latest "
            "over the circles (the job waits for its slowest circle), met at 3 or 4 (a twin "
            "converging faster or slower than the paper's is not met); NaN when a gate never "
            "opened",
            role="check",
        )
    )
    return tuple(out)


def free_parameters() -> tuple[FreeParameter, ...]:
    """The free parameters: noise rms x, y; noise time constant; ``d0`` x, y."""
    noise = (
        "assumed: from 10 nm (far below the twin's noise-free axial error, 320 / 446 nm "
        "measured) to 2000 nm (above the largest axial RMS of seed 001, 885.8 nm)"
    )
    d0 = (
        "assumed: 1 to 4000 mm/s² (a static-equivalent d0/a0 of 0.01 µm to 40 µm), from "
        "negligible to past the point where the §4.2 gates never open (measured: 100x the "
        "file's 20 / 40 mm/s²); seed 001 eq. (1) only bounds |d(t)| <= d0"
    )
    return (
        FreeParameter("noise_x_nm", 10.0, 2000.0, "nm", noise, log=True),
        FreeParameter("noise_y_nm", 10.0, 2000.0, "nm", noise, log=True),
        FreeParameter(
            "noise_time_constant_ms",
            0.03,
            300.0,
            "ms",
            "assumed: first-order low-pass of the sensor noise, from nearly white (0.03 ms: "
            "corner 5.3 kHz, past the 5 kHz Nyquist rate of the assumed 10 kHz loop) to "
            "drift-like (300 ms: corner 0.53 Hz, below the 1 Hz circles); one for both "
            "axes (the same sensor type)",
            log=True,
        ),
        FreeParameter("d0_x_mm_s2", 1.0, 4000.0, "mm/s²", d0, log=True),
        FreeParameter("d0_y_mm_s2", 1.0, 4000.0, "mm/s²", d0, log=True),
    )


def _with_parameters(config: JobConfig, values: Mapping[str, float]) -> JobConfig:
    """``config`` with the twin's noise, colour and ``d0`` replaced by ``values``."""
    tau = float(values["noise_time_constant_ms"]) * 1e-3
    twin = dataclasses.replace(
        config.twin,
        noise_rms_mm=(float(values["noise_x_nm"]) * 1e-6, float(values["noise_y_nm"]) * 1e-6),
        noise_time_constant_s=(tau, tau),
        disturbance_mm_s2=(float(values["d0_x_mm_s2"]), float(values["d0_y_mm_s2"])),
    )
    return dataclasses.replace(config, twin=twin)


def evaluate(values: Mapping[str, float], *, config: JobConfig) -> dict[str, float]:
    """The job's metrics at one parameter set (the problem's model; module-level, picklable).

    Parameters
    ----------
    values : mapping of str to float
        ``noise_x_nm``, ``noise_y_nm`` (nm), ``noise_time_constant_ms`` (ms),
        ``d0_x_mm_s2``, ``d0_y_mm_s2`` (mm/s²).
    config : JobConfig
        The job; its twin's noise and disturbance are replaced by ``values``.

    Returns
    -------
    dict of str to float
        Target id -> model value: axial RMS x, y and contour RMS (nm) of the measured
        error over every circle's periods, and the latest gate period over the circles
        (NaN when a gate never opened). Every value is NaN when the loop diverged (the job
        refuses non-finite errors with a ValueError).
    """
    names = [t.name for t in targets()]
    try:
        m = run_job(_with_parameters(config, values)).metrics()
    except ValueError:  # a diverging loop: the gate refuses its non-finite errors
        return dict.fromkeys(names, math.nan)
    gates = m.gate_period
    gate = math.nan if any(g is None for g in gates) else float(max(g for g in gates if g))
    return {
        axial_quantity("x"): float(m.axial_rms_nm[0]),
        axial_quantity("y"): float(m.axial_rms_nm[1]),
        CONTOUR_QUANTITY: float(m.contour_rms_nm),
        GATE_QUANTITY: gate,
    }


def _file_text(config: JobConfig) -> str:
    p = config.twin.params_file
    return read_data_text(DATA_FILE) if p is None else Path(p).read_text(encoding="utf-8")


def problem(
    config: JobConfig | None = None,
    *,
    source: str | Path | None = None,
    contour_fit: bool = False,
) -> CalibrationProblem:
    """Seed 001 §4.2 as a calibration problem on the nanomanipulator job.

    Parameters
    ----------
    config : JobConfig, optional
        The job (default `JobConfig()`, seed 001 §4.2's four circles); its sensor noise and
        disturbance must be on.
    source : path-like, optional
        The twin data file to calibrate (replaces ``config.twin.params_file``).
    contour_fit : bool
        Diagnostic: the contour RMS becomes a fit target too (its conflict with the axial
        RMS is then reported by `microfab.calibrate.calibrate`); never for a twin written.

    Returns
    -------
    CalibrationProblem
        Targets (`targets`), free parameters (`free_parameters`), the model `evaluate` on
        ``config`` and an identity holding the twin file's and the job's digests.

    Raises
    ------
    ValueError
        When the job's sensor noise or disturbance is off (they are what is fitted), or
        its path goes beyond the stage's travel or limits.
    """
    cfg = config or JobConfig()
    if source is not None:
        cfg = dataclasses.replace(cfg, twin=dataclasses.replace(cfg.twin, params_file=str(source)))
    if not (cfg.twin.noise and cfg.twin.disturbance):
        raise ValueError(
            "the nanomanipulator calibration fits the sensor noise and the disturbance: "
            "run it with [twin] noise = true and disturbance = true"
        )
    tgt = targets()
    if contour_fit:
        tgt = tuple(
            dataclasses.replace(t, role="fit") if t.name == CONTOUR_QUANTITY else t for t in tgt
        )
    job_reference(cfg, make_twin(cfg.twin))  # a path the stage refuses fails here, not as NaN
    digest = hashlib.sha256(_file_text(cfg).encode()).hexdigest()
    return CalibrationProblem(
        tgt,
        free_parameters(),
        functools.partial(evaluate, config=cfg),
        identity=f"{DATA_FILE} sha256 {digest}; job {cfg.fingerprint()}",
    )


def radial_share_nm(axial_x_nm: float, axial_y_nm: float, contour_nm: float) -> float:
    """The path-locked radial error that a contour RMS above the axial mean implies, nm.

    An error independent of the circle's phase gives ``c² = (x² + y²)/2`` (the contour is
    the error's normal part; averaged over whole periods ``cos² θ`` and ``sin² θ`` are
    ``1/2`` and the axes' correlation cancels). A constant radial error ``ρ`` (a radius or
    gain error at the circle's frequency) adds ``ρ²`` to the contour's mean square and only
    ``ρ²/2`` to each axis's, so ``ρ = sqrt(2 (c² − (x² + y²)/2))``; 0 when ``c`` is not
    above the phase-independent value.

    Parameters
    ----------
    axial_x_nm, axial_y_nm, contour_nm : float
        Axial RMS per axis and contour RMS, nm.

    Returns
    -------
    float
        ``ρ``, nm (seed 001 §4.2: 485.8, 885.8, 769.5 nm give 404.5 nm).
    """
    excess = contour_nm**2 - 0.5 * (axial_x_nm**2 + axial_y_nm**2)
    return math.sqrt(2.0 * excess) if excess > 0.0 else 0.0


def contour_finding(result: CalibrationResult) -> str | None:
    """One line on the contour RMS check when it is not met, with its structural cause.

    Compares the paper's numbers and the calibrated twin's through `radial_share_nm`:
    the paper's contour RMS implies a path-locked radial error; a twin whose error sources
    are independent of the phase (noise, disturbance) cannot give it. None when the check
    is met or missing.
    """
    rows = {t.name: t for t in result.targets}
    c = rows.get(CONTOUR_QUANTITY)
    ax, ay = rows.get(axial_quantity("x")), rows.get(axial_quantity("y"))
    if c is None or ax is None or ay is None or c.met:
        return None
    paper = radial_share_nm(ax.value, ay.value, c.value)
    mean = math.sqrt(0.5 * (ax.model**2 + ay.model**2))
    ratio = c.model / mean if mean > 0 else float("nan")
    twin = radial_share_nm(ax.model, ay.model, c.model)
    return (
        f"contour RMS {c.model:.1f} nm against the paper's {c.value:g} nm: seed 001's numbers "
        f"imply a path-locked radial error of {paper:.0f} nm (contour above the "
        f"phase-independent sqrt((x² + y²)/2) = "
        f"{math.sqrt(0.5 * (ax.value**2 + ay.value**2)):.1f} nm); the twin's contour is "
        f"{ratio:.2f} of its own axial mean (radial share {twin:.0f} nm): its fitted error "
        "sources (sensor noise, disturbance) are independent of the circle's phase, so no "
        "value of them meets both; the structure it points to is a radius or gain error at "
        "the circle's frequency, which the learning controller removes on the twin"
    )


def write_twin(
    result: CalibrationResult, path: str | Path, *, source: str | Path | None = None
) -> Path:
    """Write a twin data file with the calibrated values (atomically).

    Parameters
    ----------
    result : CalibrationResult
        A calibration of `problem` (its parameters hold every `TWIN_KEYS` parameter).
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to start from (default the packaged ``nanomanipulator_twin.toml``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        A result without one of the parameters, or a file without one of the keys and
        their sources (`microfab.plants.sourced_toml.update_sourced`); nothing is written.
    """
    return write_calibrated(
        result,
        TWIN_KEYS,
        command=CALIBRATION.command,
        data_file=DATA_FILE,
        path=path,
        source=source,
    )
