"""``microfab stage excite``: command files for the black-box XY stage (seed 002 §III-C).

Writes excitation runs (`microfab.identify.excitation`) as command files to play on a real
machine: one file per run (``time``, ``input_x``, ``input_y``, m, 10 kHz, from rest at the
origin back to rest there) and an index ``runs.json``. Every run passes
``check_trajectory`` against seed 002 Table I before anything is written; a refusal is one
``error:`` line, exit code 2, and nothing is written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from microfab.cli._kit import check_option, check_output_path, console, fail, print_table
from microfab.report.tables import Table

__all__ = ["stage_app"]

stage_app = typer.Typer(
    no_args_is_help=True,
    help="The black-box XY stage (seed 002): command files to run on a real machine.",
)

_KINDS = ("random", "shapes", "prbs", "chirp")
_FORMATS = ("csv", "h5", "mat")
#: Default total length per kind, s: random 600 s (seed 002 §III-C 1: 6×10⁶ points at
#: 10 kHz); shapes 210 s (40 % of the ANN set's 525 s, §III-C 2); PRBS and chirp 120 s
#: (assumed: 60 s per amplitude or axis, enough to show they are inadequate).
_DEFAULT_S = {"random": 600.0, "shapes": 210.0, "prbs": 120.0, "chirp": 120.0}
_FADE_S = 1.0  # chirp fade in / out, s (chirp_runs' default), at most a quarter of a sweep


@stage_app.command("excite")
def excite_cmd(
    out: Annotated[Path, typer.Option("--out", help="Directory for the run files and runs.json.")],
    kind: Annotated[
        str,
        typer.Option(
            help="random (the linear model's data), shapes (circles, polygons, spirals at "
            "random constant speeds), prbs, chirp (shown inadequate by the seed)."
        ),
    ] = "random",
    duration: Annotated[
        float | None,
        typer.Option(
            help="Total length of all runs [s] (default: random 600, shapes 210, prbs and "
            "chirp 120; prbs splits it over its two amplitudes, chirp over x then y, each "
            "faded in and out over min(1 s, a quarter of it))."
        ),
    ] = None,
    amax: Annotated[
        float, typer.Option(help="Largest acceleration [m/s²] (seed §III-D: 5; Table I: 40).")
    ] = 5.0,
    seed: Annotated[int, typer.Option(min=0, help="Seed; the same seed gives the same runs.")] = 0,
    fmt: Annotated[str, typer.Option("--format", help="File format: csv, h5 or mat.")] = "csv",
) -> None:
    """Write excitation runs for the XY stage as command files (seed 002 §III-C).

    Each run starts at rest at the origin and ends at rest there, sampled at 10 kHz (the
    stage's loop rate, Table I), and passes the workspace, 1.5 m/s and --amax checks of
    Table I before anything is written. Play each file on the machine, record time,
    input_x, input_y, output_x, output_y (m), then fit with ``microfab identify linear``.
    """
    check_output_path("--out", out, kind="folder")
    from microfab.identify import excitation as ex

    if kind not in _KINDS:
        fail(f"--kind must be one of {', '.join(_KINDS)}, got {kind!r}")
    if fmt not in _FORMATS:
        fail(f"--format must be one of {', '.join(_FORMATS)}, got {fmt!r}")
    total = _DEFAULT_S[kind] if duration is None else duration
    check_option("--duration", total, "s", high=ex.MAX_TOTAL_S)
    check_option("--amax", amax, "m/s²", high=ex.LIMITS.acceleration[0])
    if out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a directory")
    if (out / ex.INDEX_FILE).exists():
        fail(f"{out} already holds {ex.INDEX_FILE}: remove it or give another --out")
    try:
        if kind == "random":
            runs = ex.random_runs(total, a_max=amax, seed=seed)
        elif kind == "shapes":
            runs = ex.ann_dataset(total, random_share=0.0, seed=seed, a_max=amax)
        elif kind == "prbs":
            amps = (1e-4, 1e-3)  # prbs_runs' default amplitudes, m
            runs = ex.prbs_runs(total / len(amps), amplitudes=amps, a_max=amax, seed=seed)
        else:
            per_axis = total / 2  # x, then y
            runs = ex.chirp_runs(per_axis, a_max=amax, fade_s=min(_FADE_S, per_axis / 4))
        index = ex.write_runs(runs, out, fmt=fmt)
    except ValueError as exc:  # LimitViolation included
        fail(f"{kind} runs: {exc}")
    rows = []
    for r in runs:
        pk = r.peaks()
        v, a = pk["velocity_m_s"], pk["acceleration_m_s2"]
        rows.append(
            (r.name, f"{r.n_samples}", f"{r.duration:.3f}", f"{v[0]:.3g} / {v[1]:.3g}",
             f"{a[0]:.3g} / {a[1]:.3g}")
        )  # fmt: skip
    n = sum(r.n_samples for r in runs)
    print_table(
        Table(
            title=f"{len(runs)} {kind} runs, {n} samples ({n * ex.DT:.1f} s) at 10 kHz",
            columns=("run", "samples", "s", "peak |v| x / y [m/s]", "peak |a| x / y [m/s²]"),
            rows=rows,
            note="each from rest at the origin back to rest there; within seed 002 Table I",
        )
    )
    console.print(f"wrote {len(runs)} files and {index}", highlight=False)
