"""``microfab run``, ``microfab kinds`` and ``microfab reproduce``: read the kind registry."""

from __future__ import annotations

import contextlib
import os
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from microfab.cli._kit import (
    check_output_path,
    check_outputs,
    console,
    fail,
    print_table,
    progress,
    reporter,
)

if TYPE_CHECKING:
    from microfab.experiments.kinds import ReproductionResult

__all__ = ["kinds_cmd", "reproduce_cmd", "run_cmd"]


def run_cmd(
    job_file: Annotated[
        Path | None, typer.Argument(help="Job TOML; the default job (seed 000 twin) if omitted.")
    ] = None,
    out: Annotated[Path | None, typer.Option(help="Report folder (overrides the job's).")] = None,
    check: Annotated[
        bool,
        typer.Option("--check", help="Only check the job file and say what would run."),
    ] = False,
    fresh: Annotated[
        bool,
        typer.Option(
            "--fresh",
            help="Start clean: move the files an earlier run wrote in the report folder "
            "to its _previous/ folder instead of resuming (or refusing other settings).",
        ),
    ] = False,
    wait: Annotated[
        bool,
        typer.Option(
            "--wait",
            help="When another microfab is writing the report folder, wait for it to "
            "finish (then resume or refuse as usual) instead of refusing at once.",
        ),
    ] = False,
) -> None:
    """Run a job of any registered kind and write its report (report.html + figures + JSON).

    The kind is the job file's [job] kind (microfab kinds lists them). Results and
    learning state are saved as the run goes; running the same job again resumes, and a
    report folder that holds a run of other settings (or input files that changed) is
    refused, naming the first difference, unless --fresh is given. With --check the job
    file is read and checked and nothing runs or is written. One writer per report
    folder: while another microfab writes it, the run is refused (or waits, --wait).
    """
    check_outputs(folders={"--out": out}, inputs={"JOB": job_file})
    from microfab.experiments.catalog import default_job, load_job
    from microfab.io.runstore import check_run, open_run

    try:
        job = load_job(job_file) if job_file is not None else default_job()
        settings = job.fingerprint()
        if job.kind.preflight is not None:
            job.kind.preflight(job.config)
    except (OSError, ValueError) as exc:
        fail(f"{job_file}: {exc}" if job_file is not None and str(job_file) not in str(exc)
             else str(exc))  # fmt: skip
    out_dir = out or job.out
    if check:
        try:
            plan = check_run(out_dir, settings, fresh=fresh)
        except ValueError as exc:
            fail(str(exc))
        what = {"start": "write", "resume": "resume the run in"}.get(plan, "start fresh in")
        console.print(
            f"{job_file or 'default job'}: a valid {job.kind.name} job "
            f"({job.title}); it would {what} {out_dir}",
            highlight=False,
            soft_wrap=True,
        )
        return
    try:
        with (
            open_run(
                out_dir,
                settings,
                fresh=fresh,
                wait=wait,
                busy_hint="rerun with --wait to wait for it",
                on_wait=lambda msg: console.print(msg, highlight=False, soft_wrap=True),
            ) as store,
            progress() as prog,
        ):
            if store.moved_to is not None:
                console.print(f"moved the earlier run's files to {store.moved_to}")
            result = job.kind.run(job.config, out_dir, reporter(prog))
            path = job.kind.write_report(result, out_dir, job.title)
    except (OSError, ValueError) as exc:  # e.g. a results folder of another job
        fail(str(exc))
    for table in result.comparison():
        print_table(table)
    console.print(f"report: {path}", highlight=False)
    failed = result.failures()
    if failed:
        fail(
            f"{len(failed)} part(s) of the job failed, the rest is in the report "
            f"(running the job again retries them); first: {failed[0]}",
            code=1,
        )


