"""``microfab stage``: the black-box XY stage (seed 002 §III-C) through files.

``stage excite`` writes excitation runs (`microfab.identify.excitation`) as command files
to play on a real machine: one file per run (``time``, ``input_x``, ``input_y``, m,
10 kHz, from rest at the origin back to rest there) and an index ``runs.json``. Every run
passes ``check_trajectory`` against seed 002 Table I before anything is written.

``stage play RUNS --out MEASURED`` plays those command files on the twin
(`microfab.machines.xy_stage.play_runs`: from rest, held 0.5 s, the 2 µm noise of eq. 3)
and writes what a real controller must record instead: per run, ``time``, ``input_x``,
``input_y``, ``output_x``, ``output_y`` (m) at the command's rate (a multiple of 400 Hz;
10 kHz), the file ``identify linear`` and ``identify ann`` read; and an index
``played.json`` (the twin's settings, per run the samples the set-point guard changed).

``stage score RUN --drawing OPT [--baseline RUN0]`` scores measured runs of the command
files ``microfab optimize`` wrote into ``OPT`` (``command.csv``, ``baseline.csv``) against
the drawing: seed 002 eqs. (16)-(18) at the 400 Hz instants, with the reference job's
scorer (`microfab.machines.xy_stage.score`), and the improvement over the baseline run.
``OPT/summary.json`` gives the drawing, its sizing and contour, ``M`` and each command
file's ``t_0``; each run is matched to the command file it played by its set-points.

A refusal is one ``error:`` line, exit code 2, and nothing is written; every file is
written whole (atomically), the index last.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import (
    check_outputs,
    console,
    fail,
    print_table,
    progress,
    read_trace_file,
)
from microfab.cli._options import choice, integer, number, refuse_unused
from microfab.experiments.seed002_stage.keys import (
    A_MAX,
    HOLD_S,
    MIN_RUN_S,
    RUNS_SEED,
    RUNS_TOTAL_S,
    TWIN_SEED,
)
from microfab.io.lock import hold_for_command
from microfab.report.tables import Table

__all__ = ["stage_app"]

stage_app = typer.Typer(
    no_args_is_help=True,
    help="The black-box XY stage (seed 002): command files to run on a real machine, and "
    "the same files played on the twin.",
)

_KINDS = ("random", "shapes", "prbs", "chirp")
_FORMATS = ("csv", "h5", "mat")
#: Default total length per kind, s: random 600 s (seed 002 §III-C 1: 6×10⁶ points at
#: 10 kHz); shapes 210 s (40 % of the ANN set's 525 s, §III-C 2); PRBS and chirp 120 s
#: (assumed: 60 s per amplitude or axis, enough to show they are inadequate).
_DEFAULT_S = {"random": 600.0, "shapes": 210.0, "prbs": 120.0, "chirp": 120.0}
_FADE_S = 1.0  # chirp fade in / out, s (chirp_runs' default), at most a quarter of a sweep
_SUFFIX = {"csv": ".csv", "h5": ".h5", "mat": ".mat"}
PLAYED_INDEX = "played.json"
#: Kinds whose --duration is split over two runs (prbs: two amplitudes; chirp: x, then y).
_SPLIT_IN_TWO = ("prbs", "chirp")


@stage_app.command("excite")
def excite_cmd(
    ctx: typer.Context,
    out: Annotated[Path, typer.Option("--out", help="Directory for the run files and runs.json.")],
    kind: Annotated[
        str,
        choice(
            choices=_KINDS,
            help="Excitation: random (the linear model's data), shapes (circles, polygons, "
            "spirals at random constant speeds), prbs, chirp (shown inadequate by the seed).",
        ),
    ] = "random",
    duration: Annotated[
        float | None,
        number(
            "--duration",
            key=RUNS_TOTAL_S,
            help="Total length of all runs (default: random 600 s, shapes 210 s, prbs and "
            "chirp 120 s; prbs splits it over its two amplitudes, chirp over x then y, each "
            "faded in and out over min(1 s, a quarter of it)).",
        ),
    ] = None,
    amax: Annotated[
        float,
        number("--amax", key=A_MAX, help="Largest acceleration (seed §III-D: 5; Table I: 40)."),
    ] = 5.0,
    seed: Annotated[
        int,
        integer(
            "--seed", key=RUNS_SEED, help="Seed; the same seed gives the same runs (not chirp)."
        ),
    ] = 0,
    fmt: Annotated[str, choice("--format", choices=_FORMATS, help="File format.")] = "csv",
) -> None:
    """Write excitation runs for the XY stage as command files (seed 002 §III-C).

    Each run starts at rest at the origin and ends at rest there, sampled at 10 kHz (the
    stage's loop rate, Table I), and passes the workspace, 1.5 m/s and --amax checks of
    Table I before anything is written. Play each file on the machine, record time,
    input_x, input_y, output_x, output_y (m), then fit with ``microfab identify linear``.
    """
    check_outputs(folders={"--out": out})
    hold_for_command(out, "--out", on_refused=fail)
    from microfab.identify import excitation as ex

    if kind == "chirp":
        refuse_unused(ctx, ["seed"], "with --kind chirp (the chirp runs are not random)")
    total = _DEFAULT_S[kind] if duration is None else duration
    if kind in _SPLIT_IN_TWO and total / 2 < MIN_RUN_S:
        fail(
            f"--duration {total:g} s with --kind {kind} makes two runs of {total / 2:g} s; "
            f"each must be at least {MIN_RUN_S:g} s (the identification reads 500 ms of "
            f"history): give --duration {2 * MIN_RUN_S:g} or more"
        )
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


_RUNS_HELP = (
    "Excitation runs to play: a folder written by `stage excite` (its runs.json index, "
    "digests checked) or command files (.csv, .mat, .h5: time [s], input_x, input_y [m], "
    "at a multiple of 400 Hz, within seed 002 Table I)."
)


@stage_app.command("play")
def play_cmd(
    ctx: typer.Context,
    runs: Annotated[list[Path], typer.Argument(help=_RUNS_HELP)],
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the measured runs and played.json.")
    ],
    seed: Annotated[
        int,
        integer(
            "--seed",
            key=TWIN_SEED,
            help="Noise seed (run k gets seed + k); the same seed, the same files.",
        ),
    ] = 0,
    noise: Annotated[
        bool,
        typer.Option("--noise/--no-noise", help="The twin's 2 µm encoder noise (seed 002 eq. 3)."),
    ] = True,
    hold: Annotated[
        float,
        number(
            "--hold", key=HOLD_S, help="Hold of the last set-point after each run, recorded too."
        ),
    ] = 0.5,
    fmt: Annotated[
        str, choice("--format", choices=_FORMATS, help="File format of the measured runs.")
    ] = "csv",
) -> None:
    """Play excitation runs on the stage's twin and write the measured runs (seed 002 §III-C).

    Each run is played from rest at its first set-point, its last one held for --hold,
    and measured with the twin's 2 µm noise. Each measured file holds time, input_x,
    input_y, output_x, output_y (m) at the run's rate: what ``identify linear`` and
    ``identify ann`` read, and what a real stage's controller must record instead
    (README). Prints the samples of each run and the set-points the twin's guard changed.
    """
    check_outputs(folders={"--out": out}, inputs={"RUNS": runs})
    hold_for_command(out, "--out", on_refused=fail)
    if not noise:
        refuse_unused(ctx, ["seed"], "with --no-noise (the seed draws the noise)")
    if out.exists() and not out.is_dir():
        fail(f"--out {out} is a file; give a folder")
    if (out / PLAYED_INDEX).exists():
        fail(f"{out} already holds {PLAYED_INDEX}: remove it or give another --out")
    commands, sources = _read_commands(runs)
    files = [out / (c.name + _SUFFIX[fmt]) for c in commands]
    for f in files:  # an output file that is an input file (e.g. --out the runs' folder)
        check_outputs(files={"--out": f}, inputs={"RUNS": [*runs, *sources]})
    from microfab.identify.stage_runs import record_trace, stage_record
    from microfab.io.atomic import atomic_write_json
    from microfab.io.trace import write_trace
    from microfab.machines.xy_stage.machine import TwinSettings, play_runs

    settings = TwinSettings(seed=seed, noise=noise, hold_s=hold)
    n_total = sum(c.command.shape[0] for c in commands)
    with progress() as bar:
        task = bar.add_task(f"playing {len(commands)} runs on the twin", total=len(commands))
        played = play_runs(
            commands, settings, progress=lambda done, _n: bar.update(task, completed=done)
        )
    out.mkdir(parents=True, exist_ok=True)
    rows, entries = [], []
    for cmd, rec, lim, f in zip(commands, played.records, played.limited, files, strict=True):
        trace = record_trace(rec, cmd.dt)
        stage_record(trace, f.name)  # what identify reads: checked before it is written
        write_trace(trace, f)
        entries.append(
            {"name": cmd.name, "file": f.name, "command_samples": int(cmd.command.shape[0]),
             "samples": rec.n_samples, "rate_hz": 1.0 / cmd.dt, "guard_limited": lim,
             "noise_seed": seed + len(entries) if noise else None}
        )  # fmt: skip
        rows.append((cmd.name, f"{rec.n_samples}", f"{rec.n_samples * cmd.dt:.3f}", f"{lim}"))
    atomic_write_json(
        out / PLAYED_INDEX,
        {
            "what": "excitation runs played on the XY stage twin (seed 002): measured runs",
            "columns": ["time", "input_x", "input_y", "output_x", "output_y"],
            "unit": "m",
            "twin": {"seed": seed, "noise": noise, "hold_s": hold},
            "runs": entries,
        },
    )
    print_table(
        Table(
            title=f"{len(commands)} runs played on the twin, {n_total} command samples",
            columns=("run", "samples", "s", "set-points the guard changed"),
            rows=rows,
            note=f"each from rest, held {hold:g} s after its last set-point; noise "
            + (f"2 µm, seeds {seed}…{seed + len(commands) - 1}" if noise else "off"),
        )
    )
    if any(played.limited):
        console.print(
            "warning: the twin's set-point guard changed some set-points (outside seed 002 "
            "Table I); the files hold the commands as given",
            highlight=False,
        )
    console.print(f"wrote {len(files)} files and {out / PLAYED_INDEX}", highlight=False)


def _read_commands(paths: list[Path]) -> tuple[list[Any], list[Path]]:
    """The commands to play (`xy_stage.Command`), checked, and every file they came from."""
    from microfab.core.limits import LimitViolation, check_trajectory
    from microfab.identify import excitation as ex
    from microfab.identify.stage_runs import check_rate
    from microfab.machines.xy_stage.machine import Command, limits
    from microfab.trajectory.base import Trajectory

    commands: list[Any] = []
    sources: list[Path] = []
    for path in paths:
        if path.is_dir():
            if not (path / ex.INDEX_FILE).is_file():
                fail(
                    f"{path} holds no {ex.INDEX_FILE}: give the folder `stage excite` wrote, "
                    "or its run files"
                )
            try:
                read = ex.read_runs(path)
            except (OSError, ValueError, KeyError, TypeError) as exc:  # JSON errors included
                fail(f"{path / ex.INDEX_FILE}: cannot read the runs: {exc}")
            commands += [Command(name=r.name, dt=r.dt, command=r.command) for r in read]
            sources += [path / ex.INDEX_FILE, *sorted(path.iterdir())]
            continue
        tr = read_trace_file(path)
        missing = [c for c in ex.AXES if c not in tr.axes]
        if missing:
            fail(
                f"{path}: no column {missing[0]!r} (columns: time, {', '.join(tr.axes)}); a "
                f"command file needs time, {', '.join(ex.AXES)} (m)"
            )
        if tr.unit not in ("", "m"):
            fail(f"{path}: unit {tr.unit!r}; the stage's commands are in m")
        try:
            check_rate(tr.dt, str(path))
        except ValueError as exc:
            fail(str(exc))
        cmd = tr.values[:, [tr.axes.index(c) for c in ex.AXES]]
        try:  # from rest to rest, as the machine would take it
            check_trajectory(Trajectory(dt=tr.dt, position=cmd, at_rest=True), limits())
        except (ValueError, LimitViolation) as exc:
            fail(f"{path}: the command is outside seed 002 Table I: {exc}")
        commands.append(Command(name=path.stem, dt=float(tr.dt), command=cmd))
        sources.append(path)
    names = [c.name for c in commands]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        fail(f"two runs are named {dup[0]!r}: their measured files would be the same file")
    return commands, sources


# --- stage score: a measured run against the drawing (seed 002 eqs. 16-18) ---------------

#: How far a run's recorded set-points may lie from the command file's and still be a run of
#: it, m (assumed: 0.1 µm, above float32 rounding of set-points below 1 m (6e-8 m) and 20x
#: below the twin's 2 µm noise; ``stage play`` writes them exactly, %.17g).
_MATCH_M = 1e-7
_SUMMARY = "summary.json"


@stage_app.command("score")
def score_cmd(
    run: Annotated[
        Path,
        typer.Argument(
            help="A measured run (.csv, .mat, .h5: time [s], input_x, input_y, output_x, "
            "output_y [m], 10 kHz, from the command's first sample, its last set-point held "
            "0.5 s) of a command file of the --drawing folder."
        ),
    ],
    drawing: Annotated[
        Path,
        typer.Option(
            "--drawing",
            help="The folder `microfab optimize --out` wrote: its summary.json names the "
            "drawing (sizing, contour), M and where each command file's t_0 lies.",
        ),
    ],
    baseline: Annotated[
        Path | None,
        typer.Option(
            help="A measured run of another command of the folder (its baseline file), "
            "scored alike: prints the improvement over it."
        ),
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write the norms and the improvement (JSON).")
    ] = None,
) -> None:
    """Score measured runs against the drawing: seed 002 eqs. (16)-(18) (L1, L2, L∞).

    As the reference job scores its runs on the twin (`machines.xy_stage.score`): the
    output at the 400 Hz instants t_1 … t_M of eq. (13) projected on the exact contour,
    and the 500 ms after T (the last set-point held) scored apart as the tail's L∞. Each
    run is matched to the command file it played (its input columns), which gives its
    t_0. With --baseline, prints the improvement 100 (baseline - run) / baseline per norm
    (seed 002 Table III).
    """
    runs = [run] if baseline is None else [run, baseline]
    check_outputs(files={"--json": json_path}, inputs={"RUN": runs, "--drawing": drawing})
    summary, path = _optimized(drawing)
    from microfab.machines.xy_stage.score import score_run

    commands = _command_files(drawing, summary)
    scored: list[tuple[str, Path, str, Any]] = []
    for label, f in zip(("run", "baseline"), runs, strict=False):
        rec, dt = _measured(f)
        name, lead = _played_command(f, rec.u, dt, commands)
        try:
            norms = score_run(path, rec.y, summary["m"], lead)
        except ValueError as exc:
            fail(f"{f}: {exc}; record the hold after the command (`stage play --hold 0.5`)")
        scored.append((label, f, name, norms))
    _print_scores(scored, drawing, summary)
    if json_path is not None:
        from microfab.io.atomic import atomic_write_json

        data: dict[str, Any] = {
            "what": "seed 002 eqs. (16)-(18) at the 400 Hz instants, m; tail: the 500 ms after T",
            "optimized": str(drawing),
            "drawing": summary["drawing"],
            "m": summary["m"],
            "runs": {
                label: {"file": str(f), "command": name, **n.as_dict()}
                for label, f, name, n in scored
            },
        }
        if len(scored) == 2:
            data["improvement_percent"] = scored[0][3].improvement_over(scored[1][3])
        atomic_write_json(json_path, data)
        console.print(f"wrote {json_path}", highlight=False)


def _optimized(folder: Path) -> tuple[dict[str, Any], Any]:
    """The optimize folder's summary (the keys `stage score` reads) and its contour."""
    from microfab.cli.geometry import _load

    f = folder / _SUMMARY
    if not folder.is_dir() or not f.is_file():
        fail(f"--drawing {folder}: no {f}; give the folder `microfab optimize --out` wrote")
    from microfab.optimize.summary_file import read_optimize_summary

    try:
        doc = read_optimize_summary(f)
    except OSError as exc:
        fail(f"{f}: cannot read it: {exc.strerror or exc}")
    except ValueError as exc:  # one line naming the file and the key
        fail(f"{exc} (written by an older microfab optimize? run `microfab optimize` again)")
    summary = {
        "drawing": doc.drawing,
        "contour": doc.contour,
        "m": doc.m,
        "length": doc.path_length_m,
        "digest": doc.drawing_sha256,
        "units": doc.sizing.units,
        "chord": doc.sizing.chord,
        "text_height": doc.sizing.text_height,
        "commands": [(c.file, c.lead) for c in doc.commands.values()],
    }
    spec, k = summary["drawing"], summary["contour"]
    if summary["digest"] is not None:
        from microfab.io.runstore import content_digest

        if not Path(spec).is_file():
            fail(f"{f}: its drawing {spec} is not found from here: run where optimize ran")
        if content_digest(spec) != summary["digest"]:
            fail(f"{spec} has changed since {folder} was optimised on it")
    layer = _load(spec, summary["units"], summary["chord"], summary["text_height"])
    if not 0 <= k < len(layer):
        fail(f"{f}: contour {k} of {spec}, which has {len(layer)}")
    path = layer[k]
    # the same drawing read by the same code has the same length to the last bit (JSON
    # keeps 17 digits); 1e-9 only admits round-off, a resized drawing differs far more
    if not abs(path.length / summary["length"] - 1.0) <= 1e-9:
        fail(
            f"{spec} (contour {k}) is {path.length * 1e3:.6g} mm long, {f} says "
            f"{summary['length'] * 1e3:.6g} mm: not the drawing it was optimised on"
        )
    return summary, path


def _command_files(folder: Path, summary: dict[str, Any]) -> list[tuple[str, Any, int]]:
    """``(file name, set-points (n, 2) m, lead)`` of each command file the folder holds."""
    out = []
    for name, lead in summary["commands"]:
        f = folder / name
        if not f.is_file():
            continue  # removed by the user: a run of it is not matched (said below)
        tr = read_trace_file(f)
        if not all(c in tr.axes for c in ("input_x", "input_y")):
            fail(f"{f}: no input_x, input_y columns: not a command file of microfab optimize")
        cols = tr.values[:, [tr.axes.index("input_x"), tr.axes.index("input_y")]]
        out.append((name, cols, lead))
    return out


def _measured(f: Path) -> tuple[Any, float]:
    """A measured run (`stage_record`) and its sample time, s."""
    from microfab.identify.stage_runs import stage_record
    from microfab.machines.xy_stage.score import RUN_RATE_HZ

    tr = read_trace_file(f)
    try:
        rec = stage_record(tr, str(f))
    except ValueError as exc:
        fail(str(exc))
    if abs(tr.dt * RUN_RATE_HZ - 1.0) > 1e-9:
        fail(
            f"{f}: sampled at {1 / tr.dt:.6g} Hz; the command files are 10 kHz: record one "
            "row per command sample"
        )
    return rec, float(tr.dt)


def _played_command(
    f: Path, u: Any, dt: float, commands: list[tuple[str, Any, int]]
) -> tuple[str, int]:
    """The command file whose set-points ``u`` starts with, and its lead."""
    import numpy as np

    for name, cmd, lead in commands:
        n = cmd.shape[0]
        if u.shape[0] >= n and float(np.max(np.abs(u[:n] - cmd))) <= _MATCH_M:
            return name, lead
    names = ", ".join(c[0] for c in commands) or "none left"
    fail(
        f"{f}: its input_x, input_y are not those of a command file of --drawing ({names}): "
        "score the run of one of them, recorded from its first sample"
    )


def _print_scores(scored: list[tuple[str, Path, str, Any]], folder: Path, summary: Any) -> None:
    um = 1e6
    rows = [
        (f"{label}: {f.name}", name, f"{n.l1 * um:.2f}", f"{n.l2 * um:.2f}",
         f"{n.linf * um:.2f}", f"{n.tail_linf * um:.2f}")
        for label, f, name, n in scored
    ]  # fmt: skip
    if len(scored) == 2:
        imp = scored[0][3].improvement_over(scored[1][3])
        rows.append(("improvement [%]", "", *(f"{imp[k]:.1f}" for k in ("l1", "l2", "linf")), ""))
    print_table(
        Table(
            title=f"Deviation from {summary['drawing']} (contour {summary['contour']}), seed 002 "
            "eqs. (16)-(18)",
            columns=("run", "command", "L1 [µm]", "L2 [µm]", "L∞ [µm]", "tail L∞ [µm]"),
            rows=rows,
            note=f"at the 400 Hz instants t_1 … t_{summary['m']} of the commands in {folder}, "
            "by exact foot-point projection; tail: the 500 ms after T; improvement: 100 "
            "(baseline - run) / baseline",
        )
    )
