"""The data of the frequency-domain ILC (`microfab.control.ilc`): settings, trials, state.

`ILCConfig` (the learning settings of seed 000 §4), `Trial` (one measured period),
`ConvergenceError` (a gain that breaks seed 000 eq. 5), the update laws `Law`, the model
type `FRFModel`, the learner's mutable `_State`, and the encoding of NumPy arrays in the
JSON metadata of a saved state (`_arrays_out`, `_arrays_in`). They are apart from the
learner `~microfab.control.ilc.FrequencyILC`, which uses them and re-exports them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from microfab.core.validate import check_in_range, check_nonnegative, check_positive

__all__ = ["ConvergenceError", "FRFModel", "ILCConfig", "Law", "Trial"]

#: Key of the placeholder that stands for an array of ``meta`` in the saved JSON.
_ARRAY_KEY = "__array__"


class ConvergenceError(ValueError):
    """The learning gain violates the monotonic convergence condition, seed 000 eq. (5)."""


Law = Literal["inverse", "p-type"]


@dataclass(frozen=True, kw_only=True)
class ILCConfig:
    """Settings of the frequency-domain ILC.

    Parameters
    ----------
    cutoff_hz : float
        Highest harmonic frequency learned, Hz (seed 000 §4: 8 kHz).
    gain : float
        Learning gain rho (seed 000 §4: 0.4), in (0, 2].
    snr_min : float
        Output-to-noise magnitude ratio a harmonic needs in the first trial to be learned.
    content_tol : float
        Relative input magnitude below which a harmonic counts as empty.
    axis_gains : mapping of str to float, optional
        Learning gain per axis name, overriding ``gain`` for the axes it names (each in
        (0, 2]); e.g. ``{"y": 0.2}`` for a slower, lightly damped axis.
    law : {"inverse", "p-type"}
        ``"inverse"``: seed 000 eqs. (2), (7), the inverse of the first trial (or of a
        given model). ``"p-type"``: ``U + rho e^{j 2 pi f tau} E`` on the same harmonics,
        the time-advanced proportional update that needs no model (as ScanImage's
        scanner learning does); for comparison.
    advance_s : float, optional
        The P-type time advance ``tau``, s; default (None): the lag of the first trial's
        output behind its input, by circular cross-correlation.
    monitor : bool
        Watch for divergence: when an axis's RMS error grows by more than
        ``monitor_growth`` in two consecutive trials, its next input is the best one
        seen, and the gain of the harmonics whose error grew is halved (said in
        `FrequencyILC.events` and kept in the state).
    monitor_growth : float
        Relative growth of the RMS error that counts, > 0 (default 10 %: above the
        trial-to-trial scatter of a noise-limited error).
    """

    cutoff_hz: float = 8000.0  # seed 000 §4: harmonics up to 8 kHz
    gain: float = 0.4  # seed 000 §4: rho = 0.4
    snr_min: float = 3.0
    content_tol: float = 1e-6
    axis_gains: Mapping[str, float] | None = None
    law: Law = "inverse"
    advance_s: float | None = None
    monitor: bool = True
    monitor_growth: float = 0.1  # assumed: see the docstring

    def __post_init__(self) -> None:
        check_positive("cutoff_hz", self.cutoff_hz, "Hz")
        check_in_range("gain", self.gain, 0.0, 2.0, low_closed=False)
        if not (self.snr_min >= 0 and self.content_tol >= 0):
            raise ValueError("snr_min and content_tol must be >= 0")
        if self.axis_gains is not None:
            gains = dict(self.axis_gains)
            for name, g in gains.items():
                check_in_range(f"axis gain of {name!r}", g, 0.0, 2.0, low_closed=False)
            object.__setattr__(self, "axis_gains", gains)
        if self.law not in ("inverse", "p-type"):
            raise ValueError(f"law must be 'inverse' or 'p-type', got {self.law!r}")
        if self.advance_s is not None:
            check_nonnegative("advance_s", self.advance_s, "s")
        check_positive("monitor_growth", self.monitor_growth)

    def gain_of(self, axis: str) -> float:
        """The learning gain of ``axis`` (``axis_gains`` or ``gain``)."""
        return float((self.axis_gains or {}).get(axis, self.gain))


@dataclass(frozen=True, kw_only=True, eq=False)
class Trial:
    """One measured period of a periodic task.

    Attributes
    ----------
    dt : float
        Sample time, s.
    reference : numpy.ndarray
        Desired output ``y_d``, shape (N, n_axes).
    input : numpy.ndarray
        Input ``u_i`` applied to the stabilised machine, shape (N, n_axes).
    output : numpy.ndarray
        Measured output ``y_i`` (steady state), shape (N, n_axes).
    axes : tuple of str
        Axis names.
    """

    dt: float
    reference: np.ndarray
    input: np.ndarray
    output: np.ndarray
    axes: tuple[str, ...]

    @property
    def error(self) -> np.ndarray:
        """``y_i - y_d``, shape (N, n_axes)."""
        return self.output - self.reference


FRFModel = Callable[[np.ndarray], np.ndarray]
"""A model ``P(f)``: frequencies (n_f,) in Hz -> complex response (n_f, n_axes)."""


@dataclass(eq=False)
class _State:
    iteration: int = 0  # trials learned from so far
    dt: float = 0.0
    axes: tuple[str, ...] = ()
    reference: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    inputs: list[np.ndarray] = field(default_factory=list)  # u_1, u_2, ..., u_{i+1}
    pinv: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), complex))
    mask: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    rms: list[list[float]] = field(default_factory=list)
    pp: list[list[float]] = field(default_factory=list)
    meta: dict[str, object] = field(default_factory=dict)
    # format 3: per-harmonic gain, the model at the harmonics, the monitor's memory
    gain: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    model_frf: np.ndarray | None = None
    recent_errors: list[np.ndarray] = field(default_factory=list)  # |E| of the last trials
    best_input: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    best_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    events: list[str] = field(default_factory=list)


def _arrays_out(obj: object, arrays: dict[str, np.ndarray]) -> object:
    """``obj`` with each NumPy array replaced by a placeholder naming it in ``arrays``.

    Dicts and lists are walked; an array is added to ``arrays`` (not copied) under the
    name ``meta_array_<k>``, and ``{"__array__": name}`` takes its place.
    """
    if isinstance(obj, np.ndarray):
        name = f"meta_array_{len(arrays)}"
        arrays[name] = obj
        return {_ARRAY_KEY: name}
    if isinstance(obj, Mapping):
        return {k: _arrays_out(v, arrays) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_arrays_out(v, arrays) for v in obj]
    return obj


def _arrays_in(obj: object, data: Mapping[str, np.ndarray]) -> object:
    """Inverse of `_arrays_out`: placeholders replaced by the members they name.

    Raises
    ------
    KeyError
        A placeholder names no member of ``data``.
    """
    if isinstance(obj, dict):
        if set(obj) == {_ARRAY_KEY} and isinstance(obj[_ARRAY_KEY], str):
            name = obj[_ARRAY_KEY]
            if name not in data:
                raise KeyError(f"meta names the array {name!r}, which the file lacks")
            return data[name]
        return {k: _arrays_in(v, data) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_arrays_in(v, data) for v in obj]
    return obj
