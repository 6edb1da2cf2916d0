"""Console helpers shared by the ``microfab`` sub-commands.

The console, one-line errors and option checks, progress bars, tables, and the option and
file readers more than one command group uses (``LOW:HIGH`` ranges, measured traces).
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import threading
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NoReturn

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
from typer.core import TyperGroup

from microfab.cli import _sigint
from microfab.cli._options import USAGE_ERROR, repeated_option, resolve_choice_help
from microfab.core.memory import apply_allocator_policy
from microfab.core.threads import apply_thread_policy

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

    import numpy as np

    from microfab.core.signals import Trace
    from microfab.report.tables import Table

__all__ = [
    "RESUMING_COMMANDS",
    "OneLineErrors",
    "check_output_path",
    "check_outputs",
    "console",
    "err_console",
    "fail",
    "input_output",
    "interrupted_hint",
    "one_line",
    "parse_range",
    "print_interrupted",
    "print_table",
    "progress",
    "read_trace_file",
    "renamed",
    "reporter",
    "status",
]

#: Standard output; piped or redirected, lines are never wrapped (rich's default would
#: fold them at 80 columns, splitting summaries and table cells).
console = Console(soft_wrap=not os.isatty(1))
err_console = Console(stderr=True, soft_wrap=not os.isatty(2))


def one_line(msg: str) -> str:
    """``msg`` on one line: line breaks and runs of blanks become one space.

    Other control characters (a file's bytes quoted in a message) are shown escaped, so
    that an error is always exactly one line of plain text.
    """
    text = " ".join(msg.split())
    return "".join(
        ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in text
    )


def fail(msg: str, code: int = 2) -> NoReturn:
    """Print ``error: msg`` on stderr, on one line, and exit with ``code``."""
    err_console.print(
        f"[bold red]error:[/] {escape(one_line(msg))}", highlight=False, soft_wrap=True
    )
    raise typer.Exit(code)


def check_outputs(
    *,
    files: Mapping[str, Path | None] | None = None,
    folders: Mapping[str, Path | None] | None = None,
    inputs: Mapping[str, Path | Iterable[Path | None] | None] | None = None,
) -> None:
    """Refuse a command's outputs together, before any work (`microfab.cli._guard`).

    Every command that writes calls it once with every path it will write and every path
    it reads, before it reads or computes anything, so that a refusal is one ``error:``
    line (exit 2) and nothing is created: an output of the wrong kind, not writable, one
    of the inputs or inside an input folder, two outputs on one path or one inside an
    output folder, a symbolic-link loop, or a special file (FIFO, socket, device) among
    the outputs or inputs (looked at, never opened).

    Parameters
    ----------
    files : mapping of str to pathlib.Path or None
        Output files by option as typed (``{"--json": path}``); ``None`` values pass.
    folders : mapping of str to pathlib.Path or None
        Output folders by option (``{"--out": path}``): owned by the command.
    inputs : mapping of str to pathlib.Path, sequence of pathlib.Path, or None
        What the command reads, by option or argument (``{"TRACE": path}``).
    """
    from microfab.cli._guard import PathRefusedError, check_paths

    try:
        check_paths(files or {}, folders or {}, inputs or {})
    except PathRefusedError as exc:
        fail(str(exc))


def check_output_path(
    option: str,
    path: Path | None,
    *,
    kind: str = "file",
    inputs: Sequence[Path | None] = (),
) -> None:
    """`check_outputs` for one output: wrong kind, not writable, or one of the inputs.

    Parameters
    ----------
    option : str
        The option as the user typed it, e.g. ``"--json"``.
    path : pathlib.Path or None
        Where the command will write (``None``: not asked for, passes).
    kind : {"file", "folder"}
        What the command writes there: a file may replace a file, never a folder; a
        folder may be reused (the command then resumes or refuses itself), never a file.
    inputs : sequence of pathlib.Path or None
        What the command reads (files or folders; ``None`` entries are skipped).
    """
    named = {str(p): p for p in inputs if p is not None}
    if kind == "folder":
        check_outputs(folders={option: path}, inputs=named)
    else:
        check_outputs(files={option: path}, inputs=named)


#: Commands that save their work as they go and resume it when run again (the first
#: word, or the first two for a group's command).
RESUMING_COMMANDS = frozenset(
    {
        "run",
        "reproduce",
        "optimize",
        "droplet sweep",
        "droplet sensitivity",
        "slm build",
        "identify ann",
        "calibrate galvo",
        "calibrate laser",
        "calibrate nanomanipulator",
    }
)


def interrupted_hint(words: Sequence[str]) -> str:
    """What to tell a user who pressed Ctrl-C during the command named by ``words``.

    Parameters
    ----------
    words : sequence of str
        The command line's words that are not options (``["droplet", "sweep", ...]``).
    """
    one = words[0] if words else ""
    two = " ".join(words[:2])
    if one in RESUMING_COMMANDS or two in RESUMING_COMMANDS:
        return "what was saved is kept: rerun the same command to resume"
    return (
        "no file is left half-written (every file is written whole or not at all); "
        "rerun the same command"
    )


#: click's base exception, whether typer vendors click or uses it (``BadParameter``'s base).
_CLICK_ERROR: type[Exception] = next(
    c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException"
)


def _ignore_signal(signum: int, frame: Any) -> None:
    """A signal handler that does nothing (see `print_interrupted`)."""


def print_interrupted(words: Sequence[str]) -> None:
    """Print the one ``interrupted`` line for the command of ``words``; ignore SIGINT after.

    The shutdown has begun: a second SIGINT (another Ctrl-C, or one still pending from a
    handler that held it while a cluster started) must not cut the message or turn exit
    130 into death by signal (seen twice in the interrupt tests, under load). A Python
    handler, not SIG_IGN, which processes started later would inherit (a test's CliRunner
    runs this in the test process).

    Parameters
    ----------
    words : sequence of str
        The command line's words that are not options (`interrupted_hint`).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _ignore_signal)
    err_console.print(
        f"[bold red]interrupted[/]; {escape(interrupted_hint(words))}",
        highlight=False,
        soft_wrap=True,
    )


class OneLineErrors(TyperGroup):
    """The ``microfab`` group: a usage error is one ``error:`` line, like every refusal.

    click's default is a usage line, a hint and a boxed message; here a mistyped option
    value, an unknown option or a missing argument is refused as ``error: <what>
    (see 'microfab CMD --help')`` with click's exit code (2), on one line.
    """

    def invoke(self, ctx: Any) -> Any:
        """Run the command; Ctrl-C is one line saying what to do, and exit code 130.

        SIGINT is taken by `microfab.cli._sigint` while the command runs (one held while
        it loaded is raised first); the previous handler is back when it returns.
        """
        # the command's words, read before the group hands them to the subcommand
        given = [*getattr(ctx, "_protected_args", getattr(ctx, "protected_args", [])), *ctx.args]
        words = [str(a) for a in given if str(a)[:1] != "-"]
        twice = repeated_option(self, [str(a) for a in given])
        if twice is not None:
            raise USAGE_ERROR(twice)
        resolve_choice_help(self, [str(a) for a in given])  # the command's own, for --help
        try:
            _sigint.arm()
            result = super().invoke(ctx)
        except KeyboardInterrupt:
            print_interrupted(words)  # SIGINT ignored from now on: the guard is gone
            raise typer.Exit(130) from None
        except BaseException:
            _sigint.restore()
            raise
        _sigint.restore()
        return result

    def main(  # type: ignore[override]
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        """Run the command; in standalone mode, report usage errors on one line.

        First the process's thread pools are set (`microfab.core.threads.apply_thread_policy`:
        one thread per BLAS/OpenMP/PyTorch pool unless ``MICROFAB_THREADS`` says otherwise)
        and its allocator keeps freed memory for the next array
        (`microfab.core.memory.apply_allocator_policy`).
        """
        apply_allocator_policy()
        try:
            apply_thread_policy()
        except ValueError as exc:  # a bad MICROFAB_THREADS
            err_console.print(f"[bold red]error:[/] {escape(one_line(str(exc)))}",
                              highlight=False, soft_wrap=True)  # fmt: skip
            sys.exit(2)
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)
        except _CLICK_ERROR as exc:
            exit_code = int(getattr(exc, "exit_code", 2))
            if type(exc).__name__ == "NoArgsIsHelpError":
                # rich help is printed while it is built; plain help (piped) is the message
                text = exc.format_message()  # type: ignore[attr-defined]
                if text.strip():
                    typer.echo(text)
                sys.exit(exit_code)
            ctx = getattr(exc, "ctx", None)
            hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
            msg = exc.format_message()  # type: ignore[attr-defined]
            err_console.print(
                f"[bold red]error:[/] {escape(one_line(msg + hint))}",
                highlight=False,
                soft_wrap=True,
            )
            sys.exit(exit_code)
        except typer.Abort:
            err_console.print("Aborted!", highlight=False)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


class _Bars(Progress):
    """A `Progress` that ends honestly: full bars on success, none left on failure.

    Leaving the ``with`` block normally completes every task (a task without a total gets
    its count as total), so a bar never stays at ``8/9`` or ``0/?`` after the work is
    done; leaving it with an exception (a refusal, Ctrl-C) clears the bars, so that the
    ``error:`` or ``interrupted`` line that follows stands alone on stderr.
    """

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            for task in self.tasks:
                total = task.completed if task.total is None else task.total
                self.update(task.id, total=total, completed=total)
            super().__exit__(exc_type, exc, tb)
        elif not self.disable:
            self.live.transient = True
            self.live.stop()  # not `stop`: it adds an empty line on a non-terminal stream


def progress() -> Progress:
    """A rich progress bar on stderr (quiet in non-interactive CI); see `_Bars`."""
    return _Bars(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err_console,
        disable=not err_console.is_terminal and "CI" in os.environ,
    )


@contextlib.contextmanager
def status(what: str) -> Iterator[Callable[[str], None]]:
    """A progress line on stderr that each call of the yielded function rewrites.

    For work counted in runs of unknown number (a fit): ``show("run 3: ...")`` replaces
    the line and counts one more run. Cleared if the work fails (see `_Bars`), so that a
    refusal stays one line.
    """
    with progress() as bar:
        task = bar.add_task(what, total=None)
        yield lambda text: bar.update(task, advance=1, description=text)


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


def renamed(msg: str, names: dict[str, str]) -> str:
    """A library message with its parameter names replaced by the command line's.

    Parameters
    ----------
    msg : str
        The library's message, e.g. ``"f1_hz must lie below ..."``.
    names : dict of str to str
        Library name -> option, e.g. ``{"f1_hz": "--f1"}``; replaced in this order.
    """
    for lib, cli in names.items():
        msg = msg.replace(lib, cli)
    return msg


def parse_range(option: str, text: str, unit: str = "Hz") -> tuple[float, float]:
    """``"LOW:HIGH"`` as two finite numbers with ``0 <= LOW < HIGH`` (exits 2 otherwise).

    Parameters
    ----------
    option : str
        The option as typed (``"--band"``), named in the refusal.
    text : str
        The option's value.
    unit : str
        Unit of both numbers, named in the refusal.

    Returns
    -------
    (float, float)
        ``(low, high)`` in ``unit``.
    """
    lo, sep, hi = text.partition(":")
    try:
        a, b = float(lo), float(hi)
    except ValueError:
        a = b = math.nan
    if not sep or not (math.isfinite(a) and math.isfinite(b) and 0 <= a < b):
        fail(f"{option} must look like LOW:HIGH in {unit} with 0 <= LOW < HIGH, got {text!r}")
    return a, b


def read_trace_file(path: Path) -> Trace:
    """A measured trace (`microfab.io.trace.read_trace`); a bad file exits 2 naming it."""
    from microfab.io.trace import read_trace

    try:
        return read_trace(path)
    except (OSError, ValueError) as exc:
        msg = str(exc)
        fail(msg if str(path) in msg else f"{path}: {msg}")


def input_output(trace: Trace, path: Path, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """The ``input_<axis>`` and ``output_<axis>`` columns of a trace (exits 2 if missing).

    Parameters
    ----------
    trace : Trace
        As read from ``path``.
    path : Path
        The trace's file, named in the refusal.
    axis : str
        ``<a>`` of the column names.

    Returns
    -------
    (ndarray, ndarray)
        Input and output, shape ``(n_samples,)``, in the trace's unit.
    """
    names = (f"input_{axis}", f"output_{axis}")
    for name in names:
        if name not in trace.axes:
            fail(
                f"{path}: no column {name!r} (columns: time, {', '.join(trace.axes)}); the "
                "file needs time, input_<a> and output_<a>, --axis picks <a>"
            )
    i, o = (trace.axes.index(n) for n in names)
    return trace.values[:, i], trace.values[:, o]
