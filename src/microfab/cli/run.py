"""``microfab run``, ``microfab kinds`` and ``microfab reproduce``: read the kind registry."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Annotated, Any

import typer

from microfab.cli._kit import console, fail, print_table, progress, reporter

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
) -> None:
    """Run a job of any registered kind and write its report (report.html + figures + JSON).

    The kind is the job file's [job] kind (microfab kinds lists them). Results and
    learning state are saved as the run goes; running the same job again resumes. With
    --check the job file is read and checked and nothing runs or is written.
    """
    from microfab.experiments.catalog import default_job, load_job

    try:
        job = load_job(job_file) if job_file is not None else default_job()
    except (OSError, ValueError) as exc:
        fail(str(exc))
    out_dir = out or job.out
    if check:
        console.print(
            f"{job_file or 'default job'}: a valid {job.kind.name} job "
            f"({job.title}); it would write {out_dir}",
            highlight=False,
            soft_wrap=True,
        )
        return
    try:
        with progress() as prog:
            result = job.kind.run(job.config, out_dir, reporter(prog))
    except (OSError, ValueError) as exc:  # e.g. a results folder of another job
        fail(str(exc))
    path = job.kind.write_report(result, out_dir, job.title)
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


def kinds_cmd() -> None:
    """List the job kinds (for microfab run) and the reproductions (for microfab reproduce)."""
    from microfab.experiments.catalog import JOB_KINDS, REPRODUCTIONS
    from microfab.report.tables import Table

    print_table(
        Table(
            title="Job kinds: [job] kind = NAME in a job file, run with `microfab run JOB.toml`",
            columns=("kind", "seed", "example", "what it does"),
            rows=[
                (k.name, k.seed, f"examples/{k.example}", k.description) for k in JOB_KINDS.values()
            ],
        )
    )
    print_table(
        Table(
            title="Reproductions: `microfab reproduce NAME`",
            columns=("name", "seed", "options (--set key=value)", "what it reproduces"),
            rows=[
                (
                    r.name,
                    r.seed,
                    ", ".join(f"{o.name}={o.default}" for o in r.options) or "-",
                    r.description,
                )
                for r in REPRODUCTIONS.values()
            ],
        )
    )


def _settings(pairs: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key.strip():
            fail(f"--set takes key=value, got {pair!r}")
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
    settings: Annotated[
        list[str] | None,
        typer.Option("--set", help="Change a setting, key=value (see `microfab kinds`)."),
    ] = None,
) -> None:
    """A seed paper's published numbers beside ours, run on the twin (--json keeps them)."""
    from microfab.experiments.catalog import reproduction
    from microfab.io.atomic import atomic_write_json

    try:
        rep = reproduction(name)
        options = rep.parse_options(_settings(settings or []))
    except KeyError as exc:
        fail(str(exc.args[0]))
    except ValueError as exc:
        fail(str(exc))
    with progress() as prog:
        result = rep.run(options, reporter(prog))
    for table in result.tables:
        print_table(table)
    for note in result.notes:
        console.print(note, highlight=False)
    if json_path is not None:
        atomic_write_json(json_path, result.data or {})
        console.print(f"wrote {json_path}", highlight=False)
