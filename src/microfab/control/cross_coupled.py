"""Koren's cross-coupled controller on top of the axis controllers: the contour baseline.

Koren (1980, "Cross-coupled biaxial computer control for manufacturing systems") couples
two axis loops through an estimate of the contour error built from the axis errors
``e_x = x_ref − x``, ``e_y = y_ref − y`` and gains from the direction ``θ`` of the path:

``ε_K = −C_x e_x + C_y e_y``,   ``C_x = sin θ``, ``C_y = cos θ``,

(the linear-contour gains; ``θ`` from the reference velocity, so ``(−C_x, C_y)`` is the
path normal ``n`` of `microfab.control.contour` and ``ε_K = −ε``), passes it through a
compensator ``W`` and feeds ``−C_x W ε_K`` to x and ``C_y W ε_K`` to y. Here ``W`` is a PD,
``u_c = k_p ε_K + k_d ε̇_K``, with ``ε̇_K`` from the filtered differentiator of
`microfab.control.velocity` applied to the scalar ``ε_K`` (Koren's derivative of the
error estimate), and the coupled command enters as an acceleration, added to ``ẍ_d`` of
seed 004 eq. 3 in the same `microfab.control.preview_dob.PreviewDOB` that the contour
compensator uses:

``Δa = (−C_x, C_y) u_c``.

At equal bandwidth to the compensator (`ContourConfig`): ``k_p = ω_cc²``,
``k_d = 2 ζ_c ω_cc``, the same normal gains, checked for stability the same way.
Where the reference speed is below ``min_speed_m_s`` the direction is undefined and the
gains ``C_x, C_y`` are held at their last values (Koren's gains change per block of the
part program); before the reference first moves they are zero (no coupling). What
differs from the compensator: the derivative is that of the estimate (a step in ``C`` at
a corner taken at speed passes into ``ε̇_K``), there is no fade at rest, and no explicit
frame rotation term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import ReferenceWindow
from microfab.control.contour import check_addon_config, check_normal_gains
from microfab.control.preview_dob import (
    PreviewDOBAddOn,
    PreviewDOBConfig,
    pdob_command,
    pdob_measure,
)
from microfab.control.velocity import N_ESTIMATOR_PARAMS, estimator_step

__all__ = ["CrossCoupled", "CrossCoupledConfig", "cross_coupled_step"]

_HDR = 4 + N_ESTIMATOR_PARAMS  # k_p, k_d, min speed, spare, differentiator
_XS = 10  # state: Δa(2), C_x, C_y, ε_K, ε̇_K, differentiator(3), spare


@dataclass(frozen=True, kw_only=True)
class CrossCoupledConfig:
    """Settings of Koren's cross-coupled PD on the contour error estimate, validated.

    Parameters
    ----------
    inner : PreviewDOBConfig
        The two axis controllers (x, y).
    bandwidth_hz : float
        ``ω_cc / 2π`` of ``k_p = ω_cc²``, ``k_d = 2 ζ_c ω_cc``, Hz (assumed 100 Hz, the
        contour compensator's default: equal bandwidth).
    damping : float
        ``ζ_c`` (assumed 1).
    min_speed_m_s : float
        Reference speed below which the gains ``C_x, C_y`` are held, m/s (assumed
        0.1 mm/s, as the compensator's).
    """

    inner: PreviewDOBConfig
    bandwidth_hz: float = 100.0  # assumed: equal to ContourConfig's
    damping: float = 1.0  # assumed
    min_speed_m_s: float = 1e-4  # assumed

    def __post_init__(self) -> None:
        check_addon_config(self, "cross-coupled controller", "cross-coupled PD")
        check_normal_gains(self.inner, self.k_p, self.k_d, "cross-coupled controller")

    @property
    def k_p(self) -> float:
        """``k_p = ω_cc²``, 1/s²."""
        return (2.0 * math.pi * self.bandwidth_hz) ** 2

    @property
    def k_d(self) -> float:
        """``k_d = 2 ζ_c ω_cc``, 1/s."""
        return 2.0 * self.damping * 2.0 * math.pi * self.bandwidth_hz


@njit(cache=True)
def cross_coupled_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Kernel of `CrossCoupled`: inner measure, Koren's coupled PD, inner command."""
    pin = p[_HDR:]
    xin = x[_XS:]
    r = ref[k]
    pdob_measure(pin, xin, r, ym)
    vx = r[1, 0]
    vy = r[1, 1]
    sp = math.sqrt(vx * vx + vy * vy)
    if sp >= p[2]:
        x[2] = vy / sp  # C_x = sin θ
        x[3] = vx / sp  # C_y = cos θ
    eps = -x[2] * (r[0, 0] - ym[0]) + x[3] * (r[0, 1] - ym[1])
    epsd = estimator_step(p, 4, x, 6, eps)
    uc = p[0] * eps + p[1] * epsd
    x[0] = -x[2] * uc
    x[1] = x[3] * uc
    x[4] = eps
    x[5] = epsd
    pdob_command(pin, xin, r, ym, x[0:2], u)


class CrossCoupled(PreviewDOBAddOn):
    """`PreviewDOB` on both axes plus Koren's cross-coupled PD (module docstring).

    Parameters
    ----------
    config : CrossCoupledConfig
        Inner controllers and coupled gains.

    Notes
    -----
    ``params = [k_p, k_d, min speed, 0, differentiator(11), inner params]``; state
    ``[Δa_x, Δa_y (m/s²), C_x, C_y, ε_K (m), ε̇_K (m/s), differentiator(3), 0, inner
    state]``.
    """

    kernel_step: Any = cross_coupled_step

    head_states = _XS
    name = "cross-coupled controller"

    def __init__(self, config: CrossCoupledConfig) -> None:
        if not isinstance(config, CrossCoupledConfig):
            raise TypeError(f"config must be a CrossCoupledConfig, got {type(config).__name__}")
        self.config = config
        self._phi = config.inner.estimator.discrete(config.inner.dt)
        self._setup(config.inner, [config.k_p, config.k_d, config.min_speed_m_s, 0.0, *self._phi])

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference of the kernel); ``state`` is not modified."""
        x, ym, xin = self._begin(state, window, measurement)
        vx, vy = float(window.velocity[0, 0]), float(window.velocity[0, 1])
        sp = math.sqrt(vx * vx + vy * vy)
        if sp >= self.config.min_speed_m_s:
            x[2], x[3] = vy / sp, vx / sp
        ex = float(window.position[0, 0]) - float(ym[0])
        ey = float(window.position[0, 1]) - float(ym[1])
        eps = -x[2] * ex + x[3] * ey
        epsd, x[6:9] = self.config.inner.estimator.step(self._phi, x[6:9], eps)
        uc = self.params[0] * eps + self.params[1] * epsd
        x[0], x[1] = -x[2] * uc, x[3] * uc
        x[4], x[5] = eps, epsd
        u = self.inner.command(xin, window, ym, x[0:2].copy())
        return u, x

    def contour_error_estimate(self, state: np.ndarray) -> float:
        """Koren's ``ε_K`` of the last sample, m (``−ε`` of the compensator)."""
        return float(np.asarray(state)[4])
