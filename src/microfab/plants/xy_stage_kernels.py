"""Numba kernels of the seed 002 XY stage twin (`microfab.plants.xy_stage`) and its state layout.

The pure Python ``update`` of `XYStagePlant` is the reference for these kernels (tests
check the two to 1e-12 m through `microfab.sim.loop.simulate` and ``simulate_python``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microfab.plants import xy_stage_params as _p
from microfab.plants.friction import bristle_step, friction_force
from microfab.plants.xy_stage_params import N_MECH

__all__ = ["kernel_output", "kernel_update"]

_S_Z = N_MECH  # bristle deflection, x then y
_S_CTRL = _S_Z + 2  # [I, D, e_prev] per axis
_G = 4  # guard states per axis
_S_GUARD = _S_CTRL + 6  # [g, w, r_prev, v_prev] per axis
_S_COUNT = _S_GUARD + 2 * _G  # samples: changed, input off workspace / speed / acceleration
_S_K = _S_COUNT + 4  # sample counter
_S_SCR = _S_K + 1  # scratch of the mechanics step
_N_STATE = _S_SCR + N_MECH
_FRIC_X = _p._HEADER + _p._FRIC  # the axes' `StageFriction` blocks in the params
_FRIC_Y = _p._HEADER + _p._BLOCK + _p._FRIC


# --- kernels -------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _quantise(p: np.ndarray, x: float) -> float:
    """The encoder reading of position ``x`` (m): the nearest count when quantising."""
    if p[_p._H_QUANT] != 0.0:
        q = p[_p._H_RES]
        return math.floor(x / q + 0.5) * q
    return x


@njit(cache=True, inline="always")
def _approach(gap: float, dt: float, dv: float) -> float:
    """The fastest approach speed (m/s) that stops exactly after ``gap`` (m).

    From it, steps of ``w, w - dv, w - 2 dv, ...`` (then 0), each of ``dt`` (s), cover
    ``gap`` exactly.
    """
    m = math.floor(0.5 * (math.sqrt(1.0 + 8.0 * gap / (dt * dv)) - 1.0))
    return (gap / dt + dv * m * (m + 1.0) * 0.5) / (m + 1.0)


@njit(cache=True, inline="always")
def _guard(
    p: np.ndarray, s: np.ndarray, a: int, u: float
) -> tuple[float, float, int, int, int, int]:
    """The set-point guard of axis ``a``: ``(g, w, changed, workspace, speed, accel.)``.

    The guarded set-point (m), its speed (m/s), whether it differs from ``u`` and whether
    ``u`` broke each limit; stores the clipped input and its speed as ``r_prev``,
    ``v_prev``.
    """
    o = _S_GUARD + _G * a
    gp = s[o]
    wp = s[o + 1]
    rp = s[o + 2]
    dt = p[_p._H_DT]
    lo = p[_p._H_WLO]
    hi = p[_p._H_WHI]
    vmax = p[_p._H_VMAX]
    dv = p[_p._H_AMAX] * dt
    tol = 1.0 + p[_p._H_TOL]
    r = min(max(u, lo), hi)
    fp = 1 if r != u else 0
    vin = (r - rp) / dt
    fv = 1 if abs(vin) > vmax * tol else 0
    fa = 1 if abs(vin - s[o + 3]) > dv * tol else 0
    wd = (r - gp) / dt
    vr = min(max(vin, -vmax), vmax)
    if abs(wd) <= vmax * tol and abs(wd - wp) <= dv * tol and abs(wd - vr) <= dv * tol:
        g = r
        w = wd
    else:
        e = r - vr * dt - gp
        ws = vr + math.copysign(_approach(abs(e), dt, dv), e)
        w = min(max(ws, wp - dv), wp + dv)
        w = min(max(w, -vmax), vmax)
        g = gp + w * dt
        if g < lo:
            g = lo
            w = (g - gp) / dt
        elif g > hi:
            g = hi
            w = (g - gp) / dt
    s[o + 2] = r
    s[o + 3] = vin
    return g, w, 1 if g != u else 0, fp, fv, fa


@njit(cache=True, inline="always")
def _control(
    p: np.ndarray, s: np.ndarray, a: int, g: float, w: float, wp: float, y: float
) -> float:
    """The built-in PID + feedforward of axis ``a``: the commanded force (N).

    Updates the axis's ``[I, D, e_prev]``.
    """
    b = _p._HEADER + a * _p._BLOCK
    o = _S_CTRL + 3 * a
    e = g - y
    i0 = s[o]
    ii = i0 + p[b + _p._KI_DT] * e
    dd = p[b + _p._AD] * s[o + 1] + p[b + _p._KD_B] * (e - s[o + 2])
    aff = (w - wp) / p[_p._H_DT]
    f = p[b + _p._KP] * e + ii + dd + p[b + _p._MFF] * aff + p[b + _p._CFF] * w
    if p[_p._H_SAT] != 0.0:
        fpk = p[b + _p._FPK]
        if f > fpk:
            f = fpk
            if e > 0.0:
                ii = i0
        elif f < -fpk:
            f = -fpk
            if e < 0.0:
                ii = i0
    s[o] = ii
    s[o + 1] = dd
    s[o + 2] = e
    return f


@njit(cache=True, inline="always")
def _disturbance(p: np.ndarray, s: np.ndarray, a: int) -> tuple[float, float]:
    """``(F, g)``: the force opposing carriage ``a`` now and the Stribeck level ``g(v)``.

    ``F`` (N): friction, cogging, cable (y; `friction_force`); ``g`` (N) is 1 with
    friction off.
    """
    f, _zd, gv = friction_force(
        p, _p._HEADER + a * _p._BLOCK + _p._FRIC, s[3 * a], s[3 * a + 1], s[_S_Z + a]
    )  # MECH_POS: 0, 3; MECH_VEL: 1, 4
    return f, gv


@njit(cache=True, inline="always")
def _mech_step(
    p: np.ndarray, s: np.ndarray, iphi: int, igu: int, igd: int, fx: float, fy: float,
    dx: float, dy: float,
) -> None:  # fmt: skip
    """``s_mech <- Φ s_mech + Γu (fx, fy) + Γd (dx, dy)`` in place (``igd < 0``: no Γd)."""
    n = N_MECH
    for i in range(n):
        acc = 0.0
        r = iphi + i * n
        for j in range(n):
            acc += p[r + j] * s[j]
        acc += p[igu + 2 * i] * fx + p[igu + 2 * i + 1] * fy
        if igd >= 0:
            acc += p[igd + 2 * i] * dx + p[igd + 2 * i + 1] * dy
        s[_S_SCR + i] = acc
    for i in range(n):
        s[i] = s[_S_SCR + i]


@njit(cache=True)
def kernel_output(p: np.ndarray, s: np.ndarray, y: np.ndarray) -> None:
    """Write the encoder positions ``(x, y)`` (m) into ``y``, shape (2,)."""
    y[0] = _quantise(p, s[0])
    y[1] = _quantise(p, s[3])


@njit(cache=True)
def kernel_update(p: np.ndarray, s: np.ndarray, u: np.ndarray) -> None:
    """Advance ``s`` one sample in place under the set-points ``u`` (m), held."""
    wpx = s[_S_GUARD + 1]
    wpy = s[_S_GUARD + _G + 1]
    gx, wx, cx, px_, vx_, ax_ = _guard(p, s, 0, u[0])
    gy, wy, cy, py_, vy_, ay_ = _guard(p, s, 1, u[1])
    fx = _control(p, s, 0, gx, wx, wpx, _quantise(p, s[0]))
    fy = _control(p, s, 1, gy, wy, wpy, _quantise(p, s[3]))
    if p[_p._H_DIST] != 0.0:
        for _ in range(int(p[_p._H_NSUB])):
            dxf, gx_ = _disturbance(p, s, 0)
            dyf, gy_ = _disturbance(p, s, 1)
            x0 = s[0]
            y0 = s[3]
            _mech_step(p, s, _p._PHI_H, _p._GU_H, _p._GD_H, fx, fy, dxf, dyf)
            if p[_p._H_FRIC] != 0.0:
                s[_S_Z] = bristle_step(p, _FRIC_X, s[_S_Z], s[0] - x0, gx_)
                s[_S_Z + 1] = bristle_step(p, _FRIC_Y, s[_S_Z + 1], s[3] - y0, gy_)
    else:
        _mech_step(p, s, _p._PHI_DT, _p._GU_DT, -1, fx, fy, 0.0, 0.0)
    s[_S_GUARD] = gx
    s[_S_GUARD + 1] = wx
    s[_S_GUARD + _G] = gy
    s[_S_GUARD + _G + 1] = wy
    s[_S_COUNT] += cx | cy
    s[_S_COUNT + 1] += px_ | py_
    s[_S_COUNT + 2] += vx_ | vy_
    s[_S_COUNT + 3] += ax_ | ay_
    s[_S_K] += 1.0
