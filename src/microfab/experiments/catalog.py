"""The table of job kinds and reproductions that ``microfab`` knows.

Adding a machine adds its entries here (one line each); `microfab run`, `microfab
reproduce` and `microfab kinds` read nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from microfab.experiments.kinds import JobKind, Reproduction
from microfab.experiments.seed000_msl.job import MSL_ILC, MSL_ILC_REPRODUCTION
from microfab.experiments.seed001_nanomanipulator.job import (
    NANOMANIPULATOR_MSL,
    NANOMANIPULATOR_REPRODUCTION,
)
from microfab.experiments.seed002_reference.job import (
    REFERENCE_OPT_REPRODUCTION,
    STAGE_REFERENCE_OPT,
)
from microfab.experiments.seed002_stage.job import STAGE_IDENTIFY, STAGE_MODELS_REPRODUCTION
from microfab.experiments.seed003_inkjet.job import DROPLET_FIG4_REPRODUCTION, DROPLET_SWEEP
from microfab.experiments.seed003_slm.job import SLM_SHAPER_REPRODUCTION, SLM_SHAPING
from microfab.experiments.seed004_laser.job import LASER_MICROMACHINING, LASER_REPRODUCTION
from microfab.io.job import JobFile, JobFileError, parse_job, read_job

__all__ = [
    "DEFAULT_KIND",
    "JOB_KINDS",
    "REPRODUCTIONS",
    "Job",
    "default_job",
    "job_kind",
    "load_job",
    "reproduction",
]

#: Every job kind, by name.
JOB_KINDS: dict[str, JobKind] = {
    k.name: k
    for k in (
        MSL_ILC,
        NANOMANIPULATOR_MSL,
        STAGE_IDENTIFY,
        STAGE_REFERENCE_OPT,
        DROPLET_SWEEP,
        LASER_MICROMACHINING,
        SLM_SHAPING,
    )
}
#: Every reproduction, by name.
REPRODUCTIONS: dict[str, Reproduction] = {
    r.name: r
    for r in (
        MSL_ILC_REPRODUCTION,
        NANOMANIPULATOR_REPRODUCTION,
        STAGE_MODELS_REPRODUCTION,
        REFERENCE_OPT_REPRODUCTION,
        DROPLET_FIG4_REPRODUCTION,
        LASER_REPRODUCTION,
        SLM_SHAPER_REPRODUCTION,
    )
}


#: The kind of a job file whose ``[job]`` names none (job files written before kinds).
DEFAULT_KIND = "msl-ilc"


def job_kind(name: str) -> JobKind:
    """The job kind called ``name``.

    Raises
    ------
    KeyError
        Naming the known kinds.
    """
    try:
        return JOB_KINDS[name]
    except KeyError:
        raise KeyError(
            f"unknown job kind {name!r} (known: {', '.join(sorted(JOB_KINDS))})"
        ) from None


def reproduction(name: str) -> Reproduction:
    """The reproduction called ``name``.

    Raises
    ------
    KeyError
        Naming the known reproductions.
    """
    try:
        return REPRODUCTIONS[name]
    except KeyError:
        raise KeyError(
            f"unknown reproduction {name!r} (known: {', '.join(sorted(REPRODUCTIONS))})"
        ) from None


@dataclass(frozen=True, kw_only=True)
class Job:
    """A checked job: its kind, title, report folder, checked sections and the kind's config."""

    kind: JobKind
    title: str
    out: Path
    sections: dict[str, dict[str, Any]]
    config: Any

    def fingerprint(self) -> dict[str, Any]:
        """What the job's results depend on (`JobKind.fingerprint`): the run store's key."""
        return self.kind.fingerprint(self.sections)


def _job(file: JobFile) -> Job:
    try:
        kind = job_kind(file.kind or DEFAULT_KIND)
    except KeyError as exc:
        raise JobFileError(f"{file.source}: {exc.args[0]}") from None
    sections = file.parse(kind.schema)
    return Job(
        kind=kind,
        title=file.name or kind.default_title,
        out=file.out or Path("report"),
        sections=sections,
        config=kind.make_config_of(sections, file.source),
    )


def load_job(path: str | Path) -> Job:
    """Read and check a job file of any registered kind.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Not TOML, unknown kind, section or key, or a value of the wrong type or range
        (`microfab.io.job.JobFileError`), naming file, section, key and value.
    """
    return _job(read_job(path))


def default_job() -> Job:
    """The shipped default job (``microfab/data/default_job.toml``: seed 000 on the twin)."""
    import tomllib

    text = resources.files("microfab.data").joinpath("default_job.toml").read_text()
    return _job(parse_job(tomllib.loads(text), "default_job.toml"))
