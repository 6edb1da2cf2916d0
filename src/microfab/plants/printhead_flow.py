"""The orifice flow of the printhead model: a mean velocity record and its interpolation.

`NozzleFlow` holds what :func:`.printhead.nozzle_flow` computes, the mean orifice velocity
on a uniform time grid with its displacement and the orifice radius, and reads it at any
time: linear in velocity and exactly integrated in displacement, for arrays and, bit for
bit the same, for one time (`NozzleFlow.at`, what the slender-jet solvers ask at every
stage). It is a result, apart from the acoustic model (:mod:`.printhead`), which
re-exports it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from microfab.core.validate import check_positive

__all__ = ["NozzleFlow"]


@dataclass(frozen=True, kw_only=True)
class NozzleFlow:
    """Mean orifice velocity history on a uniform time grid.

    Attributes
    ----------
    t_s : numpy.ndarray
        Sample times in s, shape (n,), ``n >= 2``, uniform, starting at 0.
    velocity_m_s : numpy.ndarray
        Mean orifice velocity ``q_n / (π R²)`` in m/s, shape (n,), positive out of the
        nozzle.
    displacement_m : numpy.ndarray
        Cumulative ``∫ u dt`` in m by the trapezoid rule, shape (n,), 0 at ``t = 0``.
    nozzle_radius_m : float
        Orifice radius ``R`` in m, > 0.

    Examples
    --------
    >>> flow = NozzleFlow(t_s=np.array([0.0, 1e-6, 2e-6]),
    ...                   velocity_m_s=np.array([0.0, 2.0, 2.0]),
    ...                   displacement_m=np.array([0.0, 1e-6, 3e-6]), nozzle_radius_m=60e-6)
    >>> float(flow.velocity(0.5e-6)), flow.peak_velocity_m_s
    (1.0, 2.0)
    """

    t_s: np.ndarray
    velocity_m_s: np.ndarray
    displacement_m: np.ndarray
    nozzle_radius_m: float

    def __post_init__(self) -> None:
        check_positive("nozzle_radius_m", self.nozzle_radius_m, "m")
        arrays = {}
        for name in ("t_s", "velocity_m_s", "displacement_m"):
            arr = np.array(getattr(self, name), dtype=float)
            if arr.ndim != 1 or arr.size < 2:
                raise ValueError(f"{name} must have shape (n,) with n >= 2, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} holds NaN or inf")
            arr.setflags(write=False)
            arrays[name] = arr
        t = arrays["t_s"]
        if arrays["velocity_m_s"].shape != t.shape or arrays["displacement_m"].shape != t.shape:
            raise ValueError(
                f"t_s {t.shape}, velocity_m_s {arrays['velocity_m_s'].shape} and "
                f"displacement_m {arrays['displacement_m'].shape} must have the same shape"
            )
        dt = t[1] - t[0]
        if t[0] != 0.0 or not dt > 0 or not np.allclose(np.diff(t), dt, rtol=1e-9, atol=0.0):
            raise ValueError(
                f"t_s must be uniform and start at 0 s, got t_s[0] = {t[0]} s, "
                f"spacing {dt} s to {np.diff(t).max()} s"
            )
        for name, arr in arrays.items():
            object.__setattr__(self, name, arr)

    @property
    def dt_s(self) -> float:
        """Sample spacing in s."""
        return float(self.t_s[1] - self.t_s[0])

    @property
    def peak_velocity_m_s(self) -> float:
        """Largest outward mean orifice velocity over the record in m/s."""
        return float(np.max(self.velocity_m_s))

    @functools.cached_property
    def _lists(self) -> tuple[list[float], list[float], list[float]]:
        return self.t_s.tolist(), self.velocity_m_s.tolist(), self.displacement_m.tolist()

    def at(self, t_s: float) -> tuple[float, float]:
        """Velocity (m/s) and displacement (m) at one time ``t_s`` (s).

        `velocity` and `displacement` for a scalar, with the same arithmetic (bit for bit)
        and without the array overhead: a solver that asks for the inflow at every stage of
        every step (the slender-jet models) spent a quarter of its time in the array path.

        Examples
        --------
        >>> flow = NozzleFlow(t_s=np.array([0.0, 1.0]), velocity_m_s=np.array([0.0, 4.0]),
        ...                   displacement_m=np.array([0.0, 2.0]), nozzle_radius_m=1e-4)
        >>> flow.at(0.5)
        (2.0, 0.5)
        """
        t = float(t_s)
        ts, u, d = self._lists
        t_end = ts[-1]
        dt = ts[1] - ts[0]
        if not math.isfinite(t) or t > t_end + 1e-9 * dt:
            raise ValueError(f"time {t} s lies beyond the end of the record ({t_end} s)")
        if t < 0.0:
            return 0.0, 0.0
        tc = min(t, t_end)
        k = min(max(math.floor(tc / dt), 0), len(ts) - 2)
        tau = tc - ts[k]
        slope = (u[k + 1] - u[k]) / dt
        return u[k] + slope * tau, d[k] + u[k] * tau + 0.5 * slope * tau * tau

    def _locate(self, t_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sample index ``k`` and offset ``τ = t - t_k`` of each time, and the t < 0 mask."""
        t = np.asarray(t_s, dtype=float)
        t_end = self.t_s[-1]
        bad = ~np.isfinite(t) | (t > t_end + 1e-9 * self.dt_s)
        if np.any(bad):
            first = t[bad].flat[0]
            raise ValueError(f"time {first} s lies beyond the end of the record ({t_end} s)")
        before = t < 0.0
        tc = np.clip(t, 0.0, t_end)
        k = np.clip(np.floor(tc / self.dt_s).astype(np.intp), 0, self.t_s.size - 2)
        return k, tc - self.t_s[k], before

    def velocity(self, t_s: np.ndarray | float) -> np.ndarray:
        """Mean orifice velocity at any times, by linear interpolation.

        Parameters
        ----------
        t_s : float or numpy.ndarray
            Times in s, any shape, not after the end of the record.

        Returns
        -------
        numpy.ndarray
            Velocity in m/s, same shape as ``t_s``; 0 before ``t = 0``.

        Raises
        ------
        ValueError
            If a time lies after the end of the record (or is not finite).

        Examples
        --------
        >>> flow = NozzleFlow(t_s=np.array([0.0, 1.0]), velocity_m_s=np.array([0.0, 4.0]),
        ...                   displacement_m=np.array([0.0, 2.0]), nozzle_radius_m=1e-4)
        >>> flow.velocity([-1.0, 0.25, 1.0]).tolist()
        [0.0, 1.0, 4.0]
        """
        k, tau, before = self._locate(t_s)
        u = self.velocity_m_s
        slope = (u[k + 1] - u[k]) / self.dt_s
        return np.where(before, 0.0, u[k] + slope * tau)

    def displacement(self, t_s: np.ndarray | float) -> np.ndarray:
        """Exact integral of the interpolated velocity from 0 to ``t``.

        Piecewise quadratic, equal to `displacement_m` at the samples and with derivative
        `velocity` everywhere.

        Parameters
        ----------
        t_s : float or numpy.ndarray
            Times in s, any shape, not after the end of the record.

        Returns
        -------
        numpy.ndarray
            Displacement in m, same shape as ``t_s``; 0 before ``t = 0``.

        Raises
        ------
        ValueError
            If a time lies after the end of the record (or is not finite).

        Examples
        --------
        >>> flow = NozzleFlow(t_s=np.array([0.0, 1.0]), velocity_m_s=np.array([0.0, 4.0]),
        ...                   displacement_m=np.array([0.0, 2.0]), nozzle_radius_m=1e-4)
        >>> flow.displacement([0.5, 1.0]).tolist()
        [0.5, 2.0]
        """
        k, tau, before = self._locate(t_s)
        u = self.velocity_m_s
        slope = (u[k + 1] - u[k]) / self.dt_s
        x = self.displacement_m[k] + u[k] * tau + 0.5 * slope * tau * tau
        return np.where(before, 0.0, x)

    def volume_m3(self, t_s: np.ndarray | float) -> np.ndarray:
        """Volume pushed through the orifice from 0 to ``t``, ``π R² × displacement``.

        Parameters
        ----------
        t_s : float or numpy.ndarray
            Times in s, any shape, not after the end of the record.

        Returns
        -------
        numpy.ndarray
            Volume in m³, same shape as ``t_s``.

        Examples
        --------
        >>> flow = NozzleFlow(t_s=np.array([0.0, 1.0]), velocity_m_s=np.array([1.0, 1.0]),
        ...                   displacement_m=np.array([0.0, 1.0]), nozzle_radius_m=1.0)
        >>> round(float(flow.volume_m3(1.0)), 12)
        3.14159265359
        """
        return math.pi * self.nozzle_radius_m**2 * self.displacement(t_s)
