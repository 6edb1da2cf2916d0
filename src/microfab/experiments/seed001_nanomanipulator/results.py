"""Results of the seed001_nanomanipulator job kind: what its run returns and its report reads.

The job module (`job.py`) builds and returns them; the report module reads them and
never imports the job module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.machines.nanomanipulator.cure import CircleCure
from microfab.machines.nanomanipulator.job import JobConfig, JobRun
from microfab.measure.circle_tracking import TrackingMetrics
from microfab.report.tables import DASH, Table, versus

__all__ = ["NanomanipulatorResult", "cure_table", "is_seed_setup"]


def _um(v: float) -> str:
    return DASH if not math.isfinite(v) else f"{v * 1e6:.2f}"


def is_seed_setup(config: JobConfig) -> bool:
    """Whether a job runs seed 001 §4.2's set-up, the one its numbers are for.

    Four 0.15 mm circles in a 0.5 mm field (§4.2) on the full twin (§4.1 terms, ``d(t)``
    and the sensor noise of the data file, which `microfab calibrate nanomanipulator`
    fits to this set-up). Any other job prints ours alone.
    """
    p, t = config.pattern, config.twin
    return (
        p.n_circles == paper.N_CIRCLES
        and p.diameter_mm == paper.CIRCLE_DIAMETER_MM
        and p.field_mm == paper.FIELD_MM
        and t.nonlinear
        and t.disturbance
        and t.noise
        and t.noise_rms_mm is None
        and t.disturbance_mm_s2 is None
        and t.params_file is None
    )


def cure_table(cures: tuple[CircleCure, ...], config: JobConfig) -> Table:
    """Cured line per circle and print: width, closure, gap, closing width, offset.

    The seed's line width is set beside ours only for its set-up (`is_seed_setup`).
    """
    rows = []
    nominal = paper.LINE_WIDTH_UM
    seed = is_seed_setup(config)
    for c in cures:
        for name, pr in c.prints.items():
            lp = pr.loop
            off = lp.widths.offset_m[lp.widths.width_m > 0]
            rows.append(
                (
                    f"{c.circle + 1}",
                    name,
                    versus(lp.mean_width_m * 1e6, nominal, "{:.2f}".format)
                    if seed
                    else f"{lp.mean_width_m * 1e6:.2f}",
                    f"{_um(lp.min_width_m)}-{_um(lp.max_width_m)}",
                    "yes" if lp.closed else "no",
                    _um(lp.gap_m),
                    _um(lp.closing_width_m),
                    _um(float(np.sqrt(np.mean(off**2)))) if off.size else DASH,
                )
            )
    w = config.laser.warmup_s
    speed = math.pi * config.pattern.diameter_mm / config.pattern.period_s  # mm/s
    head = "Seed: lines of about {} µm, some circles not closed (Fig. 14), blamed on the laser's "
    return Table(
        title="Cured lines (seed 001 Figs. 14-15), " + ("ours / seed" if seed else "ours alone"),
        columns=(
            "circle",
            "print",
            "mean width [µm]",
            "width range [µm]",
            "closed",
            "gap [µm]",
            "closing width [µm]",
            "line offset RMS [µm]",
        ),
        rows=rows,
        note=(head.format(nominal) + "warm-up. " if seed else "")
        + f"Here the warm-up is {w * 1e3:g} ms (assumed): at "
        f"{speed:.3f} mm/s it leaves the gated loop {speed * w * 1e3:.2f} µm short of its "
        "start less the cured line's overlap; 'compensated' advances the switch-on by the "
        "warm-up, 'ungated' exposes the first loop (unconverged). Offset: RMS distance of "
        "the line's centre from the intended circle.",
    )


@dataclass(frozen=True, kw_only=True, eq=False)
class NanomanipulatorResult:
    """A finished job: the run, its metrics and its cured lines."""

    run: JobRun
    metrics: TrackingMetrics
    cures: tuple[CircleCure, ...]

    def comparison(self) -> tuple[Table, ...]:
        """Tracking beside seed 001 §4.2, and the cured lines."""
        from microfab.report.circle_tracking import tracking_table  # draws: loaded on use

        seed = is_seed_setup(self.run.config)
        return (
            tracking_table(self.metrics, seed=seed),
            cure_table(self.cures, self.run.config),
        )

    def failures(self) -> tuple[str, ...]:
        """Circles whose gate never opened."""
        return tuple(
            f"circle {c.index + 1}: the gate never opened (error never under the threshold)"
            for c in self.run.circles
            if c.gate_opened is None
        )

    def summary(self) -> dict[str, Any]:
        """Metrics, gate, cured lines and the seed's numbers, JSON-ready."""
        cures = [
            {
                "circle": c.circle + 1,
                "threshold_j_m2": c.threshold_j_m2,
                **{
                    name: {
                        "mean_width_um": p.loop.mean_width_m * 1e6,
                        "min_width_um": p.loop.min_width_m * 1e6,
                        "max_width_um": p.loop.max_width_m * 1e6,
                        "closed": p.loop.closed,
                        "gap_um": p.loop.gap_m * 1e6,
                        "closing_width_um": p.loop.closing_width_m * 1e6,
                    }
                    for name, p in c.prints.items()
                },
            }
            for c in self.cures
        ]
        return {
            "tracking": self.metrics.summary(),
            "cured_lines": cures,
            "noise_rms_nm": (self.run.noise_rms_mm * 1e6).tolist(),
            "seed": (
                {"line_width_um": paper.LINE_WIDTH_UM} if is_seed_setup(self.run.config) else None
            ),
            "failures": list(self.failures()),
        }
