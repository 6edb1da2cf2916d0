"""What a seed's experiment package registers: job kinds and reproductions.

A `JobKind` is what ``microfab run JOB.toml`` runs: it names its TOML sections (a schema
of `microfab.io.job.Key`), turns them into its own frozen config dataclass, runs, and
writes its report. A `Reproduction` is what ``microfab reproduce NAME`` runs: the seed's
published numbers beside ours, as tables. Both are plain data; the registry
`microfab.experiments.catalog` lists each by name, seed, one line and the import path of
its object (the pattern of Klipper's ``shaper_defs``), so that listing them loads no
machine: adding a machine adds one entry to each, nothing else changes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from microfab.io.job import JobFile, Key, parse_section
from microfab.report.page import Figure
from microfab.report.tables import Table

__all__ = [
    "JobKind",
    "KindResult",
    "Progress",
    "Reproduction",
    "ReproductionResult",
    "fingerprint_settings",
]


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


def fingerprint_settings(
    kind: str,
    version: str,
    sections: Mapping[str, Mapping[str, Any]],
    schema: Iterable[tuple[str, Sequence[Key]]],
    data_files: Sequence[str],
) -> dict[str, Any]:
    """Resolved settings, input and data-file digests of a run (see `JobKind.fingerprint`)."""
    from microfab.io.runstore import content_digest
    from microfab.machines.twins import data_path

    out: dict[str, Any] = {"kind": kind, "version": version}
    for sec, body in sections.items():
        for key, value in body.items():
            out[f"{sec}.{key}"] = value
    for sec, keys in schema:
        for key in keys:
            value = sections.get(sec, {}).get(key.name)
            if key.path and isinstance(value, str) and value and Path(value).exists():
                out[f"input:{sec}.{key.name}"] = content_digest(value)
    for name in data_files:
        out[f"data:{name}"] = content_digest(data_path(name))
    return out


@dataclass(frozen=True, kw_only=True)
class JobKind:
    """A kind of job ``microfab run`` knows.

    Parameters
    ----------
    name : str
        The ``[job] kind`` value, e.g. ``"msl-ilc"``.
    schema : mapping of str to sequence of Key
        The kind's TOML sections and keys.
    make_config : callable
        ``(checked_sections) -> config``: the kind's own frozen config dataclass.
    run : callable
        ``(config, out_dir, progress) -> result`` (a `KindResult`); saves whatever it
        needs under ``out_dir`` to resume after an interruption.
    write_report : callable
        ``(result, out_dir, title) -> path of report.html``.
    default_title : str
        Report title when the job file gives none.
    data_files : tuple of str
        The packaged data files (under ``microfab/data``) a run reads; their content is
        part of the run's fingerprint.
    version : str
        The model version: change it when the same settings would give other results
        (physics, solver or saved-state layout), so that older runs are not resumed.
    preflight : callable, optional
        ``(config) -> None``: checks of what a run needs besides its job file (an input
        folder another job writes), made by ``microfab run`` and ``run --check`` before any
        work; raises ValueError naming what is missing. Loading a job file does not call it.
    """

    name: str
    schema: Mapping[str, Sequence[Key]]
    make_config: Callable[[dict[str, dict[str, Any]]], Any]
    run: Callable[[Any, Path, Progress], KindResult]
    write_report: Callable[[Any, Path, str], Path]
    default_title: str
    data_files: tuple[str, ...] = ()
    version: str = "1"
    preflight: Callable[[Any], None] | None = None

    def config(self, job: JobFile) -> Any:
        """The kind's config from a parsed job file (every key checked).

        Raises
        ------
        microfab.io.job.JobFileError
            Unknown section or key, or a value of the wrong type or range.
        ValueError
            A combination of values the config refuses (message names the file).
        """
        return self.make_config_of(job.parse(self.schema), job.source)

    def make_config_of(self, sections: dict[str, dict[str, Any]], source: str) -> Any:
        """The kind's config from checked sections (`microfab.io.job.JobFile.parse`)."""
        try:
            return self.make_config(sections)
        except ValueError as exc:
            raise type(exc)(f"{source}: {exc}") from exc

    def fingerprint(self, sections: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
        """The settings a run of this kind depends on, for `microfab.io.runstore.open_run`.

        Parameters
        ----------
        sections : mapping
            Checked sections (every key, defaults included).

        Returns
        -------
        dict
            ``kind``, ``version``, ``<section>.<key>`` for every key; ``input:<section>.<key>``
            with the content digest of every path key that names an existing file or folder;
            ``data:<file>`` with that of every packaged data file the kind reads.
        """
        return fingerprint_settings(
            self.name, self.version, sections, self.schema.items(), self.data_files
        )


@dataclass(frozen=True, kw_only=True)
class ReproductionResult:
    """The seed's numbers beside ours.

    Attributes
    ----------
    tables : tuple of Table
        Comparison tables (``ours / seed`` cells or ours and seed columns), each row
        labelled with where our numbers come from (`Table.labels`: input from the paper,
        fitted to it, or predicted; `microfab.report.provenance.labelled`).
    notes : tuple of str
        What differs and why, one line each.
    data : dict
        JSON-ready numbers (ours), for ``--json``.
    figures : callable, optional
        ``figures() -> tuple of Figure``: the reproduction's figures, drawn from what the
        run returned (not computed again) and only when asked (``microfab reproduce NAME
        --out DIR`` writes them with the tables and notes as ``DIR/report.html``).

    Raises
    ------
    ValueError
        A table without its row labels.
    """

    tables: tuple[Table, ...]
    notes: tuple[str, ...] = ()
    data: dict[str, Any] | None = None
    figures: Callable[[], tuple[Figure, ...]] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "tables", tuple(self.tables))
        for t in self.tables:
            if t.rows and not t.labels:  # Table itself checks one label per row
                raise ValueError(
                    f"table {t.title!r} has no row labels: build it with "
                    "microfab.report.provenance.labelled"
                )

    def to_json(self) -> dict[str, Any]:
        """``data`` and, under ``"provenance"``, every row's label by table title."""
        out = dict(self.data or {})
        out["provenance"] = [{"table": t.title, "rows": t.labels_json()} for t in self.tables]
        return out


