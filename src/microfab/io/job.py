"""Job files (TOML): what `microfab run` does.

Example (the shipped default, ``microfab/data/default_job.toml``)::

    [job]
    kind = "msl-ilc"          # galvo MSL, feedback vs ILC (seed 000)
    out = "report"            # report folder, relative to the working directory

    [scan]
    rate_hz = 400             # features (laps of the 0.6 mm square) per second
    iterations = 30           # ILC trials; trial 1 is feedback only
    learning_rates = [100, 200, 400]   # rates whose learning curves are drawn (Fig. 6)

    [ilc]
    cutoff_hz = 8000.0        # highest learned harmonic, Hz
    gain = 0.4                # learning gain rho

    [twin]
    seed = 0                  # encoder-noise seed
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from microfab.control.ilc import ILCConfig

__all__ = ["MSLJob", "default_job", "load_job"]

_SECTIONS = {
    "job": {"kind", "out", "name"},
    "scan": {"rate_hz", "iterations", "learning_rates"},
    "ilc": {"cutoff_hz", "gain", "snr_min"},
    "twin": {"seed"},
}


@dataclass(frozen=True, kw_only=True)
class MSLJob:
    """A galvo-MSL ILC job.

    Parameters
    ----------
    name : str
        Title of the report.
    out : Path
        Report folder.
    rate_hz : int
        Main scan rate, features/s.
    iterations : int
        ILC trials.
    learning_rates : tuple of int
        Rates whose learning transients are run and drawn.
    ilc : ILCConfig
        Learning settings.
    seed : int
        Twin noise seed.
    """

    name: str = "galvo MSL: feedback vs ILC"
    out: Path = Path("report")
    rate_hz: int = 400
    iterations: int = 30
    learning_rates: tuple[int, ...] = (400,)
    ilc: ILCConfig = field(default_factory=ILCConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        if self.rate_hz <= 0 or 1_000_000 % self.rate_hz:
            raise ValueError(
                f"rate_hz must divide the 1 MHz sample rate, got {self.rate_hz} features/s"
            )
        if self.iterations < 2:
            raise ValueError(f"iterations must be >= 2, got {self.iterations}")
        for r in self.learning_rates:
            if r <= 0 or 1_000_000 % r:
                raise ValueError(f"learning rate {r} features/s must divide 1 MHz")


def _parse(data: dict[str, Any], source: str) -> MSLJob:
    for sec, body in data.items():
        if sec not in _SECTIONS:
            raise ValueError(f"{source}: unknown section [{sec}] (known: {sorted(_SECTIONS)})")
        if not isinstance(body, dict):
            raise ValueError(f"{source}: [{sec}] must be a table")
        unknown = set(body) - _SECTIONS[sec]
        if unknown:
            raise ValueError(f"{source}: unknown key(s) {sorted(unknown)} in [{sec}]")
    job = data.get("job", {})
    kind = job.get("kind", "msl-ilc")
    if kind != "msl-ilc":
        raise ValueError(f"{source}: job kind {kind!r} is not supported (known: 'msl-ilc')")
    scan, ilc, twin = data.get("scan", {}), data.get("ilc", {}), data.get("twin", {})
    rate = int(scan.get("rate_hz", 400))
    try:
        return MSLJob(
            name=str(job.get("name", MSLJob.name)),
            out=Path(job.get("out", "report")),
            rate_hz=rate,
            iterations=int(scan.get("iterations", 30)),
            learning_rates=tuple(int(r) for r in scan.get("learning_rates", [rate])),
            ilc=ILCConfig(**ilc),
            seed=int(twin.get("seed", 0)),
        )
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{source}: {exc}") from exc


def load_job(path: str | Path) -> MSLJob:
    """Read and validate a job file.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Invalid TOML, unknown sections or keys, or invalid values.
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{p}: not valid TOML: {exc}") from exc
    return _parse(data, str(p))


def default_job() -> MSLJob:
    """The shipped default job (``microfab/data/default_job.toml``)."""
    text = resources.files("microfab.data").joinpath("default_job.toml").read_text()
    return _parse(tomllib.loads(text), "default_job.toml")
