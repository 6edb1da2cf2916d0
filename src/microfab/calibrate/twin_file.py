"""Write a calibration's answer into a twin's sourced data file, naming its targets.

A twin data file (``microfab/data/*.toml``) holds every value with a ``<key>_source``
line. A calibrated value's source says ``calibrated: `<command>` ...`` (the form
`microfab.machines.provenance` reads: a file that names the command holds the
calibration) and names the targets the value was fitted to, the checks held back, and
whether every fit target was met. `write_calibrated` replaces the values and sources in
place (`microfab.plants.sourced_toml.update_sourced`: comments and other values kept)
and writes the file atomically: a refused update writes nothing.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from microfab.calibrate.report import CalibrationResult
from microfab.io.atomic import atomic_write_text
from microfab.plants.sourced_toml import update_sourced

__all__ = ["TwinKey", "calibrated_source", "twin_updates", "write_calibrated"]


@dataclass(frozen=True)
class TwinKey:
    """Where a free parameter's value goes in the twin's data file.

    Parameters
    ----------
    parameter : str
        The free parameter's name (`microfab.calibrate.FreeParameter.name`).
    section : str
        TOML section as written in its header (``"disturbance"``, ``"axes.x"``).
    key : str
        Key in that section (its ``<key>_source`` line must exist too).
    scale : float
        File value = parameter value × ``scale`` (a unit change, e.g. 1e-6 from nm to mm).
    digits : int
        Significant digits written (the fit's own resolution is coarser than this).
    """

    parameter: str
    section: str
    key: str
    scale: float = 1.0
    digits: int = 5

    def __post_init__(self) -> None:
        if not math.isfinite(self.scale) or self.scale == 0.0:
            raise ValueError(f"{self.parameter}: scale must be finite and non-zero")
        if not 1 <= self.digits <= 17:
            raise ValueError(f"{self.parameter}: digits must be in 1..17, got {self.digits}")


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _short(names: Sequence[str]) -> str:
    return "; ".join(names) if names else "none"


def calibrated_source(result: CalibrationResult, command: str, parameter: str) -> str:
    """The ``_source`` line of one calibrated value.

    Parameters
    ----------
    result : CalibrationResult
        The calibration.
    command : str
        The command that ran it (``"microfab calibrate laser"``).
    parameter : str
        The parameter whose value the line describes.

    Returns
    -------
    str
        ``"calibrated: `<command>` ..."``: the fit targets (with their residuals), the
        targets this parameter pins, the checks held back (met or not) and whether the
        calibration converged (every fit target met, measured on the answer).
    """
    fit = [t for t in result.targets if t.role == "fit"]
    checks = [t for t in result.targets if t.role == "check"]
    pinned = [t.name for t in result.targets if parameter in t.pinned_by]
    state = "every fit target met" if result.converged else "NOT every fit target met"
    row = next(p for p in result.parameters if p.name == parameter)
    bound = f"; at its {row.at_bound} bound" if row.at_bound else ""
    return (
        f"calibrated: `{command}` fits {parameter} jointly to "
        + _short(
            [f"{t.name} ({t.model:.4g} {t.unit} for {t.value:g}, r {t.residual:+.2f})" for t in fit]
        )
        + f"; pins {_short(pinned)}; checks held back: "
        + _short(
            [f"{t.name} ({t.model:.4g} {t.unit} for {t.value:g}, {_met(t.met)})" for t in checks]
        )
        + f"; {state}{bound} (seed {result.seed}, {result.requested} evaluations)"
    )


def twin_updates(
    result: CalibrationResult, keys: Sequence[TwinKey], command: str
) -> dict[tuple[str, str], tuple[float, str]]:
    """The ``(section, key) -> (value, source)`` updates of `update_sourced`.

    Raises
    ------
    ValueError
        A key names a parameter the result does not hold.
    """
    values = result.values
    out: dict[tuple[str, str], tuple[float, str]] = {}
    for k in keys:
        if k.parameter not in values:
            raise ValueError(f"the calibration has no parameter {k.parameter!r}")
        v = float(f"{values[k.parameter] * k.scale:.{k.digits}g}")
        out[(k.section, k.key)] = (v, calibrated_source(result, command, k.parameter))
    return out


def write_calibrated(
    result: CalibrationResult,
    keys: Sequence[TwinKey],
    *,
    command: str,
    data_file: str,
    path: str | os.PathLike[str],
    source: str | os.PathLike[str] | None = None,
) -> Path:
    """Write the twin data file with the calibrated values (atomically).

    Parameters
    ----------
    result : CalibrationResult
        The calibration.
    keys : sequence of TwinKey
        Where each calibrated parameter goes.
    command : str
        The command named in each source.
    data_file : str
        The packaged file's name (``"lmw_stage.toml"``), read when ``source`` is None.
    path : path-like
        Where to write (may be ``source`` itself).
    source : path-like, optional
        The data file to start from.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        As `update_sourced` (unknown section or key, a result that does not read back);
        nothing is written then.
    """
    text = update_sourced(source, data_file, twin_updates(result, keys, command))
    out = Path(path)
    atomic_write_text(out, text)
    return out
