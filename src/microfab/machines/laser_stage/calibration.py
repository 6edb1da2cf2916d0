"""``microfab calibrate laser``: fit the stage twin's disturbance scale to seed 004 Fig. 3's peak.

Seed 004 §IV.A (Fig. 3): on the 30 µm circle the axis errors "are generally lower than
0.5 µm, reaching 0.8 µm at the peak points". The twin's friction, cogging and cable
forces are assumed; one free magnitude, ``disturbance_scale`` (it multiplies all three),
is fitted here so that the larger of the two axes' peak errors of the Fig. 3 run (preview
+ DOB, `laser_stage.play_contour` with `FIG3_JOB`'s settings: 1 mm/s, three laps, noise
on; axis error ``r − y`` over the full-speed laps, `laser_stage.ContourPlay.axis_errors`,
the same figures a contour run reports) is 0.8 µm. The peak grows about linearly with
the scale (the disturbance dominates the noise), so the secant method on ``(scale,
peak)`` converges in a few runs. The share of
samples within ±0.5 µm is not fitted: it is the check (issue 15: ≥ 95 %).

`write_scale` stores the fitted value in a copy of the twin's data file (or the packaged
one) with a source line naming this command.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from microfab.core.provenance import Calibration, quantity
from microfab.core.validate import check_in_range, check_int
from microfab.io.atomic import atomic_write_text
from microfab.machines.laser_stage.machine import ContourJob, ControlSettings, play_contour, twin
from microfab.measure.contour import AxisErrors
from microfab.plants.sourced_toml import update_sourced

__all__ = [
    "CALIBRATION",
    "FIG3_JOB",
    "FIG3_PEAK_QUANTITY",
    "DisturbanceFit",
    "fit_disturbance_scale",
    "write_scale",
]

FIG3_PEAK_ERROR_M = 0.8e-6  # seed 004 §IV.A: "reaching 0.8 µm at the peak points" (paper.py)

#: The Fig. 3 run the fit uses: the seed's 30 µm circle under preview + DOB (the motion
#: experiment of §IV.A has no contour compensator), at 1 mm/s (assumed), noise on.
FIG3_JOB = ContourJob(control=ControlSettings(law="preview-dob"))

#: The published number the fit targets (`microfab.core.provenance`).
FIG3_PEAK_QUANTITY = quantity("004", "§IV.A, Fig. 3", "peak error")

#: What this calibration fits, for the rows' input / fitted / predicted labels.
CALIBRATION = Calibration(
    command="microfab calibrate laser",
    data_file="lmw_stage.toml",
    targets=frozenset({FIG3_PEAK_QUANTITY}),
    what="disturbance scale of friction, cogging and cable",
)


@dataclass(frozen=True, kw_only=True)
class DisturbanceFit:
    """Result of `fit_disturbance_scale`.

    Attributes
    ----------
    scale : float
        Fitted ``disturbance_scale``.
    peak_um : tuple of float
        Peak |error| per axis with it, µm (seed: 0.8 at the peaks; the larger is fitted).
    fraction_below : tuple of float
        Share of samples within ±0.5 µm per axis: the check (seed: "generally").
    runs : int
        Runs used.
    history : tuple of tuple
        ``(scale, larger peak µm)`` per run.
    """

    scale: float
    peak_um: tuple[float, float]
    fraction_below: tuple[float, float]
    runs: int
    history: tuple[tuple[float, float], ...]


def fit_disturbance_scale(
    job: ContourJob = FIG3_JOB,
    *,
    rtol: float = 0.02,
    max_runs: int = 8,
    progress: Callable[[int, float, float], None] | None = None,
) -> DisturbanceFit:
    """Fit ``disturbance_scale`` so the larger axis peak error of ``job`` is 0.8 µm.

    Parameters
    ----------
    job : ContourJob
        The run (default `FIG3_JOB`); its twin's scale (or the data file's) is the start.
    rtol : float
        Stop within this relative error of 0.8 µm, in (0, 0.2].
    max_runs : int
        Most runs, >= 2.
    progress : callable, optional
        ``progress(run, scale, peak_um)`` after each run.

    Raises
    ------
    ValueError
        When the fit does not converge in ``max_runs`` (the message gives the last
        values), or the error without disturbance already exceeds 0.8 µm.
    """
    tol = check_in_range("rtol", rtol, 0.0, 0.2, low_closed=False)
    check_int("max_runs", max_runs, 2, "runs")
    target = FIG3_PEAK_ERROR_M * 1e6
    scale = job.twin.disturbance_scale or twin(job.twin).config.disturbance_scale
    hist: list[tuple[float, float]] = []
    last = None

    def run(s: float) -> tuple[float, AxisErrors]:
        e = play_contour(
            job.with_(twin=dataclasses.replace(job.twin, disturbance_scale=s))
        ).axis_errors()  # the band: seed 004's 0.5 µm (`microfab.measure.contour.AXIS_BAND_M`)
        peak = max(e.peak_m) * 1e6
        hist.append((s, peak))
        if progress:
            progress(len(hist), s, peak)
        return peak, e

    peak, last = run(scale)
    prev: tuple[float, float] | None = None
    while abs(peak / target - 1.0) > tol:
        if len(hist) >= max_runs:
            raise ValueError(
                f"disturbance fit did not converge in {max_runs} runs: scale {scale:.4g} "
                f"gives a peak of {peak:.3f} µm (seed {target} µm); raise max_runs or rtol"
            )
        if prev is None or prev[1] == peak or prev[0] == scale:
            nxt = scale * target / peak  # peak ∝ scale to start
        else:
            g = (peak - prev[1]) / (scale - prev[0])
            nxt = scale + (target - peak) / g if g > 0 else scale * target / peak
        if nxt <= 0:
            raise ValueError(
                "the error without disturbance already exceeds the seed's 0.8 µm peak; no "
                "disturbance scale can fit it (lower the noise or retune the controller)"
            )
        prev = (scale, peak)
        scale = nxt
        peak, last = run(scale)
    assert last is not None
    return DisturbanceFit(
        scale=scale,
        peak_um=tuple(v * 1e6 for v in last.peak_m),  # type: ignore[arg-type]
        fraction_below=last.fraction_below,
        runs=len(hist),
        history=tuple(hist),
    )


def write_scale(fit: DisturbanceFit, path: str | Path, *, source: str | Path | None = None) -> Path:
    """Write a twin data file with the fitted ``disturbance_scale`` (atomically).

    Parameters
    ----------
    fit : DisturbanceFit
        The fit.
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to copy (default the packaged ``lmw_stage.toml``).

    Raises
    ------
    ValueError
        If the file does not hold ``[disturbance] disturbance_scale`` and its source
        (`microfab.plants.sourced_toml.update_sourced`); nothing is written then.
    """
    frac = " / ".join(f"{v * 100:.1f}" for v in fit.fraction_below)
    src = (
        "calibrated: `microfab calibrate laser` fits it so that the larger axis peak error "
        "of seed 004 Fig. 3's run (30 um circle, 1 mm/s, preview + DOB) is the seed's 0.8 um; "
        f"got {max(fit.peak_um):.3f} um in {fit.runs} runs (check, not fitted: {frac} % of "
        "samples within 0.5 um, x / y)"
    )
    scale = float(f"{fit.scale:.4g}")
    out = update_sourced(
        source, "lmw_stage.toml", {("disturbance", "disturbance_scale"): (scale, src)}
    )
    p = Path(path)
    atomic_write_text(p, out)
    return p
