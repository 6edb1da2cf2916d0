"""The table of job kinds and reproductions that ``microfab`` knows.

Adding a machine adds its entries here (one each: name, seed, one line, example and the
import path of its `JobKind` or `Reproduction`); `microfab run`, `microfab reproduce` and
`microfab kinds` read nothing else. Importing this module loads no machine: a kind's
modules are imported when it is looked up (`job_kind`, ``JOB_KINDS[name]``), so the
commands that only list or check start in a fraction of a second.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from microfab.io.job import JobFile, JobFileError, parse_job, read_job

if TYPE_CHECKING:
    from microfab.experiments.kinds import JobKind, Reproduction

T = TypeVar("T")

__all__ = [
    "DEFAULT_KIND",
    "JOB_KINDS",
    "KIND_ENTRIES",
    "REPRODUCTIONS",
    "REPRODUCTION_ENTRIES",
    "Job",
    "KindEntry",
    "ReproductionEntry",
    "default_job",
    "job_kind",
    "load_job",
    "reproduction",
]


@dataclass(frozen=True, kw_only=True)
class KindEntry:
    """A job kind as the registry lists it, before its machine is loaded.

    Attributes
    ----------
    name : str
        The ``[job] kind`` value.
    seed : str
        Seed paper it reproduces (file stem in ``shared/seeds``).
    description : str
        One line for ``microfab kinds``.
    example : str
        Its example job file under ``examples/``.
    target : str
        ``"module:ATTRIBUTE"`` of its `JobKind`, imported only when the kind runs.
    """

    name: str
    seed: str
    description: str
    example: str
    target: str


@dataclass(frozen=True, kw_only=True)
class ReproductionEntry:
    """A reproduction as the registry lists it (see `KindEntry`)."""

    name: str
    seed: str
    description: str
    target: str


#: Every job kind, by name: what ``microfab kinds`` lists without loading any machine.
KIND_ENTRIES: dict[str, KindEntry] = {
    e.name: e
    for e in (
        KindEntry(
            name="msl-ilc",
            seed="000",
            example="galvo_msl_default.toml",
            target="microfab.experiments.seed000_msl.job:MSL_ILC",
            description=(
                "Galvo MSL (seed 000): a square at N features/s, feedback vs frequency-domain ILC "
                "on the calibrated twin"
            ),
        ),
        KindEntry(
            name="nanomanipulator-msl",
            seed="001",
            example="nanomanipulator_msl.toml",
            target="microfab.experiments.seed001_nanomanipulator.job:NANOMANIPULATOR_MSL",
            description=(
                "Flexure nanomanipulator MSL (seed 001): RBF adaptive control + plug-in RC on "
                "four circles, laser gate, warm-up compensation, cured lines"
            ),
        ),
        KindEntry(
            name="stage-identify",
            seed="002",
            example="blackbox_stage_identify.toml",
            target="microfab.experiments.seed002_stage.job:STAGE_IDENTIFY",
            description=(
                "Black-box XY stage (seed 002 part 1): excitation, 4-state subspace model, "
                "per-axis networks, Table II on the letters, Fig. 9, coupling and PRBS/chirp "
                "studies"
            ),
        ),
        KindEntry(
            name="stage-reference-opt",
            seed="002",
            example="blackbox_stage_reference.toml",
            target="microfab.experiments.seed002_reference.job:STAGE_REFERENCE_OPT",
            description=(
                "Black-box XY stage (seed 002 part 2): two-stage reference optimisation "
                "(minimum-time contouring on the linear model, network refinement), Table III on "
                "the letters and the airfoil, the precision-productivity trade-off"
            ),
        ),
        KindEntry(
            name="droplet-sweep",
            seed="003",
            example="droplet_sweep.toml",
            target="microfab.experiments.seed003_inkjet.job:DROPLET_SWEEP",
            description=(
                "Inkjet (seed 003 part 1): breakup time over NaAlg concentration (Fig. 4) and "
                "drive voltage, on worker processes or a Dask cluster"
            ),
        ),
        KindEntry(
            name="slm-shaping",
            seed="003",
            example="slm_shaping.toml",
            target="microfab.experiments.seed003_slm.job:SLM_SHAPING",
            description=(
                "SLM galvo scanner (seed 003 part 2): chirp identification, model-inverse and "
                "classic input shapers, jump validation, dynamics-aware layer and build scan time"
            ),
        ),
        KindEntry(
            name="laser-micromachining",
            seed="004",
            example="laser_micromachining.toml",
            target="microfab.experiments.seed004_laser.job:LASER_MICROMACHINING",
            description=(
                "Laser micromachining stage (seed 004): preview + DOB, contour compensator and "
                "baselines on a linear-motor XY twin; tracking, contour error, speed sweep"
            ),
        ),
    )
}

#: Every reproduction, by name.
REPRODUCTION_ENTRIES: dict[str, ReproductionEntry] = {
    e.name: e
    for e in (
        ReproductionEntry(
            name="msl-ilc",
            seed="000",
            target="microfab.experiments.seed000_msl.job:MSL_ILC_REPRODUCTION",
            description=(
                "Seed 000 Tables 1 and 2 and the loop margins at 100, 200, 400 features/s"
            ),
        ),
        ReproductionEntry(
            name="nanomanipulator",
            seed="001",
            target="microfab.experiments.seed001_nanomanipulator.job:NANOMANIPULATOR_REPRODUCTION",
            description=(
                "Seed 001 §4.2: axial and contour RMS, gate period, four circles on the twin"
            ),
        ),
        ReproductionEntry(
            name="stage-models",
            seed="002",
            target="microfab.experiments.seed002_stage.job:STAGE_MODELS_REPRODUCTION",
            description=(
                "Seed 002 Table II: the linear and the network models on their data and on the "
                "letters at 1 and 3 m/s², Fig. 9, the order check"
            ),
        ),
        ReproductionEntry(
            name="reference-opt",
            seed="002",
            target="microfab.experiments.seed002_reference.job:REFERENCE_OPT_REPRODUCTION",
            description=(
                "Seed 002 Table III, letter r and the airfoil, the trade-off (Figs. 16-17), on "
                "the models of a stage-identify job"
            ),
        ),
        ReproductionEntry(
            name="droplet-fig4",
            seed="003",
            target="microfab.experiments.seed003_inkjet.job:DROPLET_FIG4_REPRODUCTION",
            description=(
                "Seed 003 Fig. 4 and Fig. 2: first breakup of six NaAlg solutions at 50 V"
            ),
        ),
        ReproductionEntry(
            name="slm-shaper",
            seed="003",
            target="microfab.experiments.seed003_slm.job:SLM_SHAPER_REPRODUCTION",
            description=(
                "Seed 003 part 2: chirp fit, inverse shaper, lag/settling/speed, jump delay, "
                "lattice scan time"
            ),
        ),
        ReproductionEntry(
            name="laser-micromachining",
            seed="004",
            target="microfab.experiments.seed004_laser.job:LASER_REPRODUCTION",
            description=(
                "Seed 004: depth of focus, Fig. 3 tracking errors, Fig. 7 contour correction, "
                "Fig. 6 autofocus"
            ),
        ),
    )
}


def _load(entry: KindEntry | ReproductionEntry) -> Any:
    module, _, attr = entry.target.partition(":")
    obj = getattr(importlib.import_module(module), attr)
    if obj.name != entry.name:  # a registry line pointing at the wrong object
        raise LookupError(f"{entry.target} is {obj.name!r}, registered as {entry.name!r}")
    return obj


class _Lazy(Mapping[str, T]):
    """A read-only mapping of registered names that imports a value on first access."""

    def __init__(self, entries: Mapping[str, KindEntry | ReproductionEntry]) -> None:
        self._entries = entries
        self._loaded: dict[str, T] = {}

    def __getitem__(self, name: str) -> T:
        if name not in self._loaded:
            self._loaded[name] = _load(self._entries[name])
        return self._loaded[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)


#: Every job kind, by name, each imported when first looked up.
JOB_KINDS: Mapping[str, JobKind] = _Lazy(KIND_ENTRIES)
#: Every reproduction, by name, each imported when first looked up.
REPRODUCTIONS: Mapping[str, Reproduction] = _Lazy(REPRODUCTION_ENTRIES)


#: The kind of a job file whose ``[job]`` names none (job files written before kinds).
DEFAULT_KIND = "msl-ilc"


def job_kind(name: str) -> JobKind:
    """The job kind called ``name``.

    Raises
    ------
    KeyError
        Naming the known kinds.
    """
    if name not in KIND_ENTRIES:
        raise KeyError(f"unknown job kind {name!r} (known: {', '.join(sorted(KIND_ENTRIES))})")
    return JOB_KINDS[name]


def reproduction(name: str) -> Reproduction:
    """The reproduction called ``name``.

    Raises
    ------
    KeyError
        Naming the known reproductions.
    """
    if name not in REPRODUCTION_ENTRIES:
        known = ", ".join(sorted(REPRODUCTION_ENTRIES))
        raise KeyError(f"unknown reproduction {name!r} (known: {known})")
    return REPRODUCTIONS[name]


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
        out=file.out or Path("report") / kind.name,  # each kind its own default folder
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
