"""A calibration problem: a paper's numbers (targets), the free parameters and the model.

The problem is data only (TOPP-RA's split: problem here, algorithm in `solve`, results in
`report`). A **target** is one number of a paper that the twin should meet: its value, its
tolerance (the band within which it counts as met), its unit and where it comes from
(figure, table, section). A target's role is ``"fit"`` (the optimiser sees it) or
``"check"`` (held back: predicted and reported, never used to choose the parameters).
A **free parameter** has bounds that are physically sourced, or stated as assumed with the
reason. The **model** maps one parameter set to the model value of every target.

The residual of a target is ``(model - value) / tolerance``: ``|r| <= 1`` means met.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = [
    "CalibrationProblem",
    "FreeParameter",
    "Model",
    "Role",
    "Side",
    "Target",
]

Role = Literal["fit", "check"]
#: Which side of a target's value is met: ``"both"`` (the value within the tolerance),
#: ``"at least"`` (a floor: above the value is met, below it counts from the value) or
#: ``"at most"`` (a ceiling).
Side = Literal["both", "at least", "at most"]

#: The model: one parameter set (name -> value, in each parameter's unit) to the model
#: value of every target (name -> value, in each target's unit).
Model = Callable[[Mapping[str, float]], Mapping[str, float]]


def _finite(value: float, what: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{what} must be finite, got {out}")
    return out


def _text(value: str, what: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{what} must be a non-empty text")
    return value


@dataclass(frozen=True)
class Target:
    """One number the model should meet.

    Parameters
    ----------
    name : str
        Unique name, the key of the model's output.
    value : float
        The paper's value, in ``unit``.
    tolerance : float
        Half-width of the band within which the target is met, in ``unit``; > 0.
    unit : str
        Unit of ``value``, ``tolerance`` and the model value.
    source : str
        Where the number comes from (figure, table or section; a project target says so).
    role : {"fit", "check"}
        ``"fit"``: used to choose the parameters; ``"check"``: held back, only predicted.
    side : {"both", "at least", "at most"}
        ``"both"``: met within ``value ± tolerance``; ``"at least"`` / ``"at most"``: a
        bound (a paper's "generally below 0.5 µm"): the residual is 0 on the bound's good
        side and ``(model - value) / tolerance`` past it, so ``tolerance`` is the slack
        past the bound that still counts as met.
    """

    name: str
    value: float
    tolerance: float
    unit: str
    source: str
    role: Role = "fit"
    side: Side = "both"

    def __post_init__(self) -> None:
        _text(self.name, "a target's name")
        what = f"target {self.name!r}"
        object.__setattr__(self, "value", _finite(self.value, f"{what}: value"))
        tol = _finite(self.tolerance, f"{what}: tolerance")
        if tol <= 0.0:
            raise ValueError(f"{what}: tolerance must be > 0, got {tol}")
        object.__setattr__(self, "tolerance", tol)
        _text(self.source, f"{what}: source")
        if self.role not in ("fit", "check"):
            raise ValueError(f"{what}: role must be 'fit' or 'check', got {self.role!r}")
        if self.side not in ("both", "at least", "at most"):
            raise ValueError(
                f"{what}: side must be 'both', 'at least' or 'at most', got {self.side!r}"
            )

    @property
    def shown(self) -> str:
        """The paper's value as a table shows it: ``0.8``, ``>= 0.95``, ``<= 5``."""
        prefix = {"both": "", "at least": ">= ", "at most": "<= "}[self.side]
        return f"{prefix}{self.value:g}"

    def residual(self, model: float) -> float:
        """``(model - value) / tolerance`` on the wrong side: ``|r| <= 1`` is met.

        NaN if ``model`` is; 0 on the good side of a one-sided target.
        """
        r = (float(model) - self.value) / self.tolerance
        if (self.side == "at least" and r > 0.0) or (self.side == "at most" and r < 0.0):
            return 0.0
        return r


@dataclass(frozen=True)
class FreeParameter:
    """One parameter the calibration chooses, within bounds.

    Parameters
    ----------
    name : str
        Unique name, the key of the model's input.
    low, high : float
        Bounds, in ``unit``; ``low < high``, both finite, and both > 0 when ``log``.
    unit : str
        Unit of the value and the bounds.
    source : str
        Why these bounds: a physical source (seed file, equation, table), or
        ``"assumed: <why>"``.
    log : bool
        Search on a logarithmic scale (for a bound range of decades).
    """

    name: str
    low: float
    high: float
    unit: str
    source: str
    log: bool = False

    def __post_init__(self) -> None:
        _text(self.name, "a parameter's name")
        what = f"parameter {self.name!r}"
        low = _finite(self.low, f"{what}: low bound")
        high = _finite(self.high, f"{what}: high bound")
        if not low < high:
            raise ValueError(f"{what}: low bound {low} must be below high bound {high}")
        if self.log and low <= 0.0:
            raise ValueError(f"{what}: a log-scaled parameter needs bounds > 0, got low {low}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)
        _text(self.source, f"{what}: source")

    def value(self, u: float) -> float:
        """The value, in ``unit``, at normalised coordinate ``u`` in [0, 1]."""
        if self.log:
            lo, hi = math.log(self.low), math.log(self.high)
            return float(min(max(math.exp(lo + u * (hi - lo)), self.low), self.high))
        return float(self.low + u * (self.high - self.low))

    def normalised(self, value: float) -> float:
        """The normalised coordinate in [0, 1] of ``value`` (inverse of `value`)."""
        if self.log:
            lo, hi = math.log(self.low), math.log(self.high)
            return (math.log(value) - lo) / (hi - lo)
        return (value - self.low) / (self.high - self.low)


@dataclass(frozen=True)
class CalibrationProblem:
    """Targets, free parameters and the model that links them.

    Parameters
    ----------
    targets : sequence of Target
        Unique names; at least one with role ``"fit"``.
    parameters : sequence of FreeParameter
        Unique names; at least one.
    evaluate : callable
        ``evaluate({parameter: value}) -> {target: model value}``. It must return every
        target's name; a non-finite value is allowed (a diverging loop) and counts as far
        from every target. With ``workers > 1`` it must be picklable (a module-level
        function or a `functools.partial` of one).
    identity : str
        Anything else that identifies the model (a twin file's digest, a version): part of
        the `fingerprint`, so that a memo of another model is refused.
    """

    targets: Sequence[Target]
    parameters: Sequence[FreeParameter]
    evaluate: Model
    identity: str = ""
    _fit: tuple[int, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        targets = tuple(self.targets)
        parameters = tuple(self.parameters)
        for t in targets:
            if not isinstance(t, Target):
                raise ValueError(f"a target must be a Target, got {type(t).__name__}")
        for p in parameters:
            if not isinstance(p, FreeParameter):
                raise ValueError(f"a parameter must be a FreeParameter, got {type(p).__name__}")
        if not parameters:
            raise ValueError("a calibration problem needs at least one free parameter")
        for kind, names in (
            ("target", [t.name for t in targets]),
            ("parameter", [p.name for p in parameters]),
        ):
            dup = sorted({n for n in names if names.count(n) > 1})
            if dup:
                raise ValueError(f"{kind} names must be unique: {', '.join(dup)} repeated")
        fit = tuple(i for i, t in enumerate(targets) if t.role == "fit")
        if not fit:
            raise ValueError("a calibration problem needs at least one target with role 'fit'")
        if not callable(self.evaluate):
            raise ValueError("evaluate must be callable: parameters -> target model values")
        object.__setattr__(self, "targets", targets)
        object.__setattr__(self, "parameters", parameters)
        object.__setattr__(self, "_fit", fit)

    @property
    def fit_index(self) -> tuple[int, ...]:
        """Indices into `targets` of the fit targets."""
        return self._fit

    @property
    def target_names(self) -> tuple[str, ...]:
        """Target names, in order."""
        return tuple(t.name for t in self.targets)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Parameter names, in order."""
        return tuple(p.name for p in self.parameters)

    def values(self, u: Sequence[float]) -> dict[str, float]:
        """Parameter values (name -> value in its unit) at normalised point ``u``, shape (n,)."""
        return {p.name: p.value(float(x)) for p, x in zip(self.parameters, u, strict=True)}

    def model_vector(self, out: Mapping[str, float]) -> np.ndarray:
        """The model values of ``evaluate``'s output in `targets` order, shape (m,).

        Raises
        ------
        ValueError
            If a target's name is missing from ``out``.
        """
        missing = [n for n in self.target_names if n not in out]
        if missing:
            raise ValueError(f"the model returned no value for target(s) {', '.join(missing)}")
        vec = np.empty(len(self.targets))
        for i, name in enumerate(self.target_names):
            try:
                vec[i] = float(out[name])
            except (TypeError, ValueError):
                raise ValueError(
                    f"the model's value for target {name!r} is not a number: {out[name]!r}"
                ) from None
        return vec

    def residuals(self, model: np.ndarray) -> np.ndarray:
        """Every target's residual ``(model - value) / tolerance``, shape (m,)."""
        value = np.array([t.value for t in self.targets])
        tol = np.array([t.tolerance for t in self.targets])
        r = (np.asarray(model, dtype=float) - value) / tol
        floor = np.array([t.side == "at least" for t in self.targets])
        ceiling = np.array([t.side == "at most" for t in self.targets])
        r[floor & (r > 0.0)] = 0.0
        r[ceiling & (r < 0.0)] = 0.0
        return r

    def fingerprint(self) -> str:
        """SHA-256 of the parameter names, bounds and scales, the target names and `identity`.

        Target values, tolerances and roles are left out: they do not change what the model
        returns, so a memo of model values stays valid when they change.
        """
        spec = {
            "parameters": [[p.name, repr(p.low), repr(p.high), p.log] for p in self.parameters],
            "targets": list(self.target_names),
            "identity": self.identity,
        }
        return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()
