"""``microfab calibrate nanomanipulator``: fit the twin's sensor noise to seed 001 §4.2.

Seed 001 §4.2 (Fig. 13a) reports axial tracking errors of 485.8 nm (x) and 885.8 nm (y)
on the four-circle job; it names no noise, disturbance or sensor. The twin's
``noise_rms_mm`` per axis is the one free magnitude fitted here: `fit_sensor_noise` runs
the job with a noise (the caller's ``run``; `fit_noise` runs the nanomanipulator job,
`microfab.machines.nanomanipulator.job.run_job`), compares the axial
RMS of the error the sensor shows over every circle period
(`microfab.measure.circle_tracking.tracking_metrics`) with the seed's, and updates the
noise per axis by the secant method on ``(σ², RMS²)``. White noise adds to the squared
RMS, ``RMS² ≈ c + g σ²``, so the secant converges in two or three runs. The contour RMS
(769.5 nm, Fig. 13b) is not fitted: it is the prediction the fit is checked on.

`write_noise` stores the fitted values in a copy of the twin's data file (or the packaged
one) with a source line naming this command.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from microfab.core.provenance import Calibration, quantity
from microfab.core.validate import check_in_range, check_int
from microfab.io.atomic import atomic_write_text
from microfab.machines.nanomanipulator.job import JobConfig, make_twin, run_job
from microfab.measure.circle_tracking import SEED_AXIAL_RMS_NM as _SEED_AXIAL
from microfab.measure.circle_tracking import SEED_CONTOUR_RMS_NM
from microfab.plants.sourced_toml import update_sourced

__all__ = [
    "CALIBRATION",
    "SEED_AXIAL_RMS_NM",
    "SEED_CONTOUR_RMS_NM",
    "NoiseFit",
    "axial_quantity",
    "fit_noise",
    "fit_sensor_noise",
    "write_noise",
]

#: seed 001 §4.2 / Fig. 13a: axial tracking errors (x, y), nm, read as RMS: the fit's
#: target (`microfab.measure.circle_tracking.SEED_AXIAL_RMS_NM`, as a pair). The contour
#: RMS of Fig. 13b, `SEED_CONTOUR_RMS_NM` (769.5 nm), is the check.
SEED_AXIAL_RMS_NM = (_SEED_AXIAL["x"], _SEED_AXIAL["y"])
_TARGET = SEED_AXIAL_RMS_NM


def axial_quantity(axis: str) -> str:
    """Id of seed 001 §4.2's axial RMS of ``axis`` (``"x"`` or ``"y"``)."""
    return quantity("001", "§4.2", "axial RMS", axis)


#: The fit's targets: the axial RMS of both axes (the contour RMS is its check).
CALIBRATION = Calibration(
    command="microfab calibrate nanomanipulator",
    data_file="nanomanipulator_twin.toml",
    targets=frozenset(axial_quantity(a) for a in ("x", "y")),
    what="sensor noise RMS per axis",
)
#: One run of the job: ``run(noise_nm) -> (axial RMS (x, y) nm, contour RMS nm)``.
JobRunner = Callable[[tuple[float, float]], tuple[tuple[float, float], float]]


@dataclass(frozen=True, kw_only=True)
class NoiseFit:
    """Result of `fit_noise`.

    Attributes
    ----------
    noise_rms_nm : tuple of float
        Fitted sensor noise (x, y), nm.
    axial_rms_nm : tuple of float
        Axial RMS of the job with that noise (x, y), nm (seed 001: 485.8, 885.8).
    contour_rms_nm : float
        Contour RMS of the same run, nm: the prediction (seed 001: 769.5 nm).
    runs : int
        Job runs used.
    history : tuple of tuple
        ``(noise_x, noise_y, axial_x, axial_y)`` per run, nm.
    """

    noise_rms_nm: tuple[float, float]
    axial_rms_nm: tuple[float, float]
    contour_rms_nm: float
    runs: int
    history: tuple[tuple[float, float, float, float], ...]

    @property
    def axial_error_pct(self) -> tuple[float, float]:
        """Axial RMS against the seed's, %, per axis."""
        return tuple(100.0 * (a / t - 1.0) for a, t in zip(self.axial_rms_nm, _TARGET, strict=True))  # type: ignore[return-value]

    @property
    def contour_error_pct(self) -> float:
        """Contour RMS (the prediction) against the seed's 769.5 nm, %."""
        return 100.0 * (self.contour_rms_nm / SEED_CONTOUR_RMS_NM - 1.0)