def kinds_cmd(
    name: Annotated[
        str | None,
        typer.Argument(help="A kind or reproduction: show its settings (sections and keys)."),
    ] = None,
) -> None:
    """List the job kinds (for microfab run) and the reproductions (for microfab reproduce).

    With a NAME, the settings of that kind (its job-file sections and keys, defaults,
    ranges and units) or reproduction (its --set options).
    """
    from microfab.experiments.catalog import KIND_ENTRIES, REPRODUCTION_ENTRIES
    from microfab.report.tables import Table

    if name is not None:
        _settings_of(name)
        return
    print_table(
        Table(
            title="Job kinds: [job] kind = NAME in a job file, run with `microfab run JOB.toml`",
            columns=("kind", "seed", "example", "what it does"),
            rows=[
                (k.name, k.seed, f"examples/{k.example}", k.description)
                for k in KIND_ENTRIES.values()
            ],
        )
    )
    print_table(
        Table(
            title="Reproductions: `microfab reproduce NAME` (settings: `microfab kinds NAME`)",
            columns=("name", "seed", "what it reproduces"),
            rows=[(r.name, r.seed, r.description) for r in REPRODUCTION_ENTRIES.values()],
        )
    )


def _settings_of(name: str) -> None:
    """Print the schema of the kind, and the options of the reproduction, called ``name``."""
    from microfab.experiments.catalog import (
        KIND_ENTRIES,
        REPRODUCTION_ENTRIES,
        job_kind,
        reproduction,
    )
    from microfab.report.tables import Table

    if name not in KIND_ENTRIES and name not in REPRODUCTION_ENTRIES:
        known = ", ".join(sorted({*KIND_ENTRIES, *REPRODUCTION_ENTRIES}))
        fail(f"unknown kind or reproduction {name!r} (known: {known})")

    def rows(section: str, keys: Any) -> list[tuple[str, ...]]:
        return [(section, k.name, _shown(k.default), _allowed(k), k.help) for k in keys]

    columns = ("section", "key", "default", "allowed", "what it is")
    if name in KIND_ENTRIES:
        kind = job_kind(name)
        body = [r for sec, keys in kind.schema.items() for r in rows(f"[{sec}]", keys)]
        print_table(Table(title=f"Job kind {name}: its sections and keys", columns=columns,
                          rows=body))  # fmt: skip
    if name in REPRODUCTION_ENTRIES:
        rep = reproduction(name)
        print_table(Table(title=f"Reproduction {name}: --set key=value", columns=columns,
                          rows=rows("--set", rep.options)))  # fmt: skip


def _allowed(key: Any) -> str:
    """A key's type or range and unit, e.g. ``[1, 125000] features/s``."""
    if key.choices is not None:
        return " | ".join(key.choices)
    if key.type not in ("int", "float", "int_list", "float_list"):
        return key.type
    lo = "-inf" if key.low is None else _shown(key.low)
    hi = "inf" if key.high is None else _shown(key.high)
    return f"[{lo}, {hi}] {key.unit}".rstrip()


def _shown(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, tuple):
        return "[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value) + "]"
    if isinstance(value, float):
        return str(int(value)) if value.is_integer() and abs(value) < 1e15 else f"{value:g}"
    return str(value)


