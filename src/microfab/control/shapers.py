"""Classic impulse shapers (ZV, ZVD, MZV, EI, 2-hump EI, 3-hump EI) and their residual vibration.

A shaper is a train of impulses, amplitudes ``A_i`` (sum 1) at times ``T_i`` (``T_0 = 0``),
convolved with the command. Its **residual vibration** at a mode of natural frequency
``f`` and damping ``zeta`` is Singer and Seering's (ASME J. Dyn. Syst. 112, 1990; seed 003
part 2 ref. [10])::

    V(f, zeta) = |sum_i A_i exp(zeta w (T_i - T_n)) exp(j w_d T_i)| / sum_i A_i,

``w = 2 pi f``, ``w_d = w sqrt(1 - zeta^2)``, ``T_n`` the last impulse: the vibration left
after the shaped step over that of a plain step issued at ``T_n``. (The same form as
Klipper's ``_estimate_shaper``; `microfab.control.shaping_metrics.filter_vibration`
compares at equal times instead, which differs by ``exp(-zeta w T_n)``.)

**Registry.** `SHAPERS` maps each name to a `ShaperForm`: a pure closed form
``(freq_hz, damping, v_tol) -> (A, T)`` (Klipper's ``shaper_defs`` forms, whose
frequency is the undamped natural frequency), the damping up to which Klipper uses that
form, and for the EI family the constraints that define the shaper:

* ZV, ZVD, MZV: zeros of ``V`` placed exactly for any ``zeta < 1`` (MZV is Klipper's
  three-impulse one: the undamped zeros at ``f`` spaced by ``3/4`` of a damped period).
* EI (3 impulses): ``V = v_tol`` with zero slope at ``f`` (a hump), two zeros around it.
* 2-hump EI (4 impulses): ``V = 0`` at ``f``, two humps of height ``v_tol``, two zeros outside.
* 3-hump EI (5 impulses): a hump of ``v_tol`` at ``f``, two side humps, four zeros.

``v_tol = 0.05`` (5 %) by default, Klipper's ``1 / SHAPER_VIBRATION_REDUCTION``. The
registry and ``V`` live in `microfab.control.shaper_forms` (below this module and the
numerical solver `microfab.control.shaper_solve`) and are re-exported here.

**Where the closed forms miss.** Klipper's EI-family forms are polynomial fits in
``zeta`` for small damping (Klipper uses them up to ``zeta = 0.4``, 0.3, 0.2). At larger
damping they miss their own constraints: at ``zeta = 0.5`` the EI gives ``V(f) = 4.09 %``
instead of 5 % and does not reach its zeros (2.2 %, 1.2 %), the 2-hump EI gives
16.6 % instead of 0 with a negative amplitude, the 3-hump EI 371 % (both with impulse
times out of order). (The issue text says
"0.38 %" for the EI; the form as Klipper writes it gives 4.09 %, see the tests.)
`design_shaper` (``method="auto"``) therefore checks the closed form -- amplitudes >= 0,
``|V(f) - target| <= closed_form_tol`` (0.5 % points) and ``zeta`` within Klipper's
range -- and otherwise **solves the constraints numerically** (``scipy.optimize.root``,
Powell's hybrid method, on amplitudes, times, and the unknown frequencies of the zeros and
side humps, in time units of ``1/f``), continued in ``zeta`` from the exact undamped
shaper in steps of at most 0.05, and flags the result (``ImpulseShaper.numeric``). The
families end where their structure does: EI near ``zeta = 0.69``, 2-hump EI near 0.448,
3-hump EI near 0.276 (for ``v_tol = 0.05``); beyond that `design_shaper` refuses, naming
the largest damping reached.

**On a sampled command** (`ImpulseShaper.taps`): an impulse at ``T_i = (k + r) dt``
(``0 <= r < 1``) either goes to the nearest sample (``method="round"``, halves to even as
``numpy.rint``) or is split linearly, ``(1 - r) A_i`` on sample ``k`` and ``r A_i`` on
``k + 1`` (``method="interpolate"``, the default: a linearly interpolated delay, which
keeps the sum and the centroid, i.e. the added delay, exactly).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from microfab.control.shaper_forms import (
    DEFAULT_V_TOL,
    SHAPER_NAMES,
    SHAPERS,
    ShaperForm,
    ShaperName,
    residual_vibration,
)
from microfab.control.shaper_solve import numeric_unit
from microfab.control.shaping import Bounds, filter_command, shaped_trajectory
from microfab.core.arrays import readonly
from microfab.core.limits import AxisLimits
from microfab.core.threads import one_blas_thread
from microfab.core.validate import check_in_range, check_positive
from microfab.trajectory.base import Trajectory

__all__ = [
    "DEFAULT_V_TOL",
    "MAX_TAPS",
    "SHAPERS",
    "SHAPER_NAMES",
    "ImpulseShaper",
    "ShaperForm",
    "ShaperName",
    "design_shaper",
    "residual_vibration",
]

#: Most FIR taps `ImpulseShaper.taps` builds (assumed 2**24: 168 s at the seed's 10 µs, far
#: longer than any shaper of a mode that sampling can see; a shorter dt or a mode near
#: 0 Hz would otherwise allocate without bound).
MAX_TAPS = 2**24
#: Longest period of a mode `design_shaper` accepts, s (assumed 1e200 s: far beyond any
#: mode, and the impulse times, a few periods, stay finite in float64).
_MAX_PERIOD_S = 1e200


@dataclass(frozen=True, kw_only=True, eq=False)
class ImpulseShaper:
    """An impulse shaper for one mode (build it with `design_shaper`, or give your own).

    Attributes
    ----------
    name : str
        Registry name (or your label).
    freq_hz : float
        Design natural frequency, Hz.
    damping : float
        Design damping ratio.
    amplitudes : numpy.ndarray
        Impulse amplitudes, shape (n,), finite, sum > 0 (the registry's sum to 1).
    times : numpy.ndarray
        Impulse times, s, shape (n,), starting at 0, non-decreasing.
    v_tol : float
        Vibration tolerance of the EI family (ignored by ZV, ZVD, MZV).
    numeric : bool
        True where the constraints were solved numerically (the closed form missed them).
    constraint_miss : float
        ``|V(f) - target|`` of the returned shaper (target 0 or ``v_tol``).
    """

    name: str
    freq_hz: float
    damping: float
    amplitudes: np.ndarray
    times: np.ndarray
    v_tol: float = DEFAULT_V_TOL
    numeric: bool = False
    constraint_miss: float = 0.0

    def __post_init__(self) -> None:
        check_positive("freq_hz", self.freq_hz, "Hz")
        check_in_range("damping", self.damping, 0.0, 1.0, high_closed=False)
        A = readonly(self.amplitudes)
        T = readonly(self.times)
        if A.ndim != 1 or A.shape != T.shape or A.size == 0:
            raise ValueError(
                f"amplitudes and times must be 1-D of one length, got {A.shape}, {T.shape}"
            )
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(T))):
            raise ValueError("amplitudes and times must be finite")
        if not A.sum() > 0.0:
            raise ValueError(f"the amplitudes must sum to a positive value, got {A.sum()}")
        if T[0] != 0.0 or np.any(np.diff(T) < 0.0):
            raise ValueError(f"times must start at 0 s and not decrease, got {T.tolist()} s")
        object.__setattr__(self, "amplitudes", A)
        object.__setattr__(self, "times", T)

    @property
    def duration(self) -> float:
        """Time of the last impulse, s."""
        return float(self.times[-1])

    @property
    def delay(self) -> float:
        """Added delay: the centroid ``sum A_i T_i / sum A_i``, s (the ramp lag it adds)."""
        return float(self.amplitudes @ self.times / self.amplitudes.sum())

    @property
    def command_peak(self) -> float:
        """Peak of a shaped unit step: largest ``|partial sum of A| / sum A`` (1 if A >= 0)."""
        return float(np.max(np.abs(np.cumsum(self.amplitudes))) / self.amplitudes.sum())

    def vibration(self, freq_hz: np.ndarray | float, damping: float | None = None) -> np.ndarray:
        """``V`` at ``freq_hz`` (Hz) for a mode of ``damping`` (default the design's)."""
        z = self.damping if damping is None else damping
        return residual_vibration(self.amplitudes, self.times, freq_hz, z)

    def taps(
        self, dt: float, method: Literal["interpolate", "round"] = "interpolate"
    ) -> np.ndarray:
        """FIR taps of the shaper on a sampled command (sum 1), shape (k_last + 1,).

        Parameters
        ----------
        dt : float
            Sample time, s.
        method : {"interpolate", "round"}
            Split each impulse linearly between its two neighbouring samples, or move it
            to the nearest sample (see the module).
        """
        check_positive("dt", dt, "s")
        q = self.times / dt
        if not q[-1] < MAX_TAPS:
            raise ValueError(
                f"the {self.name} shaper lasts {self.duration:g} s, {q[-1]:.4g} samples of dt = "
                f"{dt:g} s: more than {MAX_TAPS} taps; use a longer dt or a faster mode"
            )
        A = self.amplitudes / self.amplitudes.sum()
        if method == "round":
            k = np.rint(q).astype(int)
            h = np.zeros(int(k[-1]) + 1)
            np.add.at(h, k, A)
            return h
        if method != "interpolate":
            raise ValueError(f"method must be 'interpolate' or 'round', got {method!r}")
        k = np.floor(q).astype(int)
        r = q - k
        h = np.zeros(int(k[-1]) + 2)
        np.add.at(h, k, A * (1.0 - r))
        np.add.at(h, k + 1, A * r)
        return np.trim_zeros(h, "b") if h[-1] == 0.0 else h

    def sampled_vibration(
        self,
        dt: float,
        freq_hz: np.ndarray | float,
        damping: float | None = None,
        method: Literal["interpolate", "round"] = "interpolate",
    ) -> np.ndarray:
        """``V`` of the sampled shaper (`taps` as impulses every ``dt``), same convention."""
        h = self.taps(dt, method)
        z = self.damping if damping is None else damping
        return residual_vibration(h, np.arange(h.size) * dt, freq_hz, z)

    def shape(
        self,
        command: np.ndarray,
        dt: float,
        *,
        method: Literal["interpolate", "round"] = "interpolate",
        periodic: bool = False,
        axes: Sequence[str] | None = None,
        bounds: Bounds | None = None,
        limits: Mapping[str, AxisLimits] | None = None,
        unit: str = "",
    ) -> np.ndarray:
        """The command convolved with the shaper's `taps`, from rest, and checked.

        Non-periodic: ``len(taps) - 1`` hold samples appended so that the last impulse
        lands; periodic: circular. Bounds, limits and messages as
        `microfab.control.shaping.InverseShaper.shape`.
        """
        h = self.taps(dt, method)
        return filter_command(
            command,
            h,
            np.array([1.0]),
            dt=dt,
            periodic=periodic,
            tail=h.size - 1,
            axes=axes,
            bounds=bounds,
            limits=limits,
            unit=unit,
        )

    def apply(self, trajectory: Trajectory) -> Trajectory:
        """`microfab.control.base.Feedforward`: the trajectory shaped at its own ``dt``."""
        h = self.taps(trajectory.dt)
        return shaped_trajectory(trajectory, h, np.array([1.0]), h.size - 1, self.name)


def design_shaper(
    name: ShaperName,
    freq_hz: float,
    damping: float = 0.0,
    *,
    v_tol: float = DEFAULT_V_TOL,
    method: Literal["auto", "closed", "numeric"] = "auto",
    closed_form_tol: float = 0.005,
) -> ImpulseShaper:
    """Design a classic impulse shaper for a mode.

    Parameters
    ----------
    name : {"zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei"}
        Shaper type (`SHAPER_NAMES`).
    freq_hz : float
        Natural (undamped) frequency of the mode, Hz.
    damping : float
        Damping ratio of the mode, in [0, 1).
    v_tol : float
        Vibration tolerance of the EI family, in (0, 0.25] (default 5 %).
    method : {"auto", "closed", "numeric"}
        ``"auto"``: the closed form where it meets its constraints (see the module), else
        the numerical solution; ``"closed"``: Klipper's form whatever it gives;
        ``"numeric"``: always solve (EI family; the exact forms are returned as they are).
    closed_form_tol : float
        Largest ``|V(f) - target|`` accepted from a closed form in ``"auto"``.

    Returns
    -------
    ImpulseShaper
        With ``numeric`` and ``constraint_miss`` saying what was done.

    Raises
    ------
    ValueError
        Unknown name, bad numbers, or no shaper of that family meets its constraints at
        this damping (the message names the largest damping reached).
    """
    if name not in SHAPERS:
        raise ValueError(f"unknown shaper {name!r}; known: {', '.join(SHAPER_NAMES)}")
    form = SHAPERS[name]
    check_positive("freq_hz", freq_hz, "Hz")
    if not 1.0 / freq_hz < _MAX_PERIOD_S:
        raise ValueError(
            f"freq_hz = {freq_hz:g} Hz is too slow: a period of more than {_MAX_PERIOD_S:g} s "
            "overflows the impulse times"
        )
    check_in_range("damping", damping, 0.0, 1.0, high_closed=False)
    check_in_range("v_tol", v_tol, 0.0, 0.25, "(fraction)", low_closed=False)
    check_positive("closed_form_tol", closed_form_tol)
    if method not in ("auto", "closed", "numeric"):
        raise ValueError(f"method must be 'auto', 'closed' or 'numeric', got {method!r}")
    target = form.centre_target(v_tol)
    A, T = form.closed_form(freq_hz, damping, v_tol)
    A = A / A.sum()  # unit static gain (Klipper divides by the sum when it applies them)
    miss = abs(float(residual_vibration(A, T, freq_hz, damping)[0]) - target)
    closed_ok = (
        np.all(A >= 0.0)
        and miss <= closed_form_tol
        and damping <= form.max_damping
        and (form.fixed_v_tol is None or v_tol == form.fixed_v_tol)
    )
    use_closed = form.exact or method == "closed" or (method == "auto" and closed_ok)
    if use_closed and np.any(np.diff(T) < 0.0):
        raise ValueError(
            f"Klipper's closed form of {name} is no shaper at damping {damping}: its impulse "
            f"times decrease ({np.round(T * freq_hz, 4).tolist()} periods of f); use "
            "method='auto' or 'numeric'"
        )
    if use_closed:
        return ImpulseShaper(
            name=name,
            freq_hz=freq_hz,
            damping=damping,
            amplitudes=A,
            times=T,
            v_tol=v_tol,
            numeric=False,
            constraint_miss=miss,
        )
    with one_blas_thread():  # small systems: BLAS threads only cost here
        An, Tn, reached = numeric_unit(name, float(damping), float(v_tol))
    if not An:
        raise ValueError(
            f"no {name} shaper meets its constraints at damping {damping} (v_tol {v_tol}): "
            f"the family ends near damping {reached:.3f}; use zvd or mzv (exact at any "
            f"damping), ei (to damping 0.69), or a lower damping"
        )
    A, T = np.array(An), np.array(Tn) / freq_hz
    miss = abs(float(residual_vibration(A, T, freq_hz, damping)[0]) - target)
    return ImpulseShaper(
        name=name,
        freq_hz=freq_hz,
        damping=damping,
        amplitudes=A,
        times=T,
        v_tol=v_tol,
        numeric=True,
        constraint_miss=miss,
    )
