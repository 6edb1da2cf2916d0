"""Velocity from measured positions: a second-order filtered differentiator.

Only positions are measured on the seed 001 stage (§2, §4.2), while the RBF controller's
input ``z = (x1, x2, x̄1, x̄2, s, v)`` and the error function ``s = λe + ė`` (seed 001
§3.2) need velocities. They come from

``v̂ = s ω² / (s² + 2 ζ ω s + ω²) · y``,

the derivative of the measurement low-passed with unit DC gain. It is discretised by
Tustin's rule (python-control), which keeps the slope of a sampled ramp exact in steady
state (a ZOH discretisation read at the samples is off by ~1 % at 500 Hz and 10 kHz), and
has feed-through: ``v̂_k`` responds to ``y_k``. The first measurement sets the filter to
its steady state for a stage at rest there (``v̂ = 0``), so a stage that starts away from
zero shows no spurious velocity.

Defaults (assumed, not in the seed): bandwidth 500 Hz, ten times the 50 Hz resonance of
seed 001 eq. 9 and one twentieth of the assumed 10 kHz sample rate; damping 1/√2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

import control
from microfab.core.validate import check_in_range, check_positive
from microfab.plants.lti import discretize

__all__ = ["N_ESTIMATOR_PARAMS", "N_ESTIMATOR_STATES", "VelocityEstimator", "estimator_step"]

#: Parameters of the discrete filter in a flat array: A (2x2), B, C, D, g (see `discrete`).
N_ESTIMATOR_PARAMS = 11
#: States per axis: the filter's two states, initialised flag (0 or 1).
N_ESTIMATOR_STATES = 3


@dataclass(frozen=True, kw_only=True)
class VelocityEstimator:
    """Second-order filtered differentiator on a measured position (per axis).

    Parameters
    ----------
    bandwidth_hz : float
        Natural frequency of the filter, Hz (assumed default 500 Hz: 10x the seed 001
        eq. 9 resonance of ~50 Hz); below the Nyquist frequency of the sample rate used.
    damping : float
        Damping ratio ζ of the filter, in (0, 2] (default 1/√2: flat, little overshoot).
    """

    bandwidth_hz: float = 500.0  # assumed, see the module docstring
    damping: float = 1.0 / math.sqrt(2.0)  # assumed: Butterworth

    def __post_init__(self) -> None:
        check_positive("estimator bandwidth_hz", self.bandwidth_hz, "Hz")
        check_in_range("estimator damping", self.damping, 0.0, 2.0, low_closed=False)

    def discrete(self, dt: float) -> np.ndarray:
        """Tustin discretisation, flat: ``[A(2x2), B(2), C(2), D, g(2)]``.

        ``v̂_k = C x_k + D y_k``, ``x_{k+1} = A x_k + B y_k``; ``g = (I − A)⁻¹ B`` is the
        state at rest at ``y = 1`` (the initialisation).

        Parameters
        ----------
        dt : float
            Sample time, s; the bandwidth must lie below the Nyquist frequency ``1/(2 dt)``.

        Returns
        -------
        numpy.ndarray
            Shape (11,).
        """
        dt = check_positive("dt", dt, "s")
        if self.bandwidth_hz >= 0.5 / dt:
            raise ValueError(
                f"estimator bandwidth_hz must lie below the Nyquist frequency {0.5 / dt:g} Hz "
                f"of dt = {dt:g} s, got {self.bandwidth_hz:g} Hz; lower it"
            )
        w = 2.0 * math.pi * self.bandwidth_hz
        ss = control.ss(
            [[0.0, 1.0], [-w * w, -2.0 * self.damping * w]], [[0.0], [w * w]], [[0.0, 1.0]], [[0.0]]
        )
        # the velocity state of a filter on y: dp/dt = v, dv/dt = w²(y − p) − 2ζw v
        d = discretize(ss, dt, "tustin")
        g = np.linalg.solve(np.eye(2) - d.A, d.B[:, 0])
        return np.concatenate([d.A.ravel(), d.B[:, 0], d.C[0], d.D[0], g]).astype(np.float64)

    def step(self, phi: np.ndarray, state: np.ndarray, y: float) -> tuple[float, np.ndarray]:
        """One sample in Python: ``(v̂, new state)`` (the reference of `estimator_step`).

        Parameters
        ----------
        phi : numpy.ndarray
            `discrete` output, shape (11,).
        state : numpy.ndarray
            ``[x0, x1, initialised]``, shape (3,); not modified.
        y : float
            Measured position, mm.
        """
        new = np.array(state, dtype=float)
        if new[2] == 0.0:
            new[0] = phi[9] * y
            new[1] = phi[10] * y
            new[2] = 1.0
        v = phi[6] * new[0] + phi[7] * new[1] + phi[8] * y
        x0 = phi[0] * new[0] + phi[1] * new[1] + phi[4] * y
        x1 = phi[2] * new[0] + phi[3] * new[1] + phi[5] * y
        new[0] = x0
        new[1] = x1
        return float(v), new


@njit(cache=True, inline="always")
def estimator_step(phi: np.ndarray, io: int, x: np.ndarray, ix: int, y: float) -> float:
    """Advance the filter whose state is ``x[ix:ix+3]`` with ``y``; return ``v̂`` (mm/s).

    ``phi[io:io+11]`` holds `VelocityEstimator.discrete`; no allocation.
    """
    if x[ix + 2] == 0.0:
        x[ix] = phi[io + 9] * y
        x[ix + 1] = phi[io + 10] * y
        x[ix + 2] = 1.0
    v = phi[io + 6] * x[ix] + phi[io + 7] * x[ix + 1] + phi[io + 8] * y
    x0 = phi[io] * x[ix] + phi[io + 1] * x[ix + 1] + phi[io + 4] * y
    x1 = phi[io + 2] * x[ix] + phi[io + 3] * x[ix + 1] + phi[io + 5] * y
    x[ix] = x0
    x[ix + 1] = x1
    return v
