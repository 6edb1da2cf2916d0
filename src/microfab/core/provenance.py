"""Where a reproduced number comes from: an input from the paper, fitted to it, or predicted.

A reproduction sets our numbers beside a seed paper's. Such a match means something only
when the number was neither given to the twin (an *input*: a value in a twin's data file
whose ``_source`` cites the seed) nor made to match by a calibration (*fitted*: the target
of a ``microfab calibrate`` command whose result the data file holds). Everything else the
twin computes is *predicted*, and only predicted matches test the model.

The label of a table row is derived, never written by hand: the row declares what it
shows (`Shows`: the seed quantities its numbers are compared with, and the twin parameters
it prints), each calibration declares its targets (`Calibration`, in its own module), and
`microfab.machines.provenance` looks both up in the data files the twins read.

Quantity ids are plain strings made by `quantity` (``"seed 004 Fig. 3 / peak error"``),
shared by the calibration that fits the quantity and the rows that show it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

__all__ = [
    "LABEL_COLUMN",
    "ORIGINS",
    "Calibration",
    "Origin",
    "RowLabel",
    "Shows",
    "quantity",
]

#: What a row's numbers are: from the paper, fitted to it, or computed by the twin.
Origin = Literal["input", "fitted", "predicted", "mixed"]
#: The origins in the order a mixed row lists them.
ORIGINS: tuple[str, ...] = ("input", "fitted", "predicted")

#: Head of the column that carries each row's label in a comparison table.
LABEL_COLUMN = "ours is"


def quantity(seed: str, *parts: object) -> str:
    """The id of a quantity the seed publishes.

    Parameters
    ----------
    seed : str
        Seed number, e.g. ``"004"``.
    *parts
        Figure or table, then what within it (axis, row, column), most general first.

    Examples
    --------
    >>> quantity("000", "Table 1", "x", "fb_rms", 100)
    'seed 000 Table 1 / x / fb_rms / 100'
    """
    if not parts:
        raise ValueError("a quantity needs at least its figure or table")
    return f"seed {seed} " + " / ".join(str(p) for p in parts)


@dataclass(frozen=True)
class Calibration:
    """A calibration command and the published numbers it fits the twin to.

    Parameters
    ----------
    command : str
        The command that runs it, as its data file names it (``"microfab calibrate
        laser"``); a data file that contains this text holds the calibration's result.
    data_file : str
        The file under ``microfab/data`` the calibration writes.
    targets : frozenset of str
        Ids (`quantity`) of the published numbers it fits.
    what : str
        One line: the parameters it fits.
    checks : frozenset of str
        Ids of the published numbers it holds back: predicted by the calibrated twin and
        reported beside the targets, never used to choose the parameters. A row that shows
        one is labelled predicted.
    marker : str
        The text whose presence in ``data_file`` shows the file holds this calibration's
        result (default ``command``). Two calibrations by one command that wrote their
        sources differently (a retired fit and its successor) tell their files apart by it.
    """

    command: str
    data_file: str
    targets: frozenset[str]
    what: str = ""
    checks: frozenset[str] = frozenset()
    marker: str = ""

    def __post_init__(self) -> None:
        if not self.targets:
            raise ValueError(f"{self.command}: a calibration needs at least one target")
        object.__setattr__(self, "targets", frozenset(self.targets))
        object.__setattr__(self, "checks", frozenset(self.checks))
        both = sorted(self.targets & self.checks)
        if both:
            raise ValueError(
                f"{self.command}: {', '.join(both)} is both a target and a check; a number "
                "held back to check a fit cannot also be fitted"
            )


@dataclass(frozen=True)
class Shows:
    """What one row of a comparison table shows.

    Parameters
    ----------
    quantities : tuple of str
        Ids (`quantity`) of the seed's numbers that the row's numbers are compared with.
    parameters : tuple of (str, str)
        Twin parameters the row prints (or recovers, e.g. by identification): ``(data file,
        "section.key")`` (``"axes.x.mass_kg"``); the label is that value's ``_source``.
    from_seed : tuple of str
        Numbers the row computes from the seed's published numbers alone (no twin), each
        named by its citation: inputs.
    """

    quantities: tuple[str, ...] = ()
    parameters: tuple[tuple[str, str], ...] = ()
    from_seed: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "quantities", tuple(self.quantities))
        object.__setattr__(self, "parameters", tuple(tuple(p) for p in self.parameters))
        object.__setattr__(self, "from_seed", tuple(self.from_seed))


@dataclass(frozen=True)
class RowLabel:
    """The derived label of one row.

    Attributes
    ----------
    origin : {"input", "fitted", "predicted", "mixed"}
        ``"mixed"`` when the row's numbers have more than one origin.
    fitted : tuple of str
        Quantities of the row that a calibration fits.
    inputs : tuple of str
        Parameters (``"file: section.key"``) the row shows that come from the seed.
    by : tuple of str
        The calibrations that fitted ``fitted``.
    counts : dict of str to int
        Numbers of the row's items per origin.
    quantities : tuple of str
        Every seed quantity the row is compared with (`Shows.quantities`).
    """

    origin: Origin
    quantities: tuple[str, ...] = ()
    fitted: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    by: tuple[str, ...] = ()
    counts: Mapping[str, int] = field(default_factory=dict)

    @property
    def text(self) -> str:
        """The cell: ``"predicted"``, ``"fitted (microfab calibrate laser)"``, ..."""
        by = f" ({', '.join(b.removeprefix('microfab ') for b in self.by)})" if self.by else ""
        if self.origin == "fitted":
            return f"fitted{by}"
        if self.origin != "mixed":
            return self.origin
        parts = [
            f"{self.counts[o]} {o}{by if o == 'fitted' else ''}"
            for o in ORIGINS
            if self.counts.get(o)
        ]
        return ", ".join(parts)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready: origin, the fitted quantities and their calibrations, the inputs."""
        return {
            "label": self.origin,
            "text": self.text,
            "quantities": list(self.quantities),
            "fitted": list(self.fitted),
            "by": list(self.by),
            "inputs": list(self.inputs),
            "counts": dict(self.counts),
        }
