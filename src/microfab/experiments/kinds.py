"""What a seed's experiment package registers: job kinds and reproductions.

A `JobKind` is what ``microfab run JOB.toml`` runs: it names its TOML sections (a schema
of `microfab.io.job.Key`), turns them into its own frozen config dataclass, runs, and
writes its report. A `Reproduction` is what ``microfab reproduce NAME`` runs: the seed's
published numbers beside ours, as tables. Both are plain data in the table of
`microfab.experiments.catalog` (the pattern of Klipper's ``shaper_defs``): adding a
machine adds one entry to each, nothing else changes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from microfab.io.job import JobFile, Key, parse_section
from microfab.report.tables import Table

__all__ = ["JobKind", "KindResult", "Progress", "Reproduction", "ReproductionResult"]


class Progress(Protocol):
    """Progress of long work: ``progress(task, done, total)``.

    ``task`` labels one bar (e.g. ``"ILC at 400 features/s"``); ``total`` may be ``None``
    when unknown. The CLI draws rich progress bars from it; library code never imports
    rich.
    """

    def __call__(self, task: str, done: int, total: int | None) -> None:
        """Report that ``done`` of ``total`` steps of ``task`` are finished."""
        ...


def no_progress(task: str, done: int, total: int | None) -> None:
    """A `Progress` that reports nothing."""


@runtime_checkable
class KindResult(Protocol):
    """What a job kind's run returns: enough to write its report and a summary."""

    def summary(self) -> dict[str, Any]:
        """JSON-ready numbers of the run, ours beside the seed's where it has them."""
        ...

    def comparison(self) -> tuple[Table, ...]:
        """Our numbers beside the seed's, as tables (terminal and report)."""
        ...

    def failures(self) -> tuple[str, ...]:
        """One line per part of the job that failed (kept going; empty when all ran)."""
        ...


@dataclass(frozen=True, kw_only=True)
class JobKind:
    """A kind of job ``microfab run`` knows.

    Parameters
    ----------
    name : str
        The ``[job] kind`` value, e.g. ``"msl-ilc"``.
    description : str
        One line for ``microfab kinds``.
    seed : str
        Seed paper it reproduces (file stem in ``shared/seeds``), e.g. ``"000"``.
    schema : mapping of str to sequence of Key
        The kind's TOML sections and keys.
    make_config : callable
        ``(checked_sections) -> config``: the kind's own frozen config dataclass.
    run : callable
        ``(config, out_dir, progress) -> result`` (a `KindResult`); saves whatever it
        needs under ``out_dir`` to resume after an interruption.
    write_report : callable
        ``(result, out_dir, title) -> path of report.html``.
    example : str
        The shipped example job file (under ``examples/``).
    default_title : str
        Report title when the job file gives none.
    """

    name: str
    description: str
    seed: str
    schema: Mapping[str, Sequence[Key]]
    make_config: Callable[[dict[str, dict[str, Any]]], Any]
    run: Callable[[Any, Path, Progress], KindResult]
    write_report: Callable[[Any, Path, str], Path]
    example: str
    default_title: str

    def config(self, job: JobFile) -> Any:
        """The kind's config from a parsed job file (every key checked).

        Raises
        ------
        microfab.io.job.JobFileError
            Unknown section or key, or a value of the wrong type or range.
        ValueError
            A combination of values the config refuses (message names the file).
        """
        sections = job.parse(self.schema)
        try:
            return self.make_config(sections)
        except ValueError as exc:
            raise type(exc)(f"{job.source}: {exc}") from exc


@dataclass(frozen=True, kw_only=True)
class ReproductionResult:
    """The seed's numbers beside ours.

    Attributes
    ----------
    tables : tuple of Table
        Comparison tables (``ours / seed`` cells or ours and seed columns).
    notes : tuple of str
        What differs and why, one line each.
    data : dict
        JSON-ready numbers (ours), for ``--json``.
    """

    tables: tuple[Table, ...]
    notes: tuple[str, ...] = ()
    data: dict[str, Any] | None = None


@dataclass(frozen=True, kw_only=True)
class Reproduction:
    """A reproduction of a seed paper's tables, run by ``microfab reproduce NAME``.

    Parameters
    ----------
    name : str
        Command-line name, e.g. ``"msl-ilc"``.
    description : str
        One line for ``microfab kinds``.
    seed : str
        Seed paper, e.g. ``"000"``.
    run : callable
        ``(options, progress) -> ReproductionResult``.
    options : tuple of Key
        Settings a user may change (``microfab reproduce NAME --set key=value``); the
        defaults are the seed's.
    """

    name: str
    description: str
    seed: str
    run: Callable[[dict[str, Any], Progress], ReproductionResult]
    options: tuple[Key, ...] = ()

    def parse_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Check user settings against `options` (unknown names refused).

        Raises
        ------
        microfab.io.job.JobFileError
            Unknown option, or a value of the wrong type or range.
        """
        return parse_section(given, self.options, f"reproduce {self.name}")
