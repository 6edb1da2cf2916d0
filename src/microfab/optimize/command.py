"""The 400 Hz input of stage 2 as a 10 kHz machine command within the machine's limits.

The networks read the command at 400 Hz (every 25th 10 kHz sample, seed 002 §III-B), so
the command between those samples is ours to choose. `command_from_input` passes a
cubic spline through them, C² (the acceleration continuous, the jerk bounded):

* before sample 0 the command holds ``rest`` (the stage starts at rest there), and after
  the last sample it holds that sample (plus ``hold_s``);
* the knots are ``rest`` at ``t = -2Δt, -Δt``, ``r_j`` at ``t = jΔt`` and ``r_{M-1}`` again
  at ``MΔt, (M+1)Δt``, with zero slope at both ends (clamped), so the command leaves
  ``rest`` and reaches its last value at rest;
* the command starts at the first knot, at rest (`LEAD` = 2 input samples before
  ``r_0``), and ends at the last, at rest; its 10 kHz samples at ``t = jΔt`` are exactly
  ``r_j`` (the spline interpolates), and the networks, reading every 25th sample from
  the start, see ``rest, rest, r_0, r_1, …``: what stage 2 assumed.

Bounds (`input_bounds`). On a uniform grid of spacing ``Δt`` the knot accelerations
``M_j`` of an interpolating cubic spline solve ``M_{j-1} + 4 M_j + M_{j+1} = 6 Δ²r_j / Δt²``
in the interior; with the clamped, resting ends (two equal knots and zero slope at each
end) the end rows are ``2 M_0 + M_1 = 0``. The matrix is strictly diagonally dominant
(margin 2 inside, 1 at the ends), so ``max|M| ≤ 3 max|Δ²r| / Δt²``, and the acceleration
is linear between knots: ``|Δ²r| ≤ a Δt² / 3`` keeps the command's acceleration ≤ ``a``.
Between two knots the slope of the cubic differs from the chord's by at most
``Δt max|M| / 4``, so ``|Δr| ≤ (v - a Δt / 4) Δt`` keeps the speed ≤ ``v``. Both are
sufficient (conservative) conditions, checked on random inputs by the tests. A 10 kHz
finite difference of the command is a mean of its derivative over the step, so the
sampled command obeys the same bounds, which `microfab.core.limits.check_trajectory`
checks.

`checked_command` builds the command and runs `check_trajectory` before returning it:
nothing over the limits leaves this module.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

from microfab.core.limits import MachineLimits, check_trajectory
from microfab.trajectory.base import Trajectory

__all__ = ["LEAD", "checked_command", "command_from_input", "input_bounds"]

_PAD = 2  # rest knots before sample 0 and held knots after the last one
LEAD = _PAD  # input samples of the command before r_0


def command_from_input(
    r: np.ndarray,
    *,
    rest: np.ndarray,
    rate_hz: float = 400.0,
    run_rate_hz: float = 1e4,
    hold_s: float = 0.0,
) -> np.ndarray:
    """The 10 kHz command through the 400 Hz input (module docstring).

    Parameters
    ----------
    r : numpy.ndarray
        ``r_0 … r_{M-1}``, shape (M, 2), m, at ``t = jΔt``.
    rest : numpy.ndarray
        The rest position before the start, (2,), m.
    rate_hz, run_rate_hz : float
        Input and command rates, Hz; ``run_rate_hz / rate_hz`` an integer.
    hold_s : float
        Extra time the last value is held, s.

    Returns
    -------
    numpy.ndarray
        Shape (q (M + 3) + 1 + round(hold_s run_rate_hz), 2), m,
        ``q = run_rate_hz / rate_hz``: from rest at ``t = -2Δt`` (`LEAD` input samples
        before ``r_0``, so ``r_j`` is sample ``q (j + LEAD)``) to rest at ``r_{M-1}``,
        ``2Δt`` after it.
    """
    r = np.asarray(r, dtype=float)
    rest = np.asarray(rest, dtype=float).reshape(2)
    if r.ndim != 2 or r.shape[1] != 2 or r.shape[0] < 1 or not np.all(np.isfinite(r)):
        raise ValueError(f"r must be a finite (M, 2) array with M >= 1, got shape {r.shape}")
    q = run_rate_hz / rate_hz
    if abs(q - round(q)) > 1e-9 or q < 1:
        raise ValueError(f"run_rate_hz / rate_hz must be an integer >= 1, got {q:g}")
    q = round(q)
    m = r.shape[0]
    knots = np.vstack([np.repeat(rest[None], _PAD, axis=0), r, np.repeat(r[-1:], _PAD, axis=0)])
    tk = np.arange(-_PAD, m + _PAD)  # in units of Δt
    spline = CubicSpline(tk, knots, axis=0, bc_type="clamped")
    n = q * (m + 2 * _PAD - 1) + 1  # from rest to rest: the first to the last knot
    t = np.arange(n) / q - _PAD
    out = spline(t)
    out[::q] = knots  # exact at the knots (the spline interpolates; no rounding drift)
    n_hold = round(hold_s * run_rate_hz)
    if n_hold:
        out = np.vstack([out, np.repeat(out[-1:], n_hold, axis=0)])
    return out


def input_bounds(limits: MachineLimits, rate_hz: float = 400.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis bounds on ``|Δr|`` and ``|Δ²r|`` (400 Hz differences, m).

    They keep the command of `command_from_input` within ``limits`` (module docstring).
    """
    dt = 1.0 / rate_hz
    a = np.asarray(limits.acceleration, dtype=float)
    v = np.asarray(limits.velocity, dtype=float)
    d2 = a * dt**2 / 3.0
    dv = np.maximum(v - a * dt / 4.0, 0.0) * dt
    if np.any(dv <= 0):
        raise ValueError(
            f"the limits leave no room at {rate_hz:g} Hz: v {v} m/s against a dt / 4 "
            f"{a * dt / 4} m/s"
        )
    return dv, d2


def checked_command(
    r: np.ndarray,
    *,
    rest: np.ndarray,
    limits: MachineLimits,
    rate_hz: float = 400.0,
    run_rate_hz: float = 1e4,
    hold_s: float = 0.0,
) -> Trajectory:
    """`command_from_input` as a `Trajectory`, refused unless within ``limits``.

    Raises
    ------
    microfab.core.limits.LimitViolation
        Naming the axis, the time, the value and the limit; nothing is returned.
    """
    pos = command_from_input(r, rest=rest, rate_hz=rate_hz, run_rate_hz=run_rate_hz,
                             hold_s=hold_s)  # fmt: skip
    traj = Trajectory(dt=1.0 / run_rate_hz, position=pos, at_rest=True)
    check_trajectory(traj, limits)
    if not math.isfinite(float(np.abs(pos).max())):  # pragma: no cover - check_samples
        raise ValueError("the command is not finite")
    return traj
