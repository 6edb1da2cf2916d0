"""The sensor-noise fit of seed 001 §4.2 on the nanomanipulator job.

`fit_noise` runs the job (`run.run_job`, defaults of `run.JobConfig` unless given) with
the noise the fit asks for and hands it to the machine's fit
(`microfab.machines.nanomanipulator_calibration.fit_sensor_noise`: the secant on the axial
RMS, targets seed 001 §4.2 / Fig. 13a); `write_noise` there stores the result.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from microfab.experiments.seed001_nanomanipulator.run import JobConfig, make_twin, run_job
from microfab.machines.nanomanipulator_calibration import NoiseFit, fit_sensor_noise

__all__ = ["fit_noise"]


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
