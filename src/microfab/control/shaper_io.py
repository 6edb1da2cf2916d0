"""Shapers as JSON: the model-inverse shaper and the classic impulse shapers, and back.

A shaper file is one JSON object with ``"format": 1`` and a ``"kind"``:

* ``"inverse"`` (`microfab.control.shaping.InverseShaper`): ``"model"``, the continuous
  model it inverts (`microfab.identify.model.TFModel.to_dict`), and ``"config"``, its
  `InverseShaperConfig` (``pole_hz``, ``order``, ``dt``, ``discretization``). It is rebuilt
  by `design_inverse_shaper` from those two, so that a file can never hold a filter that
  does not belong to its model. A ``"derived"`` block (continuous and discrete
  coefficients, preview, gain peak, lag) is written for readers and not read back.
* ``"impulse"`` (`microfab.control.shapers.ImpulseShaper`): ``"amplitudes"`` and
  ``"times_s"`` (kept as they are: a shaper solved numerically is not redesigned on
  reading), its design ``"name"``, ``"freq_hz"``, ``"damping"``, ``"v_tol"``, and
  ``"numeric"`` / ``"constraint_miss"`` (how it was designed).

Reading is strict: another format or kind, a missing or unknown key, a value of the wrong
type raise ValueError naming it. `shaper_lti` turns either into the discrete filter that a
command at ``dt`` goes through (`microfab.plants.lti.DiscreteLTI`), for
`microfab.process.slm.estimate.series`.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import scipy.signal
from pydantic import BaseModel, ConfigDict, Field

from microfab.control.shapers import ImpulseShaper
from microfab.control.shaping import InverseShaper, InverseShaperConfig, design_inverse_shaper
from microfab.identify.model import TFModel, TFModelDoc
from microfab.io.atomic import atomic_write_json
from microfab.io.filekinds import FILE_KINDS
from microfab.io.schema import SchemaError, read_json, validated
from microfab.plants.lti import DiscreteLTI

__all__ = [
    "FORMAT",
    "KINDS",
    "SHAPER_KIND",
    "ImpulseShaperDoc",
    "InverseShaperDoc",
    "Shaper",
    "read_shaper",
    "shaper_from_dict",
    "shaper_lti",
    "shaper_to_dict",
    "write_shaper",
]

#: Format number of a shaper file.
FORMAT = 1

#: The kinds a shaper file can hold.
KINDS = ("inverse", "impulse")

Shaper = InverseShaper | ImpulseShaper

_INVERSE_KEYS = {"format", "kind", "model", "config", "derived"}
_IMPULSE_KEYS = {
    "format",
    "kind",
    "name",
    "freq_hz",
    "damping",
    "v_tol",
    "amplitudes",
    "times_s",
    "numeric",
    "constraint_miss",
}
_IMPULSE_REQUIRED = ("name", "freq_hz", "damping", "amplitudes", "times_s")
_CONFIG_KEYS = ("pole_hz", "order", "dt", "discretization")


#: Most FIR taps an impulse shaper may have at the command's sample time. Assumed bound of
#: the work: its state-space filter is taps × taps (2000: 32 MB); at 10 µs it allows a
#: shaper 20 ms long, a ZV shaper for modes above 25 Hz (the galvos' modes are kHz).
MAX_FIR_TAPS = 2000


def _floats(a: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(a, dtype=float)]


def shaper_to_dict(shaper: Shaper) -> dict[str, Any]:
    """A shaper as a JSON-ready dict (module doc).

    Parameters
    ----------
    shaper : InverseShaper or ImpulseShaper
        The shaper.

    Returns
    -------
    dict
        ``{"format": 1, "kind": ..., ...}``; `shaper_from_dict` reads it back.

    Raises
    ------
    TypeError
        For anything else.
    """
    if isinstance(shaper, InverseShaper):
        model = TFModel(num=shaper.plant_num, den=shaper.plant_den)
        gain, at = shaper.gain_peak()
        return {
            "format": FORMAT,
            "kind": "inverse",
            "model": model.to_dict(),
            "config": asdict(shaper.config),
            "derived": {
                "num": _floats(shaper.num),
                "den": _floats(shaper.den),
                "num_d": _floats(shaper.num_d),
                "den_d": _floats(shaper.den_d),
                "preview": int(shaper.preview),
                "gain_peak": gain,
                "gain_peak_hz": at,
                "lag_s": shaper.lag(),
                "discrete_lag_s": shaper.lag(discrete=True),
            },
        }
    if isinstance(shaper, ImpulseShaper):
        return {
            "format": FORMAT,
            "kind": "impulse",
            "name": shaper.name,
            "freq_hz": float(shaper.freq_hz),
            "damping": float(shaper.damping),
            "v_tol": float(shaper.v_tol),
            "amplitudes": _floats(shaper.amplitudes),
            "times_s": _floats(shaper.times),
            "numeric": bool(shaper.numeric),
            "constraint_miss": float(shaper.constraint_miss),
        }
    raise TypeError(
        f"shaper_to_dict takes an InverseShaper or an ImpulseShaper, got {type(shaper).__name__}"
    )


# --------------------------------------------------------------------------- the schema
#: What `microfab.io.schema.read_json` calls a shaper file.
SHAPER_KIND = FILE_KINDS["shaper"].what
#: Most impulses of an impulse shaper read from a file. Assumed: the classic shapers have
#: 2 to 5 and a numerically solved one a few more; 64 refuses a list of samples.
MAX_IMPULSES = 64
_STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)


class InverseConfigDoc(BaseModel):
    """``config`` of an inverse shaper: `InverseShaperConfig` (pole in Hz, dt in s)."""

    model_config = _STRICT

    # assumed ranges: a pole above 1 GHz or a sample time above 1 s is a unit mistake
    pole_hz: float = Field(gt=0, le=1e9)
    order: int = Field(ge=0, le=16)  # assumed: the seed's is 4 (seed 003 §2)
    dt: float = Field(gt=0, le=1.0)
    discretization: Literal["zoh", "zpetc"]


class InverseShaperDoc(BaseModel):
    """An inverse shaper file (`shaper_to_dict` of an `InverseShaper`)."""

    model_config = _STRICT

    format: Literal[1]
    kind: Literal["inverse"]
    model: TFModelDoc
    config: InverseConfigDoc
    derived: dict[str, Any] | None = None


class ImpulseShaperDoc(BaseModel):
    """An impulse shaper file (`shaper_to_dict` of an `ImpulseShaper`); times in s."""

    model_config = _STRICT

    format: Literal[1]
    kind: Literal["impulse"]
    name: str = Field(min_length=1, max_length=200)
    freq_hz: float = Field(gt=0, le=1e9)  # assumed bound, as `InverseConfigDoc.pole_hz`
    damping: float = Field(ge=0, lt=1)  # an underdamped mode
    v_tol: float = Field(0.05, ge=0, le=1)  # a fraction of the vibration
    amplitudes: list[float] = Field(min_length=1, max_length=MAX_IMPULSES)
    times_s: list[Annotated[float, Field(ge=0, le=1e3)]] = Field(
        min_length=1, max_length=MAX_IMPULSES
    )
    numeric: bool = False
    constraint_miss: float = Field(0.0, ge=0)


def _number(d: dict[str, Any], key: str, where: str) -> float:
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{where} {key!r} must be a finite number, got {v!r}")
    return float(v)


def _numbers(d: dict[str, Any], key: str) -> np.ndarray:
    v = d[key]
    if (
        not isinstance(v, list)
        or not v
        or not all(isinstance(c, int | float) and not isinstance(c, bool) for c in v)
    ):
        raise ValueError(f"impulse shaper {key!r} must be a non-empty list of numbers, got {v!r}")
    return np.array(v, dtype=float)


def _check_keys(d: dict[str, Any], allowed: set[str], required: tuple[str, ...], what: str) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise ValueError(
            f"unknown key {unknown[0]!r} in the {what} (known: {', '.join(sorted(allowed))})"
        )
    for key in required:
        if key not in d:
            raise ValueError(f"the {what} has no {key!r}")


def _inverse(d: dict[str, Any]) -> InverseShaper:
    _check_keys(d, _INVERSE_KEYS, ("model", "config"), "inverse shaper")
    try:
        model = TFModel.from_dict(d["model"])
    except ValueError as exc:
        raise ValueError(f"inverse shaper 'model': {exc}") from None
    cfg = d["config"]
    if not isinstance(cfg, dict):
        raise ValueError(f"inverse shaper 'config' must be an object, got {cfg!r}")
    _check_keys(cfg, set(_CONFIG_KEYS), _CONFIG_KEYS, "inverse shaper's config")
    order = cfg["order"]
    if isinstance(order, bool) or not isinstance(order, int):
        raise ValueError(f"inverse shaper config 'order' must be an integer, got {order!r}")
    config = InverseShaperConfig(
        pole_hz=_number(cfg, "pole_hz", "inverse shaper config"),
        order=order,
        dt=_number(cfg, "dt", "inverse shaper config"),
        discretization=cfg["discretization"],
    )
    return design_inverse_shaper((model.num, model.den), config)


def _impulse(d: dict[str, Any]) -> ImpulseShaper:
    _check_keys(d, _IMPULSE_KEYS, _IMPULSE_REQUIRED, "impulse shaper")
    if not isinstance(d["name"], str):
        raise ValueError(f"impulse shaper 'name' must be a string, got {d['name']!r}")
    numeric = d.get("numeric", False)
    if not isinstance(numeric, bool):
        raise ValueError(f"impulse shaper 'numeric' must be true or false, got {numeric!r}")
    extra = {k: _number(d, k, "impulse shaper") for k in ("v_tol", "constraint_miss") if k in d}
    amplitudes = _numbers(d, "amplitudes")
    total = float(np.sum(amplitudes))
    if not abs(total - 1.0) <= 1e-6:
        raise ValueError(
            f"impulse shaper amplitudes sum to {total:.6g}, not 1: a shaped command would not "
            f"reach its target (it would end at {total:.6g} of it)"
        )
    return ImpulseShaper(
        name=d["name"],
        freq_hz=_number(d, "freq_hz", "impulse shaper"),
        damping=_number(d, "damping", "impulse shaper"),
        amplitudes=amplitudes,
        times=_numbers(d, "times_s"),
        numeric=numeric,
        **extra,
    )


def shaper_from_dict(d: dict[str, Any]) -> Shaper:
    """Read `shaper_to_dict`'s output.

    Returns
    -------
    InverseShaper or ImpulseShaper
        The inverse redesigned from its model and config; the impulse shaper as stored.

    Raises
    ------
    ValueError
        Not an object, another format (a model file, say) or kind, a missing or unknown
        key, a wrong type, or a model / config the design refuses.
    """
    if not isinstance(d, dict):
        raise ValueError(f"a shaper must be a JSON object, got {type(d).__name__}")
    fmt = d.get("format")
    if fmt != FORMAT or isinstance(fmt, bool):
        hint = " (a model file: design a shaper from it first)" if "num" in d else ""
        raise ValueError(f"not a shaper file of format {FORMAT}: its format is {fmt!r}{hint}")
    kind = d.get("kind")
    if kind == "inverse":
        return _inverse(d)
    if kind == "impulse":
        return _impulse(d)
    raise ValueError(f"unknown shaper kind {kind!r}; known: {', '.join(KINDS)}")


def write_shaper(path: str | os.PathLike[str], shaper: Shaper) -> None:
    """Write `shaper_to_dict` of ``shaper`` to ``path`` as JSON, atomically."""
    atomic_write_json(path, shaper_to_dict(shaper))


def read_shaper(path: str | os.PathLike[str]) -> Shaper:
    """Read a shaper file through its schema (`InverseShaperDoc`, `ImpulseShaperDoc`).

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        (`microfab.io.schema.SchemaError` for the first three) Not JSON (or nested too
        deeply), a file of another kind (named), a field of the wrong type, length or
        range; or not a valid shaper (see `shaper_from_dict`). The line names the file.
    """
    p = Path(path)
    try:
        data = read_json(p, SHAPER_KIND)
    except FileNotFoundError:
        raise FileNotFoundError(f"shaper file not found: {p}") from None
    kind = data.get("kind") if isinstance(data, dict) else None
    if isinstance(data, dict) and data.get("format") != FORMAT and "num" not in data:
        raise SchemaError(f"{p}: not a shaper file of format {FORMAT}: its format is "
                          f"{data.get('format')!r}")  # fmt: skip
    if kind in ("inverse", "impulse"):
        validated(InverseShaperDoc if kind == "inverse" else ImpulseShaperDoc, data, str(p))
    try:
        return shaper_from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


def shaper_lti(shaper: Shaper, dt: float) -> DiscreteLTI:
    """The shaper as the discrete filter a command sampled every ``dt`` goes through.

    The inverse shaper's own filter (its ``dt`` must be ``dt``; a ZPETC filter's preview
    is a delay of ``preview`` samples here); an impulse shaper's FIR `ImpulseShaper.taps`
    at ``dt`` (linear interpolation of each impulse), as a state-space model.

    Raises
    ------
    ValueError
        An inverse shaper designed for another sample time.
    """
    if isinstance(shaper, InverseShaper):
        if abs(shaper.dt - dt) > 1e-9 * dt:
            raise ValueError(
                f"the inverse shaper was designed for dt = {shaper.dt:g} s, the command is "
                f"sampled every {dt:g} s: design it for {dt:g} s"
            )
        return shaper.to_lti()
    n_taps = shaper.duration / dt + 1 if np.isfinite(shaper.duration) else np.inf
    if not n_taps <= MAX_FIR_TAPS:
        raise ValueError(
            f"a shaper {shaper.duration:g} s long at dt = {dt:g} s is {n_taps:.3g} taps; the "
            f"most is {MAX_FIR_TAPS} (its filter has as many states): a shaper for a mode "
            f"above {1.0 / (2.0 * MAX_FIR_TAPS * dt):.3g} Hz, or check its times_s"
        )
    h = shaper.taps(dt)
    if h.size == 1:  # a pure gain: one state that the output ignores
        return DiscreteLTI(
            np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1)), h.reshape(1, 1), dt
        )
    den = np.zeros(h.size)
    den[0] = 1.0
    A, B, C, D = scipy.signal.tf2ss(h, den)
    return DiscreteLTI(A, B, C, D, dt)