def _settings(pairs: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key.strip():
            fail(f"--set takes key=value, got {pair!r}")
        if key.strip() in out:  # the last would silently win over the first
            fail(f"--set {key.strip()} is given twice; give each setting once")
        try:
            out[key.strip()] = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = text.strip()  # a bare word: a string
    return out


def reproduce_cmd(
    name: Annotated[str, typer.Argument(help="Reproduction name (see `microfab kinds`).")],
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write our numbers as JSON.")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the tables, notes and figures as DIR/report.html (a run folder: "
            "rerun with the same settings to rewrite it, --fresh to start clean).",
        ),
    ] = None,
    settings: Annotated[
        list[str] | None,
        typer.Option("--set", help="Change a setting, key=value (see `microfab kinds`)."),
    ] = None,
    fresh: Annotated[
        bool,
        typer.Option(
            "--fresh",
            help="With a checkpoint folder: move what an earlier run saved there to its "
            "_previous/ folder and start clean.",
        ),
    ] = False,
    check: Annotated[
        bool,
        typer.Option("--check", help="Check the settings, inputs and outputs only; run nothing."),
    ] = False,
) -> None:
    """A seed paper's published numbers beside ours, run on the twin (--json keeps them).

    A reproduction that saves checkpoints (a --set checkpoints=FOLDER option) resumes from
    them when rerun with the same settings, and refuses a folder saved with other settings
    (naming the first difference) unless --fresh is given. With --check the settings,
    required inputs and outputs are checked as a run would check them, and nothing runs.
    """
    check_output_path("--json", json_path)
    from microfab.experiments.catalog import reproduction
    from microfab.io.atomic import atomic_write_json
    from microfab.io.runstore import check_run, open_run

    try:
        rep = reproduction(name)
    except KeyError as exc:
        fail(str(exc.args[0]))
    try:
        options = rep.parse_options(_settings(settings or []))
        folder = options.get(rep.run_folder_option or "") or None
        inputs = [Path(options[k.name]) for k in rep.options if k.path and options[k.name]]
        if folder and out is not None and os.path.realpath(folder) == os.path.realpath(out):
            fail(f"--out {out} is also the checkpoint folder; give --out another folder")
        check_outputs(
            folders={
                "--out": out,
                f"--set {rep.run_folder_option}": Path(folder) if folder else None,
            },
            files={"--json": json_path},
            inputs={"--set": inputs},
        )
        # the settings' fingerprint digests inputs and data files: only when a page is asked
        page_settings = (
            {**rep.fingerprint(options), "written": "report page"} if out is not None else {}
        )
        if rep.preflight is not None:
            rep.preflight(options)
        if check:
            plan = check_run(folder, rep.fingerprint(options), fresh=fresh) if folder else None
            what = {
                None: "save nothing to resume from",
                "start": f"save its checkpoints in {folder}",
                "resume": f"resume from {folder}",
            }.get(plan, f"start fresh in {folder}")
            if out is not None:
                page = check_run(out, page_settings, fresh=fresh)
                what += f", and {'rewrite' if page == 'resume' else 'write'} {out}/report.html"
            console.print(
                f"reproduce {name}: valid settings; it would {what}",
                highlight=False,
                soft_wrap=True,
            )
            return
        store = (
            open_run(
                folder,
                rep.fingerprint(options),
                fresh=fresh,
                other_hint=f"give another --set {rep.run_folder_option}=FOLDER",
            )
            if folder
            else contextlib.nullcontext()
        )
        page_store = (
            open_run(out, page_settings, fresh=fresh, other_hint="give another --out")
            if out is not None
            else contextlib.nullcontext()
        )
        with store, page_store, progress() as prog:
            result = rep.run(options, reporter(prog))
            page = _write_reproduction_page(name, result, out) if out is not None else None
            if json_path is not None:
                atomic_write_json(json_path, result.to_json())
    except ValueError as exc:
        fail(str(exc))
    for table in result.tables:
        print_table(table)
    for note in result.notes:
        console.print(note, highlight=False)
    for written in (json_path, page):
        if written is not None:
            console.print(f"wrote {written}", highlight=False)


def _write_reproduction_page(name: str, result: ReproductionResult, out: Path) -> Path:
    """``out/report.html``: the reproduction's tables (with their labels), notes, figures."""
    from microfab.experiments.catalog import REPRODUCTION_ENTRIES
    from microfab.report.page import page_html, write_page

    entry = REPRODUCTION_ENTRIES[name]
    figures = result.figures() if result.figures is not None else ()
    text = page_html(
        f"microfab reproduce {name}",
        intro=f"Seed {entry.seed}: {entry.description}. Each table's last column says whether "
        "our number is an input from the paper, fitted to it (by which calibration) or "
        "predicted.",
        notes=result.notes,
        figures=figures,
        tables=result.tables,
    )
    return write_page(out, text, figures)
