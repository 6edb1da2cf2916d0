"""What every ``microfab calibrate <machine>`` on the calibration core shares.

The options (budget, seed, workers, run folder, fresh start, twin file, JSON report), the
run folder (`microfab.io.runstore`: the memo of evaluations and the result live there, so
an interrupted calibration resumes and a folder of another problem is refused), the
progress line and the printed tables (per target: role, paper, model, residual, met,
pinned by; per parameter: value, bounds, at a bound; the conflict, if any).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from microfab.cli._kit import check_outputs, console, fail, print_table, status
from microfab.cli._options import integer

if TYPE_CHECKING:
    from microfab.calibrate import CalibrationProblem, CalibrationResult

__all__ = [
    "BudgetOption",
    "ConflictBudgetOption",
    "FreshOption",
    "JsonOption",
    "OutOption",
    "SeedOption",
    "WorkersOption",
    "print_result",
    "run_calibration",
]

#: Most evaluations one calibration may ask for (assumed: 10^5 model runs is days of work
#: for the slowest twin; a larger number is a typo).
MAX_BUDGET = 100_000
#: Most worker processes (assumed: far above the cores of one workstation).
MAX_WORKERS = 256

BudgetOption = Annotated[
    int | None,
    integer(
        "--budget",
        help="Model evaluations the search may ask for (default: the machine's).",
        low=5,
        high=MAX_BUDGET,
    ),
]
ConflictBudgetOption = Annotated[
    int | None,
    integer(
        "--conflict-budget",
        help="Evaluations of the conflict sweep when a fit target is unmet (default: "
        "--budget; 0: no sweep).",
        low=0,
        high=MAX_BUDGET,
    ),
]
SeedOption = Annotated[int, integer("--seed", help="Seed of the global search.", low=0)]
WorkersOption = Annotated[
    int, integer("--workers", help="Evaluations run side by side.", low=1, high=MAX_WORKERS)
]
OutOption = Annotated[
    Path | None,
    typer.Option(
        "--out",
        help="Run folder: the memo of evaluations and calibration.json (resumes when rerun).",
    ),
]
FreshOption = Annotated[
    bool, typer.Option("--fresh", help="Move an earlier run in --out aside and start clean.")
]
JsonOption = Annotated[
    Path | None, typer.Option("--json", help="Write the calibration report as JSON here.")
]


def _fmt(x: float) -> str:
    return "nan" if x != x else f"{x:.4g}"


def print_result(result: CalibrationResult, title: str) -> None:
    """Print the per-target and per-parameter tables and the conflict, if any."""
    from microfab.report.tables import Table

    rows = [
        (
            t.name,
            t.role,
            t.shown,
            _fmt(t.model),
            t.unit,
            f"{t.residual:+.2f}",
            "yes" if t.met else "NO",
            ", ".join(t.pinned_by) or "-",
            t.source,
        )
        for t in result.targets
    ]
    print_table(
        Table(
            title=f"{title}: targets (r = (model - paper) / tolerance; met when |r| <= 1)",
            columns=("target", "role", "paper", "model", "unit", "r", "met", "pinned by", "source"),
            rows=rows,
            note="fit: chosen by the search; check: held back, predicted by the fitted twin",
        )
    )
    prow = [
        (
            p.name,
            _fmt(p.value),
            p.unit,
            f"[{p.low:.4g}, {p.high:.4g}]",
            p.at_bound or "-",
            p.source,
        )
        for p in result.parameters
    ]
    print_table(
        Table(
            title=f"{title}: free parameters",
            columns=("parameter", "value", "unit", "bounds", "at bound", "bounds from"),
            rows=prow,
        )
    )
    fits = [t for t in result.targets if t.role == "fit"]
    met = sum(t.met for t in fits)
    state = "converged" if result.converged else "NOT converged"
    console.print(
        f"{state}: {met} of {len(fits)} fit targets met (worst |r| {result.worst_fit:.3g}); "
        f"{result.requested} points asked, {result.evaluated} evaluated"
    )
    if result.conflict is not None:
        c = result.conflict
        console.print(f"conflict: {c.target_a} against {c.target_b}: {c.finding}")
        for ra, rb in c.front:
            console.print(f"  front: |r| {ra:.3g} / {rb:.3g}")


def run_calibration(
    problem: CalibrationProblem,
    *,
    title: str,
    budget: int,
    seed: int,
    workers: int,
    out: Path | None,
    fresh: bool,
    json_out: Path | None,
    write: Path | None,
    write_twin: Callable[[CalibrationResult, Path], Path],
    inputs: dict[str, Path | None] | None = None,
    conflict_budget: int | None = None,
) -> CalibrationResult:
    """Run a calibration for a command: checks, run folder, progress, tables, files.

    Parameters
    ----------
    problem : CalibrationProblem
        The machine's problem.
    title : str
        The tables' title (``"seed 004 stage twin"``).
    budget, seed, workers : int
        As `microfab.calibrate.calibrate`.
    out : Path or None
        Run folder for the memo and ``calibration.json`` (resumable; refused when it holds
        another problem's run, unless ``fresh``).
    fresh : bool
        Move an earlier run in ``out`` aside first.
    json_out, write : Path or None
        The report as JSON; the twin data file with the calibrated values.
    write_twin : callable
        ``write_twin(result, path)``: the machine's writer of its twin file.
    inputs : dict, optional
        Input files by option (refused as outputs).
    conflict_budget : int, optional
        As `microfab.calibrate.calibrate` (default ``budget``).

    Returns
    -------
    CalibrationResult
    """
    check_outputs(
        files={"--write": write, "--json": json_out}, folders={"--out": out}, inputs=inputs or {}
    )
    if fresh and out is None:
        fail("--fresh needs --out: it starts the run folder clean")
    from microfab.calibrate import Progress, calibrate
    from microfab.io.atomic import atomic_write_text
    from microfab.io.runstore import RunRefusedError, open_run

    def go(memo: Path | None) -> CalibrationResult:
        with status("calibrating") as show:

            def on(p: Progress) -> None:
                show(
                    f"{p.phase}: {p.requested} points, {p.evaluated} evaluated, "
                    f"best worst |r| {p.best_worst:.3g}"
                )

            return calibrate(
                problem,
                budget=budget,
                seed=seed,
                workers=workers,
                on_progress=on,
                memo_path=memo,
                conflict_budget=conflict_budget,
            )

    try:
        if out is None:
            result = go(None)
        else:
            settings = {"calibration": title, "problem": problem.fingerprint(), "seed": seed}
            with open_run(
                out,
                settings,
                fresh=fresh,
                fresh_hint="add --fresh",
                other_hint="give another --out",
            ):
                result = go(out / "memo.json")
                atomic_write_text(out / "calibration.json", result.to_json() + "\n")
    except (RunRefusedError, ValueError, OSError) as exc:
        fail(str(exc))
    print_result(result, title)
    if json_out is not None:
        atomic_write_text(json_out, result.to_json() + "\n")
        console.print(f"wrote {json_out}")
    if write is not None:
        try:
            write_twin(result, write)
        except ValueError as exc:
            fail(str(exc))
        console.print(f"wrote {write}")
    if out is not None:
        console.print(f"run folder {os.fspath(out)}")
    return result
