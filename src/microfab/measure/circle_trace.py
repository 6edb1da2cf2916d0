"""Seed 001 metrics of a measured trace (``microfab nanomanipulator analyze``).

A trace is a file with the columns ``time, ref_x, ref_y, x, y, laser`` (s, mm, mm, 0/1;
`microfab.io.xy_trace`) recorded over a whole job of the circle-field pattern (seed 001
§4.2): from the stage at rest at the field centre, through every circle, to the end of
the last pause. Where the circles lie in it comes from the pattern
(`microfab.trajectory.circle_pattern.PatternConfig`), whose reference the trace must
follow sample by sample (`check_reference`); the metrics are
`microfab.measure.circle_tracking.tracking_metrics`; the figures and the page are
`microfab.report.circle_tracking` (`write_analysis`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from microfab.io.job import JobFileError, Key, parse_section, read_job
from microfab.io.xy_trace import (
    REF_TOL_MM,
    MeasuredTrace,
    largest_deviation,
    read_measured,
)
from microfab.measure.circle_tracking import TrackingMetrics, pattern_metrics
from microfab.trajectory.circle_pattern import (
    PatternConfig,
    PatternReference,
    pattern_reference,
)

__all__ = [
    "PATTERN_KEYS",
    "Analysis",
    "analyze_trace",
    "check_reference",
    "pattern_from_job",
    "twin_sample_rate_hz",
]

#: The ``[pattern]`` section of a job file as `pattern_from_job` reads it (the keys of
#: `PatternConfig`, ranges checked again there).
PATTERN_KEYS = (
    Key(name="n_circles", type="int", default=PatternConfig.n_circles, low=1, unit="circles"),
    Key(name="diameter_mm", type="float", default=PatternConfig.diameter_mm, low=0, unit="mm"),
    Key(name="field_mm", type="float", default=PatternConfig.field_mm, low=0, unit="mm"),
    Key(name="period_s", type="float", default=PatternConfig.period_s, low=0, unit="s"),
    Key(name="periods", type="int", default=PatternConfig.periods, low=1, unit="periods"),
    Key(name="pause_s", type="float", default=PatternConfig.pause_s, low=0, unit="s"),
    Key(name="move_s", type="float", default=PatternConfig.move_s, low=0, unit="s"),
    Key(name="ramp_s", type="float", default=PatternConfig.ramp_s, low=0, unit="s"),
)


def twin_sample_rate_hz() -> float:
    """The twin's sample rate, Hz (``data/nanomanipulator_twin.toml`` [sampling], assumed)."""
    from microfab.plants.nanomanipulator import load_params

    return float(load_params().sample_rate_hz)


def pattern_from_job(path: str | Path) -> PatternConfig:
    """The pattern of a job file's ``[pattern]`` section (other sections are the kind's).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not TOML, an unknown key in ``[pattern]``, or a value of the wrong type or range.
    """
    job = read_job(path)
    body = job.sections.get("pattern", {})
    values = parse_section(body, PATTERN_KEYS, job.source, "pattern")
    try:
        return PatternConfig(**values)
    except ValueError as exc:
        raise JobFileError(f"{job.source} [pattern]: {exc}") from exc


@dataclass(frozen=True, kw_only=True, eq=False)
class Analysis:
    """A measured trace, the pattern it ran and its metrics.

    Attributes
    ----------
    trace : MeasuredTrace
        The checked trace (with the laser column).
    config : PatternConfig
        The pattern.
    pattern : PatternReference
        The pattern's reference at the trace's sample time.
    metrics : TrackingMetrics
        The seed 001 §4.2 metrics.
    """

    trace: MeasuredTrace
    config: PatternConfig
    pattern: PatternReference
    metrics: TrackingMetrics

    @property
    def laser(self) -> np.ndarray:
        """Laser on per sample, bool, shape (n,)."""
        assert self.trace.laser is not None  # read with laser=True
        return self.trace.laser

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the trace, its pattern and the metrics' summary."""
        return {
            "trace": str(self.trace.path),
            "samples": self.trace.n_samples,
            "sample_rate_hz": 1.0 / self.trace.dt,
            "pattern": dataclasses.asdict(self.config),
            "metrics": self.metrics.summary(),
        }


_PATTERN_HINT = (
    "--job, or --period, --periods, --circles, --diameter-mm, --field-mm, --pause-s, "
    "--move-s, --ramp-s"
)


def check_reference(trace: MeasuredTrace, pattern: PatternReference) -> None:
    """Refuse a trace whose reference does not follow the pattern's (to `REF_TOL_MM`).

    Raises
    ------
    ValueError
        One line: the lengths when they differ, else the largest deviation, its axis,
        time and sample, and how to fix it.
    """
    p = trace.path
    if trace.n_samples != pattern.n_samples:
        raise ValueError(
            f"{p}: holds {trace.n_samples} samples ({trace.n_samples * trace.dt:g} s), the "
            f"pattern {pattern.n_samples} ({pattern.n_samples * pattern.dt:g} s): give the "
            f"pattern the job ran ({_PATTERN_HINT}) and the whole job, from rest to rest"
        )
    dev, k, j = largest_deviation(trace.reference, pattern.position)
    if dev > REF_TOL_MM:
        raise ValueError(
            f"{p}: ref_{'xy'[j]} departs from the pattern by {dev * 1e3:.4g} µm at "
            f"t = {trace.time[k]:g} s (sample {k}; tolerance {REF_TOL_MM * 1e6:g} nm): the "
            f"trace does not follow the pattern; give the pattern the job ran ({_PATTERN_HINT})"
        )


def analyze_trace(
    path: str | Path, config: PatternConfig | None = None, *, sample_rate_hz: float | None = None
) -> Analysis:
    """Read a measured trace, check it against the pattern and compute the metrics.

    Parameters
    ----------
    path : str or Path
        The trace (module docstring).
    config : PatternConfig, optional
        The pattern the job ran (default `PatternConfig()`).
    sample_rate_hz : float, optional
        The pattern's sample rate, Hz (default the twin's, `twin_sample_rate_hz`).

    Returns
    -------
    Analysis

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        A bad trace (`microfab.io.xy_trace.read_measured`), a sample rate other than the
        pattern's, a period that is not a whole number of samples, or a reference that does
        not follow the pattern (`check_reference`).
    """
    cfg = PatternConfig() if config is None else config
    fs = twin_sample_rate_hz() if sample_rate_hz is None else float(sample_rate_hz)
    if not (math.isfinite(fs) and fs > 0):
        raise ValueError(f"the sample rate must be positive, got {fs:g} Hz")
    trace = read_measured(path, laser=True)
    if not math.isclose(1.0 / trace.dt, fs, rel_tol=1e-6):
        raise ValueError(
            f"{trace.path}: sampled at {1.0 / trace.dt:.6g} Hz, the pattern at {fs:.6g} Hz: "
            "record at the pattern's rate or give it with --sample-rate-hz"
        )
    pattern = pattern_reference(cfg, 1.0 / fs)
    check_reference(trace, pattern)
    assert trace.laser is not None
    metrics = pattern_metrics(pattern, trace.output, trace.laser, reference=trace.reference)
    return Analysis(trace=trace, config=cfg, pattern=pattern, metrics=metrics)
