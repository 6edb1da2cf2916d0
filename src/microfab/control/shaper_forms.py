"""The registry of the classic impulse shapers and their residual vibration.

`SHAPERS` maps each name (`ShaperName`) to a `ShaperForm`: Klipper's closed form, the
damping up to which Klipper uses it and, for the EI family, the constraints that define
the shaper; `residual_vibration` is Singer and Seering's ``V(f, zeta)``. Both the design
(`microfab.control.shapers`, which re-exports these names and describes the forms) and the
numerical solution of the EI family (`microfab.control.shaper_solve`) build on them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Literal, TypeAlias

import numpy as np

from microfab.core.validate import check_in_range

__all__ = [
    "DEFAULT_V_TOL",
    "SHAPERS",
    "SHAPER_NAMES",
    "ShaperForm",
    "ShaperName",
    "residual_vibration",
]

ShaperName: TypeAlias = Literal["zv", "zvd", "mzv", "ei", "2hump_ei", "3hump_ei"]

#: Vibration tolerance of the EI family: Klipper's 1 / SHAPER_VIBRATION_REDUCTION (= 1/20).
DEFAULT_V_TOL = 0.05


def _df(damping: float) -> float:
    return math.sqrt(1.0 - damping * damping)


def _zv(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """ZV: two impulses half a damped period apart (Singer-Seering; Klipper)."""
    K = math.exp(-damping * math.pi / _df(damping))
    t_d = 1.0 / (freq_hz * _df(damping))
    return np.array([1.0, K]), np.array([0.0, 0.5 * t_d])


def _zvd(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """ZVD: ZV convolved with itself (zero vibration and zero slope at ``f``)."""
    K = math.exp(-damping * math.pi / _df(damping))
    t_d = 1.0 / (freq_hz * _df(damping))
    return np.array([1.0, 2.0 * K, K * K]), np.array([0.0, 0.5 * t_d, t_d])


def _mzv(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """MZV: three impulses over 3/4 of a damped period (Klipper's 3-impulse form)."""
    K = math.exp(-0.75 * damping * math.pi / _df(damping))
    t_d = 1.0 / (freq_hz * _df(damping))
    a1 = 1.0 - 1.0 / math.sqrt(2.0)
    return (
        np.array([a1, (math.sqrt(2.0) - 1.0) * K, a1 * K * K]),
        np.array([0.0, 0.375 * t_d, 0.75 * t_d]),
    )


def _ei(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """EI: Klipper's polynomial fit in ``damping`` and ``v_tol`` (small damping)."""
    t_d = 1.0 / (freq_hz * _df(damping))
    z, v = damping, v_tol
    # Klipper shaper_defs.get_ei_shaper: fitted coefficients
    a1 = (0.24968 + 0.24961 * v) + ((0.80008 + 1.23328 * v) + (0.49599 + 3.17316 * v) * z) * z
    a3 = (0.25149 + 0.21474 * v) + ((-0.83249 + 1.41498 * v) + (0.85181 - 4.90094 * v) * z) * z
    t2 = (
        0.4999
        + (
            ((0.46159 + 8.57843 * v) * v)
            + (((4.26169 - 108.644 * v) * v) + ((1.75601 + 336.989 * v) * v) * z) * z
        )
        * z
    )
    return np.array([a1, 1.0 - a1 - a3, a3]), np.array([0.0, t2 * t_d, t_d])


def _from_fit(
    freq_hz: float, damping: float, t_fit: np.ndarray, a_fit: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes and times from cubic fits in ``damping`` (rows: impulses), times in 1/f."""
    powers = damping ** np.arange(t_fit.shape[1])
    return a_fit @ powers, (t_fit @ powers) / freq_hz


# Klipper shaper_defs.get_2hump_ei_shaper / get_3hump_ei_shaper: fits for v_tol = 5 %
_T_2HUMP = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [0.49890, 0.16270, -0.54262, 6.16180],
        [0.99748, 0.18382, -1.58270, 8.17120],
        [1.49920, -0.09297, -0.28338, 1.85710],
    ]
)
_A_2HUMP = np.array(
    [
        [0.16054, 0.76699, 2.26560, -1.22750],
        [0.33911, 0.45081, -2.58080, 1.73650],
        [0.34089, -0.61533, -0.68765, 0.42261],
        [0.15997, -0.60246, 1.00280, -0.93145],
    ]
)
_T_3HUMP = np.array(
    [
        [0.0, 0.0, 0.0, 0.0],
        [0.49974, 0.23834, 0.44559, 12.4720],
        [0.99849, 0.29808, -2.36460, 23.3990],
        [1.49870, 0.10306, -2.01390, 17.0320],
        [1.99960, -0.28231, 0.61536, 5.40450],
    ]
)
_A_3HUMP = np.array(
    [
        [0.11275, 0.76632, 3.29160, -1.44380],
        [0.23698, 0.61164, -2.57850, 4.85220],
        [0.30008, -0.19062, -2.14560, 0.13744],
        [0.23775, -0.73297, 0.46885, -2.08650],
        [0.11244, -0.45439, 0.96382, -1.46000],
    ]
)


def _ei2(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """2-hump EI: Klipper's fit (``v_tol`` = 5 % only)."""
    return _from_fit(freq_hz, damping, _T_2HUMP, _A_2HUMP)


def _ei3(freq_hz: float, damping: float, v_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """3-hump EI: Klipper's fit (``v_tol`` = 5 % only)."""
    return _from_fit(freq_hz, damping, _T_3HUMP, _A_3HUMP)


@dataclass(frozen=True, kw_only=True)
class ShaperForm:
    """One entry of the registry: a closed form and, for the EI family, its constraints.

    Attributes
    ----------
    name : ShaperName
        Registry key.
    closed_form : callable
        ``(freq_hz, damping, v_tol) -> (amplitudes, times_s)``, pure.
    max_damping : float
        Damping up to which Klipper uses the closed form (``max_damping_ratio``).
    fixed_v_tol : float or None
        The only ``v_tol`` the closed form holds for (5 % for the 2- and 3-hump fits).
    n_impulses : int
        Number of impulses.
    n_zeros, n_side_humps : int
        Zeros of ``V`` and humps of height ``v_tol`` away from ``f`` (EI family).
    centre : {"zero", "hump", None}
        Constraint at ``f``: ``V = 0`` or a hump ``V = v_tol`` with zero slope; ``None``
        for the exact forms (ZV, ZVD, MZV), which are never solved numerically.
    """

    name: ShaperName
    closed_form: Callable[[float, float, float], tuple[np.ndarray, np.ndarray]]
    max_damping: float
    n_impulses: int
    fixed_v_tol: float | None = None
    n_zeros: int = 0
    n_side_humps: int = 0
    centre: Literal["zero", "hump"] | None = None

    @property
    def exact(self) -> bool:
        """Whether the closed form meets the constraints for every damping (ZV, ZVD, MZV)."""
        return self.centre is None

    def centre_target(self, v_tol: float) -> float:
        """``V(f)`` the shaper is defined to have: 0 or ``v_tol``."""
        return v_tol if self.centre == "hump" else 0.0


#: The registry, in order of increasing length. Max damping: Klipper's INPUT_SHAPERS.
SHAPERS: Mapping[ShaperName, ShaperForm] = {
    "zv": ShaperForm(name="zv", closed_form=_zv, max_damping=0.99, n_impulses=2),
    "mzv": ShaperForm(name="mzv", closed_form=_mzv, max_damping=0.99, n_impulses=3),
    "zvd": ShaperForm(name="zvd", closed_form=_zvd, max_damping=0.99, n_impulses=3),
    "ei": ShaperForm(
        name="ei", closed_form=_ei, max_damping=0.4, n_impulses=3, n_zeros=2, centre="hump"
    ),
    "2hump_ei": ShaperForm(
        name="2hump_ei",
        closed_form=_ei2,
        max_damping=0.3,
        n_impulses=4,
        fixed_v_tol=DEFAULT_V_TOL,
        n_zeros=2,
        n_side_humps=2,
        centre="zero",
    ),
    "3hump_ei": ShaperForm(
        name="3hump_ei",
        closed_form=_ei3,
        max_damping=0.2,
        n_impulses=5,
        fixed_v_tol=DEFAULT_V_TOL,
        n_zeros=4,
        n_side_humps=2,
        centre="hump",
    ),
}

SHAPER_NAMES: tuple[ShaperName, ...] = tuple(SHAPERS)


def residual_vibration(
    amplitudes: Sequence[float] | np.ndarray,
    times_s: Sequence[float] | np.ndarray,
    freq_hz: np.ndarray | float,
    damping: float,
) -> np.ndarray:
    """Singer-Seering residual vibration of an impulse train at a mode.

    Parameters
    ----------
    amplitudes : array_like
        Impulse amplitudes, shape (n,) (sum nonzero).
    times_s : array_like
        Impulse times, s, shape (n,), non-decreasing; the last is ``T_n``.
    freq_hz : float or numpy.ndarray
        Natural frequencies of the mode, Hz, shape (m,).
    damping : float
        Damping ratio of the mode, in [0, 1).

    Returns
    -------
    numpy.ndarray
        ``V``, shape (m,) (the formula in `microfab.control.shapers`).
    """
    check_in_range("damping", damping, 0.0, 1.0, high_closed=False)
    A = np.asarray(amplitudes, dtype=float)
    T = np.asarray(times_s, dtype=float)
    w = 2.0 * np.pi * np.atleast_1d(np.asarray(freq_hz, dtype=float))
    expo = np.outer(w, damping * (T - T[-1]) + 1j * _df(damping) * T)
    # elementwise sum, not a BLAS product: many small calls (the fit) stay single-threaded
    return np.abs((np.exp(expo) * A).sum(axis=1)) / A.sum()