@dataclass(frozen=True, kw_only=True)
class Reproduction:
    """A reproduction of a seed paper's tables, run by ``microfab reproduce NAME``.

    Parameters
    ----------
    name : str
        Command-line name, e.g. ``"msl-ilc"``.
    run : callable
        ``(options, progress) -> ReproductionResult``.
    options : tuple of Key
        Settings a user may change (``microfab reproduce NAME --set key=value``); the
        defaults are the seed's.
    data_files, version : tuple of str, str
        As for `JobKind`: what a resumed reproduction's checkpoints depend on.
    run_folder_option : str, optional
        The option that names a folder where the reproduction saves what it resumes from;
        ``microfab reproduce`` opens it as a run store (`microfab.io.runstore`) keyed on
        the other options, so a rerun with other settings is refused, not resumed.
    preflight : callable, optional
        ``preflight(options)``: raises ``ValueError`` for what a run would refuse only
        once started (a required input folder missing); called by ``microfab reproduce``
        (with or without ``--check``) before any work.
    """

    name: str
    run: Callable[[dict[str, Any], Progress], ReproductionResult]
    options: tuple[Key, ...] = ()
    data_files: tuple[str, ...] = ()
    version: str = "1"
    run_folder_option: str | None = None
    preflight: Callable[[dict[str, Any]], None] | None = None

    def fingerprint(self, options: Mapping[str, Any]) -> dict[str, Any]:
        """The settings a resumable reproduction depends on (see `JobKind.fingerprint`).

        The run-folder option itself is left out: the same run may be moved.
        """
        given = {k: v for k, v in options.items() if k != self.run_folder_option}
        return fingerprint_settings(
            f"reproduce {self.name}", self.version, {"set": given}, [("set", self.options)],
            self.data_files,
        )  # fmt: skip

    def parse_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Check user settings against `options` (unknown names refused).

        Raises
        ------
        microfab.io.job.JobFileError
            Unknown option, or a value of the wrong type or range.
        """
        return parse_section(given, self.options, f"reproduce {self.name}")
