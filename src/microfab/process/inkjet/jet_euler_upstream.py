"""The linear model upstream of the Eulerian jet's meniscus: its definition and working arrays.

:func:`.jet_euler.run_jet_euler` marches it alongside the grid (two-way coupling, in
:mod:`.jet_euler_meniscus`); the dispenser's acoustics are one
(:func:`microfab.process.inkjet.droplet.coupled_upstream`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microfab.core.arrays import readonly

__all__ = ["Upstream", "UpstreamArrays"]


@dataclass(frozen=True, kw_only=True)
class Upstream:
    """A linear model upstream of the meniscus that feeds the nozzle (dimensionless).

    Sampled at a fixed step ``dt`` with its inputs held over each step (zero-order
    hold): ``x_{k+1} = phi x_k + g_drive s_k + g_pressure p_m``, nozzle velocity
    ``u_c = c_row · x`` (positive out of the nozzle), where ``s_k`` is the drive over step
    ``k`` and ``p_m`` the meniscus pressure from the grid (:mod:`.jet_euler_meniscus`). The
    dispenser's acoustics without its lumped meniscus are one
    (:func:`microfab.process.inkjet.droplet.coupled_upstream`).

    Parameters
    ----------
    phi : numpy.ndarray
        State transition over one step, shape ``(nx, nx)``.
    g_drive : numpy.ndarray
        State increment per unit drive held over a step, shape ``(nx,)``.
    g_pressure : numpy.ndarray
        State increment per unit meniscus pressure (``sigma / R``) held over a step,
        shape ``(nx,)``.
    c_row : numpy.ndarray
        Nozzle velocity (``R / t_c``) per state, shape ``(nx,)``.
    slopes : numpy.ndarray
        Drive per step from the start of the run, shape ``(m,)``; 0 after the last.
    dt : float
        Step, capillary times, > 0.
    x0 : numpy.ndarray, optional
        Initial state, shape ``(nx,)`` (default at rest).
    """

    phi: np.ndarray
    g_drive: np.ndarray
    g_pressure: np.ndarray
    c_row: np.ndarray
    slopes: np.ndarray
    dt: float
    x0: np.ndarray | None = None

    def __post_init__(self) -> None:
        phi = np.array(self.phi, float)
        if phi.ndim != 2 or phi.shape[0] != phi.shape[1] or phi.shape[0] < 1:
            raise ValueError(f"phi must be a square matrix, got shape {phi.shape}")
        nx = phi.shape[0]
        object.__setattr__(self, "phi", readonly(np.ascontiguousarray(phi)))
        for name in ("g_drive", "g_pressure", "c_row"):
            v = np.array(getattr(self, name), float)
            if v.shape != (nx,):
                raise ValueError(f"{name} needs shape ({nx},), got {v.shape}")
            object.__setattr__(self, name, readonly(v))
        x0 = np.zeros(nx) if self.x0 is None else np.array(self.x0, float)
        if x0.shape != (nx,):
            raise ValueError(f"x0 needs shape ({nx},), got {x0.shape}")
        object.__setattr__(self, "x0", readonly(x0))
        slopes = np.array(self.slopes, float).reshape(-1)
        object.__setattr__(self, "slopes", readonly(slopes))
        for name in ("phi", "g_drive", "g_pressure", "c_row", "slopes", "x0"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"{name} holds NaN or inf")
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0, got {self.dt!r}")


@dataclass
class UpstreamArrays:
    """Working arrays of the coupled upstream model handed to the kernels."""

    u_tab: np.ndarray
    x: np.ndarray
    phi: np.ndarray
    g_drive: np.ndarray
    g_pressure: np.ndarray
    c_row: np.ndarray
    slopes: np.ndarray

    @classmethod
    def idle(cls) -> UpstreamArrays:
        """Placeholders for a run without an upstream model (never read)."""
        one = np.zeros(1)
        return cls(np.zeros(2), one.copy(), np.zeros((1, 1)), one, one, one, one)

    @classmethod
    def of(cls, up: Upstream, size: int) -> UpstreamArrays:
        """Arrays for ``size`` table entries, the state at ``up.x0``."""
        assert up.x0 is not None
        u_tab = np.zeros(size)
        u_tab[0] = float(up.c_row @ up.x0)
        return cls(
            u_tab,
            np.array(up.x0, float),
            np.ascontiguousarray(up.phi),
            np.asarray(up.g_drive),
            np.asarray(up.g_pressure),
            np.asarray(up.c_row),
            np.asarray(up.slopes),
        )
