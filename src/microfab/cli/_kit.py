"""Console helpers shared by the ``microfab`` sub-commands."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, NoReturn

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table as RichTable

if TYPE_CHECKING:
    from collections.abc import Callable

    from microfab.report.tables import Table

__all__ = ["console", "err_console", "fail", "print_table", "progress", "reporter"]

#: Standard output; piped or redirected, lines are never wrapped (rich's default would
#: fold them at 80 columns, splitting summaries and table cells).
console = Console(soft_wrap=not os.isatty(1))
err_console = Console(stderr=True, soft_wrap=not os.isatty(2))


def fail(msg: str, code: int = 2) -> NoReturn:
    """Print ``error: msg`` on stderr and exit with ``code``."""
    err_console.print(f"[bold red]error:[/] {escape(msg)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code)


def progress() -> Progress:
    """A rich progress bar on stderr (quiet in non-interactive CI)."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err_console,
        disable=not err_console.is_terminal and "CI" in os.environ,
    )


def reporter(prog: Progress) -> Callable[[str, int, int | None], None]:
    """A library progress callback ``(task, done, total)`` drawn as one bar per task."""
    tasks: dict[str, TaskID] = {}

    def report(task: str, done: int, total: int | None) -> None:
        if task not in tasks:
            tasks[task] = prog.add_task(task, total=total)
        prog.update(tasks[task], completed=done, total=total)

    return report


def print_table(table: Table) -> None:
    """Print a report table: a rich table on a terminal, plain tab-separated lines else."""
    if not console.is_terminal:
        print(table.to_text())
        return
    tab = RichTable(title=table.title, caption=table.note or None)
    for i, col in enumerate(table.columns):
        tab.add_column(escape(col), justify="right" if i else "left")
    for row in table.rows:
        tab.add_row(*(escape(c) for c in row))
    console.print(tab)