def fit_sensor_noise(
    run: JobRunner,
    start_nm: tuple[float, float],
    *,
    rtol: float = 0.01,
    max_runs: int = 8,
    progress: Callable[[int, tuple[float, float], tuple[float, float]], None] | None = None,
) -> NoiseFit:
    """Fit the sensor noise per axis so the job's axial RMS meets seed 001 §4.2.

    Parameters
    ----------
    run : callable
        ``run((σx, σy)) -> ((axial x, axial y), contour)``: the job run with that sensor
        noise, nm in and out.
    start_nm : tuple of float
        Noise of the first run (x, y), nm (the twin's).
    rtol : float
        Stop when both axial RMS are within this relative error of the seed's, in
        (0, 0.2] (default 1 %, inside the issue's ±5 %).
    max_runs : int
        Most job runs, >= 2.
    progress : callable, optional
        ``progress(run, noise_nm, axial_nm)`` after each run.

    Returns
    -------
    NoiseFit

    Raises
    ------
    ValueError
        When the axial RMS does not reach the seed's within ``max_runs`` (the message gives
        the last values), or the errors without noise already exceed the seed's (no noise
        can fit).
    """
    tol = check_in_range("rtol", rtol, 0.0, 0.2, low_closed=False)
    check_int("max_runs", max_runs, 2, "runs")
    sigma = [float(start_nm[0]), float(start_nm[1])]  # nm
    hist: list[tuple[float, float, float, float]] = []

    def run_once(s: list[float]) -> tuple[tuple[float, float], float]:
        ax, contour = run((s[0], s[1]))
        ax = (float(ax[0]), float(ax[1]))
        hist.append((s[0], s[1], ax[0], ax[1]))
        if progress:
            progress(len(hist), (s[0], s[1]), ax)
        return ax, float(contour)

    axial, contour = run_once(sigma)
    prev: tuple[list[float], tuple[float, float]] | None = None
    while not all(abs(a / t - 1.0) <= tol for a, t in zip(axial, _TARGET, strict=True)):
        if len(hist) >= max_runs:
            raise ValueError(
                f"noise fit did not converge in {max_runs} runs: noise {sigma[0]:.1f} / "
                f"{sigma[1]:.1f} nm gives axial RMS {axial[0]:.1f} / {axial[1]:.1f} nm "
                f"(seed {_TARGET[0]} / {_TARGET[1]}); raise max_runs or rtol"
            )
        new = []
        for a in range(2):
            t2, s2, a2 = _TARGET[a] ** 2, sigma[a] ** 2, axial[a] ** 2
            if prev is None or prev[1][a] == axial[a]:
                s2_next = s2 * t2 / a2  # RMS² ∝ σ² to start
            else:
                ps2, pa2 = prev[0][a] ** 2, prev[1][a] ** 2
                g = (a2 - pa2) / (s2 - ps2) if s2 != ps2 else a2 / s2
                s2_next = s2 + (t2 - a2) / g if g > 0 else s2 * t2 / a2
            if s2_next <= 0:
                raise ValueError(
                    f"axis {'xy'[a]}: the error without noise already exceeds the seed's "
                    f"{_TARGET[a]} nm axial RMS; no sensor noise can fit it (lower the "
                    "disturbance or retune the controller)"
                )
            new.append(math.sqrt(s2_next))
        prev = (sigma, axial)
        sigma = new
        axial, contour = run_once(sigma)
    return NoiseFit(
        noise_rms_nm=(sigma[0], sigma[1]),
        axial_rms_nm=axial,
        contour_rms_nm=contour,
        runs=len(hist),
        history=tuple(hist),
    )


def fit_noise(
    config: JobConfig | None = None,
    *,
    rtol: float = 0.01,
    max_runs: int = 8,
    progress: Callable[[int, tuple[float, float], tuple[float, float]], None] | None = None,
) -> NoiseFit:
    """Fit ``noise_rms_mm`` per axis so the job's axial RMS meets seed 001 §4.2.

    Parameters
    ----------
    config : JobConfig, optional
        The job (default `JobConfig()`); its twin's noise is the start and must be on.
    rtol, max_runs, progress
        As `fit_sensor_noise`.

    Returns
    -------
    NoiseFit

    Raises
    ------
    ValueError
        When the noise is off in ``config``, or as `fit_sensor_noise`.
    """
    cfg = config or JobConfig()
    if not cfg.twin.noise:
        raise ValueError("fit_noise needs the sensor noise on ([twin] noise = true)")

    def run(s: tuple[float, float]) -> tuple[tuple[float, float], float]:
        tw = dataclasses.replace(cfg.twin, noise_rms_mm=(s[0] * 1e-6, s[1] * 1e-6))
        m = run_job(dataclasses.replace(cfg, twin=tw)).metrics()
        return (float(m.axial_rms_nm[0]), float(m.axial_rms_nm[1])), float(m.contour_rms_nm)

    start = [float(v) * 1e6 for v in make_twin(cfg.twin).noise_rms_mm()]  # nm
    return fit_sensor_noise(
        run, (start[0], start[1]), rtol=rtol, max_runs=max_runs, progress=progress
    )


def write_noise(fit: NoiseFit, path: str | Path, *, source: str | Path | None = None) -> Path:
    """Write a twin data file with the fitted noise (atomically).

    Parameters
    ----------
    fit : NoiseFit
        The fit.
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to copy (default the packaged ``nanomanipulator_twin.toml``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        If the file does not hold ``noise_rms_mm`` and its source in ``[axes.x]`` and
        ``[axes.y]`` (`microfab.plants.sourced_toml.update_sourced`); nothing is written.
    """
    updates = {
        (f"axes.{ax}", "noise_rms_mm"): (
            float(f"{fit.noise_rms_nm[a] * 1e-6:.4e}"),
            "calibrated: `microfab calibrate nanomanipulator` fits the sensor noise so that "
            f"the four-circle job's axial RMS is seed 001 §4.2's {_TARGET[a]} nm ({ax}); got "
            f"{fit.axial_rms_nm[a]:.1f} nm in {fit.runs} runs",
        )
        for a, ax in enumerate("xy")
    }
    out = update_sourced(source, "nanomanipulator_twin.toml", updates)
    p = Path(path)
    atomic_write_text(p, out)
    return p
