"""Results of the seed003_slm job kind: what its run returns and its report reads.

The job module (`job.py`) builds and returns them; the report module reads them and
never imports the job module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from microfab.experiments.seed003_slm.tables import scan_table, seed_table
from microfab.machines.slm_galvo.shapers import ShaperComparison
from microfab.machines.slm_galvo.shaping import ShapingRun, ShapingSettings
from microfab.process.slm.build import BuildResult, BuildSettings
from microfab.report.slm_tables import build_table, comparison_table
from microfab.report.tables import Table

__all__ = ["ShapingJob", "ShapingResult"]


@dataclass(frozen=True, kw_only=True)
class ShapingJob:
    """An ``slm-shaping`` job: the run, the comparison switch, the build (or none)."""

    run: ShapingSettings
    compare: bool = True
    build: BuildSettings | None = None
    workers: int = 2
    scheduler: str | None = None


@dataclass(frozen=True, kw_only=True, eq=False)
class ShapingResult:
    """A finished job: the run, the shaper comparisons, the build (if any)."""

    config: ShapingJob
    run: ShapingRun
    comparisons: tuple[ShaperComparison, ...] = ()
    build: BuildResult | None = None
    errors: tuple[str, ...] = ()

    def comparison(self) -> tuple[Table, ...]:
        """Seed beside ours, the layer's scan times, the shaper comparisons, the build."""
        tables = [seed_table(self.run), scan_table(self.run)]
        tables += [comparison_table(c) for c in self.comparisons]
        if self.build is not None:
            tables.append(build_table(self.build))
        return tuple(tables)

    def failures(self) -> tuple[str, ...]:
        """Parts that failed (the rest ran): comparison or build errors, failed layers."""
        failed = tuple(self.build.failed) if self.build is not None else ()
        return self.errors + failed

    def summary(self) -> dict[str, Any]:
        """The numbers of the tables, JSON-ready."""
        out = self.run.summary()
        out["comparisons"] = [c.summary() for c in self.comparisons]
        if self.build is not None:
            out["build"] = self.build.summary()
        out["failures"] = list(self.failures())
        return out
