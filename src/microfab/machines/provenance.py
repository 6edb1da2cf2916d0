"""Labels of reproduced numbers, derived from the twins' data files and the calibrations.

Every calibration declares the published numbers it fits (`Calibration`, a ``CALIBRATION``
in its module; the registry `CALIBRATION_MODULES` lists them). A calibration *holds* when the
data file it writes names its command (the ``calibrated: `microfab calibrate ...` `` sources,
notes and headers the calibrations write); one whose file was reset to assumed values
labels nothing fitted. `label` then gives a row (`Shows`) its `RowLabel`:

* a twin parameter the row shows is an **input** when its ``_source`` cites the seed,
  **fitted** when it says ``calibrated``;
* a seed quantity the row compares with is **fitted** when a holding calibration targets
  it, else **predicted**;
* a row of several origins is **mixed** and counts them.

See `microfab.core.provenance` for the vocabulary.
"""

from __future__ import annotations

import functools
import importlib
import tomllib
from collections.abc import Collection, Iterable
from typing import Any

from microfab.core.provenance import Calibration, RowLabel, Shows
from microfab.data import read_text as read_data_text

__all__ = [
    "CALIBRATION_MODULES",
    "calibrations",
    "holds",
    "label",
    "labels",
    "parameter_source",
]

#: Modules that define a ``CALIBRATION`` (or a tuple ``CALIBRATIONS``): every fit of a twin
#: to a seed's published numbers.
CALIBRATION_MODULES: tuple[str, ...] = (
    "microfab.machines.galvo.calibration",
    "microfab.machines.nanomanipulator.calibration",
    "microfab.machines.xy_stage.calibration",
    "microfab.machines.xy_stage.calibration_core",
    "microfab.machines.xy_stage.cases",
    "microfab.machines.printhead.calibration",
    "microfab.machines.laser_stage.calibration",
)


@functools.cache
def calibrations() -> tuple[Calibration, ...]:
    """Every calibration the modules of `CALIBRATION_MODULES` declare."""
    out: list[Calibration] = []
    for name in CALIBRATION_MODULES:
        mod = importlib.import_module(name)
        found = getattr(mod, "CALIBRATIONS", None) or (getattr(mod, "CALIBRATION", None),)
        for cal in found:
            if not isinstance(cal, Calibration):
                raise TypeError(f"{name} declares no Calibration (CALIBRATION or CALIBRATIONS)")
            out.append(cal)
    return tuple(out)


def _data_text(name: str) -> str:
    return read_data_text(name)  # shared with the twins' loaders: one read per content


def holds(cal: Calibration) -> bool:
    """Whether the shipped data file holds ``cal``'s result (its command is named there).

    A calibration run at every run (``data_file`` empty) always holds. The text looked for
    is the calibration's ``marker`` when it has one (a retired fit and its successor by one
    command), else its command.
    """
    return not cal.data_file or (cal.marker or cal.command) in _data_text(cal.data_file)


def parameter_source(data_file: str, key: str) -> str:
    """The ``_source`` string of ``key`` (``"section.sub.name"``) in a data file.

    Raises
    ------
    KeyError
        The file has no such value or no source for it.
    """
    table: Any = tomllib.loads(_data_text(data_file))
    *path, name = key.split(".")
    for part in path:
        if not isinstance(table, dict) or part not in table:
            raise KeyError(f"{data_file}: no section {'.'.join(path)!r}")
        table = table[part]
    src = table.get(f"{name}_source") if isinstance(table, dict) else None
    if not isinstance(src, str):
        raise KeyError(f"{data_file}: {key} has no _source")
    return src


def _parameter_origin(data_file: str, key: str) -> str:
    src = parameter_source(data_file, key).strip().lower()
    if src.startswith("seed"):
        return "input"
    if src.startswith("calibrated"):
        return "fitted"
    raise ValueError(
        f"{data_file}: {key} is {src[:40]!r}...; a row compared with the seed may show a "
        "value taken from the seed or calibrated, not an assumed one"
    )


def label(shows: Shows, *, not_applied: Collection[str] = ()) -> RowLabel:
    """The label of one row.

    Parameters
    ----------
    shows : Shows
        What the row shows.
    not_applied : collection of str
        Commands of calibrations this run did not use (e.g. a twin run with its assumed
        magnitudes); their targets count as predicted.
    """
    # only the data files of calibrations that target this row are read: a run's labels
    # depend on nothing it has not read for its twin
    wanted = set(shows.quantities)
    targets: dict[str, list[str]] = {}
    for cal in calibrations():
        hit = wanted & cal.targets
        if hit and cal.command not in not_applied and holds(cal):
            for q in hit:
                targets.setdefault(q, []).append(cal.command)
    counts = {"input": 0, "fitted": 0, "predicted": 0}
    fitted: list[str] = []
    inputs: list[str] = []
    by: list[str] = []
    for data_file, key in shows.parameters:
        origin = _parameter_origin(data_file, key)
        counts[origin] += 1
        (inputs if origin == "input" else fitted).append(f"{data_file}: {key}")
    for cite in shows.from_seed:
        counts["input"] += 1
        inputs.append(cite)
    for q in shows.quantities:
        if q in targets:
            counts["fitted"] += 1
            fitted.append(q)
            by += [c for c in targets[q] if c not in by]
        else:
            counts["predicted"] += 1
    used = [o for o, n in counts.items() if n]
    origin = used[0] if len(used) == 1 else ("predicted" if not used else "mixed")
    return RowLabel(
        origin=origin,  # type: ignore[arg-type]
        quantities=shows.quantities,
        fitted=tuple(fitted),
        inputs=tuple(inputs),
        by=tuple(by),
        counts={k: v for k, v in counts.items() if v},
    )


def labels(rows: Iterable[Shows], *, not_applied: Collection[str] = ()) -> tuple[RowLabel, ...]:
    """`label` of each row."""
    return tuple(label(s, not_applied=not_applied) for s in rows)
