"""Numba kernels of the Eulerian slender-jet model (one time step, breakup bookkeeping).

The model and its discretisation are described in :mod:`.jet_euler`. This module holds
the per-cell loops. All quantities are dimensionless (length: nozzle radius ``R``; time:
capillary time ``sqrt(rho R^3 / sigma)``; stress: ``sigma / R``).

Grid
----
``n`` uniform cells of length ``dz`` on ``[0, n dz]``; cell ``i`` spans
``[i dz, (i + 1) dz]``. Cell arrays (length ``n``): ``a = h^2`` (cell mean of the
squared radius), ``azz``, ``arr`` (polymer conformation). Face arrays (length ``n + 1``):
``u`` (axial velocity at ``z = j dz``; face ``j`` lies between cells ``j - 1`` and ``j``).

Boundary codes
--------------
``BC_NOZZLE`` (left only): nozzle exit, prescribed face velocity, ghost cells of
``a = a_nozzle`` and an unstretched conformation. ``BC_WALL``: symmetry plane, zero
velocity, mirrored cells. ``BC_OUTFLOW`` (right only): zero gradient.

Parameter vector ``par`` (float64)
---------------------------------
Indexed by the ``P_*`` constants: ``dz``, solvent Ohnesorge number, polymer modulus
``G = Oh_p / De``, ``1 / De``, ``1 / L^2`` (0: Oldroyd-B), film area ``a_film``, nozzle
area, CFL number, breakup radius, re-wetting factor, largest time step.

Integer vector ``ipar`` (int64)
-------------------------------
Indexed by ``I_*``: left and right boundary codes, flux limiter (0: van Leer, 1: minmod),
meniscus code (``MENISCUS_*``), coupled upstream acoustics (0/1).

Moving meniscus
---------------
With a retracting meniscus the grid's left end is the meniscus at ``z_m <= 0`` (lab
frame), and cell ``i`` spans ``[z_m + i dz, z_m + (i + 1) dz]``: the grid moves with the
meniscus (frame velocity ``w``, uniform), so every flux is carried by the velocity
relative to the grid, ``u - w``, while ``u`` stays the lab velocity (no fictitious force:
only the coordinate moves). Positions handed back are in the lab frame.

The codes and indices are in :mod:`.jet_euler_codes` and the breakup bookkeeping
(:func:`analyse`) in :mod:`.jet_euler_breakup`; both are re-exported here.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from microfab.process.inkjet.jet_euler_breakup import _cross_left as _cross_left
from microfab.process.inkjet.jet_euler_breakup import _cross_right as _cross_right
from microfab.process.inkjet.jet_euler_breakup import _runs as _runs
from microfab.process.inkjet.jet_euler_breakup import analyse
from microfab.process.inkjet.jet_euler_codes import (
    BC_NOZZLE,
    BC_OUTFLOW,
    BC_WALL,
    HIST_ROWS,
    I_BL,
    I_BR,
    I_LIMITER,
    P_A_FILM,
    P_A_NOZ,
    P_CFL,
    P_DT_MAX,
    P_DZ,
    P_GP,
    P_INV_DE,
    P_INV_L2,
    P_OH,
)
from microfab.process.inkjet.jet_euler_codes import EV_COLS as EV_COLS
from microfab.process.inkjet.jet_euler_codes import I_COUPLED as I_COUPLED
from microfab.process.inkjet.jet_euler_codes import I_MENISCUS as I_MENISCUS
from microfab.process.inkjet.jet_euler_codes import MENISCUS_PINNED as MENISCUS_PINNED
from microfab.process.inkjet.jet_euler_codes import MENISCUS_RETRACTING as MENISCUS_RETRACTING
from microfab.process.inkjet.jet_euler_codes import MIN_CELLS as MIN_CELLS
from microfab.process.inkjet.jet_euler_codes import N_IPAR as N_IPAR
from microfab.process.inkjet.jet_euler_codes import N_PAR as N_PAR
from microfab.process.inkjet.jet_euler_codes import P_BACK as P_BACK
from microfab.process.inkjet.jet_euler_codes import P_BORE as P_BORE
from microfab.process.inkjet.jet_euler_codes import P_CAP as P_CAP
from microfab.process.inkjet.jet_euler_codes import P_DEPIN as P_DEPIN
from microfab.process.inkjet.jet_euler_codes import P_H_BREAK as P_H_BREAK
from microfab.process.inkjet.jet_euler_codes import P_REWET as P_REWET

__all__ = [
    "BC_NOZZLE",
    "BC_OUTFLOW",
    "BC_WALL",
    "HIST_ROWS",
    "analyse",
    "step",
]


@njit(cache=True)
def _phi(r: float, kind: int) -> float:
    """Flux limiter: van Leer (``kind`` 0) or minmod (1)."""
    if kind == 1:
        return max(0.0, min(1.0, r))
    ar = abs(r)
    return (r + ar) / (1.0 + ar)


@njit(cache=True)
def _ghost_cells(a: np.ndarray, bl: int, br: int, left: float, out: np.ndarray) -> None:
    """``out[i + 2] = a[i]`` with two ghost cells either side (``left`` at a nozzle)."""
    n = a.size
    for i in range(n):
        out[i + 2] = a[i]
    if bl == BC_NOZZLE:
        out[1] = left
        out[0] = left
    else:
        out[1] = a[0]
        out[0] = a[1] if n > 1 else a[0]
    if br == BC_WALL:
        out[n + 2] = a[n - 1]
        out[n + 3] = a[n - 2] if n > 1 else a[n - 1]
    else:
        out[n + 2] = a[n - 1]
        out[n + 3] = a[n - 1]


@njit(cache=True)
def _ghost_faces(u: np.ndarray, bl: int, br: int, out: np.ndarray) -> None:
    """``out[j + 1] = u[j]`` with one ghost face either side."""
    nf = u.size
    for j in range(nf):
        out[j + 1] = u[j]
    out[0] = u[0] if bl == BC_NOZZLE else -u[1]
    out[nf + 1] = -u[nf - 2] if br == BC_WALL else u[nf - 1]


@njit(cache=True)
def _fene(azz: float, arr: float, inv_l2: float) -> float:
    """FENE-P factor ``f = (1 - 3/L^2) / (1 - tr A / L^2)`` (1 for Oldroyd-B)."""
    if inv_l2 == 0.0:
        return 1.0
    den = 1.0 - (azz + 2.0 * arr) * inv_l2
    if den <= 1e-12:
        den = 1e-12
    return (1.0 - 3.0 * inv_l2) / den


@njit(cache=True)
def _film_switch(a: float, a_film: float) -> float:
    """Weight of the capillary tension: 0 in the film (``a <= a_film``), 1 from ``4 a_film``.

    A smoothstep in ``a``; without it the film, a thread of radius ``film``, would retract
    at the Taylor-Culick speed from every place where it ends (the nozzle rim, a drop)
    and drain itself.
    """
    x = (a - a_film) / (3.0 * a_film)
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@njit(cache=True)
def _tension(am: float, a0: float, ap: float, dz: float) -> float:
    """Capillary tension ``4 a^2 (2 + a_zz) / (4 a + a_z^2)^(3/2)`` by central differences."""
    az = (ap - am) / (2.0 * dz)
    azz = (ap - 2.0 * a0 + am) / (dz * dz)
    q = 4.0 * a0 + az * az
    return 4.0 * a0 * a0 * (2.0 + azz) / (q * np.sqrt(q))


@njit(cache=True)
def time_step_limit(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    par: np.ndarray,
    w: float = 0.0,
) -> float:
    """Largest stable explicit step: advection, capillary waves, polymer waves.

    * advection (TVD fluxes, Burgers momentum): ``cfl dz / max |u|`` (and ``|u - w|``
      on a grid moving at ``w``);
    * capillary waves, treated explicitly in forward-backward order (velocity from the
      old profile, profile from the new velocity, stable for ``omega dt <= 2``), the
      grid-scale frequency being ``omega = (4 / dz^2) sqrt(h / 2)``:
      ``min(2 cfl, 0.9) dz^2 / sqrt(2 h_max)``;
    * polymer stress (explicit, relaxation implicit): the two-variable scheme for
      ``u`` and the stress is stable while ``G_eff dt^2 k^2 <= 2 (2 + dt / De)`` with
      ``k^2 = 4 / dz^2``, ``G_eff = G f (2 A_zz + A_rr) (1 + f tr A / (L^2 - 3))``; this
      is ``dz / sqrt(G_eff)`` for an elastic solid and ``dz^2 / (6 Oh_p)`` for a fast
      relaxing polymer.
    """
    dz = par[P_DZ]
    cfl = par[P_CFL]
    a_film = par[P_A_FILM]
    gp = par[P_GP]
    inv_de = par[P_INV_DE]
    inv_l2 = par[P_INV_L2]
    umax = 0.0
    for j in range(u.size):
        umax = max(umax, abs(u[j]), abs(u[j] - w))
    amax = par[P_A_NOZ]
    geff = 0.0
    for i in range(a.size):
        amax = max(amax, a[i])
        if gp > 0.0 and a[i] > a_film:
            f = _fene(azz[i], arr[i], inv_l2)
            tr = azz[i] + 2.0 * arr[i]
            stiff = 1.0
            if inv_l2 > 0.0:
                stiff += f * tr * inv_l2 / (1.0 - 3.0 * inv_l2)
            geff = max(geff, gp * f * (2.0 * azz[i] + arr[i]) * stiff)
    dt = par[P_DT_MAX]
    if umax > 0.0:
        dt = min(dt, cfl * dz / umax)
    dt = min(dt, min(2.0 * cfl, 0.9) * dz * dz / np.sqrt(2.0 * np.sqrt(amax)))
    if geff > 0.0:
        k2 = 4.0 / (dz * dz)
        dt_el = (2.0 * inv_de + np.sqrt(4.0 * inv_de * inv_de + 16.0 * geff * k2)) / (
            2.0 * geff * k2
        )
        dt = min(dt, cfl * dt_el)
    return dt


@njit(cache=True)
def _limited(q: np.ndarray, iu: int, idn: int, iuu: int, nu: float, lim: int) -> float:
    """Face value of ``q`` from its upwind cell ``iu``: limited Lax-Wendroff (Sweby 1984)."""
    d = q[idn] - q[iu]
    if d == 0.0:
        return q[iu]
    return q[iu] + 0.5 * (1.0 - nu) * _phi((q[iu] - q[iuu]) / d, lim) * d


@njit(cache=True)
def _face_fluxes(
    ae: np.ndarray,
    cz: np.ndarray,
    cr: np.ndarray,
    vel: np.ndarray,
    lam: float,
    bl: int,
    br: int,
    lim: int,
    poly: bool,
    flux: np.ndarray,
    fz: np.ndarray,
    fr: np.ndarray,
) -> None:
    """TVD fluxes of ``a`` (and of ``a A_zz``, ``a A_rr``) through the faces, velocity ``vel``.

    ``ae``, ``cz``, ``cr`` carry two ghost cells either side (see :func:`_ghost_cells`).
    Interior faces use the flux-limited Lax-Wendroff face value; the two end faces are
    first-order upwind (a nozzle supplies ``a_nozzle`` and an unstretched polymer).
    """
    n = vel.size - 1
    for j in range(n + 1):
        w = vel[j]
        if j == 0 or j == n:
            if (j == 0 and bl == BC_WALL) or (j == n and br == BC_WALL):
                flux[j] = 0.0
                fz[j] = 0.0
                fr[j] = 0.0
                continue
            iu = (j + 1 if w >= 0.0 else j + 2) if j == 0 else n + 1
            flux[j] = w * ae[iu]
            if poly:
                fz[j] = flux[j] * cz[iu]
                fr[j] = flux[j] * cr[iu]
            continue
        nu = abs(w) * lam
        if w >= 0.0:
            iu, idn, iuu = j + 1, j + 2, j
        else:
            iu, idn, iuu = j + 2, j + 1, j + 3
        flux[j] = w * _limited(ae, iu, idn, iuu, nu, lim)
        if poly:
            fz[j] = flux[j] * _limited(cz, iu, idn, iuu, nu, lim)
            fr[j] = flux[j] * _limited(cr, iu, idn, iuu, nu, lim)


@njit(cache=True)
def step(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    dt: float,
    u_left: float,
    par: np.ndarray,
    ipar: np.ndarray,
    a_new: np.ndarray,
    u_new: np.ndarray,
    azz_new: np.ndarray,
    arr_new: np.ndarray,
    w_grid: float = 0.0,
    rel_left: float = np.nan,
    a_left: float = np.nan,
) -> tuple:
    """One time step; returns ``(ok, flux_in, flux_out)``.

    ``u_left`` is the lab velocity of the left face (a nozzle's), ``w_grid`` the velocity of
    the grid (a moving meniscus; 0 on a fixed grid) and ``rel_left`` the velocity of the
    liquid through the left face relative to it (default ``u_left - w``); all fluxes are
    carried by ``u - w``. ``a_left`` replaces the nozzle's ghost area (default
    ``a_nozzle``), e.g. the film when a meniscus with nothing attached moves through it.

    Order (forward-backward, first order in time): (1) face velocities from the old
    profile and conformation (momentum advection in the conservative staggered form of
    Stelling & Duinmeijer, Int. J. Numer. Meth. Fluids 43, 1329, 2003, with limited
    upwind face velocities, over the face's mass after the liquid that arrives at it
    where that is larger; capillary and polymer tension explicit), the solvent
    viscous stress implicit (one tridiagonal solve); (2) the squared radius from the
    new velocities with TVD fluxes; (3) the polymer content ``a A`` with the same
    fluxes, then stretching (exact exponential over the step) and relaxation (implicit,
    solved exactly). ``ok`` is False if the step produced a negative or non-finite area
    (the caller retries with a shorter step). ``flux_in`` and ``flux_out`` are the
    volume fluxes over pi
    through the left and right ends (positive in the +z direction).
    """
    n = a.size
    dz = par[P_DZ]
    oh = par[P_OH]
    gp = par[P_GP]
    inv_de = par[P_INV_DE]
    inv_l2 = par[P_INV_L2]
    a_film = par[P_A_FILM]
    a_noz = par[P_A_NOZ]
    bl = ipar[I_BL]
    br = ipar[I_BR]
    lim = ipar[I_LIMITER]
    lam = dt / dz

    ae = np.empty(n + 4)
    _ghost_cells(a, bl, br, a_noz if np.isnan(a_left) else a_left, ae)
    ef = np.empty(n + 4)  # regularised area
    for i in range(n + 4):
        ef[i] = max(ae[i], a_film)
    ue = np.empty(n + 4)
    _ghost_faces(u, bl, br, ue)

    # --- tension per cell: capillary + polymer (explicit) ---
    s = np.empty(n)
    for i in range(n):
        s[i] = _tension(ef[i + 1], ef[i + 2], ef[i + 3], dz) * _film_switch(a[i], a_film)
        if gp > 0.0:
            f = _fene(azz[i], arr[i], inv_l2)
            s[i] += a[i] * gp * f * (azz[i] - arr[i])

    # --- momentum advection, conservative (Stelling & Duinmeijer 2003) ---
    # mass fluxes with the old velocities, averaged to the cell centres, carry the
    # limited upwind face velocity; the face's momentum balance then gives u u_z
    poly = gp > 0.0
    cz = np.ones(n + 4)
    cr = np.ones(n + 4)
    if poly:
        _ghost_cells(azz, bl, br, 1.0, cz)
        _ghost_cells(arr, bl, br, 1.0, cr)
    flux = np.empty(n + 1)
    fz = np.zeros(n + 1)
    fr = np.zeros(n + 1)
    rel0 = u_left - w_grid if np.isnan(rel_left) else rel_left
    ur = np.empty(n + 1)
    for j in range(n + 1):
        ur[j] = u[j] - w_grid
    if bl == BC_NOZZLE:
        ur[0] = rel0
    _face_fluxes(ae, cz, cr, ur, lam, bl, br, lim, False, flux, fz, fr)
    qc = np.empty(n)
    mflux = np.empty(n)
    for i in range(n):
        qc[i] = 0.5 * (flux[i] + flux[i + 1])
        nu = 0.5 * abs(ue[i + 1] + ue[i + 2] - 2.0 * w_grid) * lam
        if qc[i] >= 0.0:
            us = _limited(ue, i + 1, i + 2, i, nu, lim)
        else:
            us = _limited(ue, i + 2, i + 1, i + 3, nu, lim)
        mflux[i] = qc[i] * us

    # --- momentum at interior faces 1..n-1, implicit viscosity (Thomas algorithm) ---
    # face j between cells j-1 and j; unknowns u_1..u_{n-1}
    m = n - 1
    lo = np.zeros(m)
    di = np.zeros(m)
    up = np.zeros(m)
    rhs = np.zeros(m)
    u0 = u_left if bl == BC_NOZZLE else 0.0
    for k in range(m):
        j = k + 1
        el = ef[j + 1]  # cell j-1 (regularised)
        er = ef[j + 2]  # cell j
        af = 0.5 * (el + er)
        adv = mflux[j] - mflux[j - 1] - u[j] * (qc[j] - qc[j - 1])
        # liquid arriving at a face shares its momentum with it: divide by the face's
        # mass after the arrival (conservative), not before, or a face in the film that
        # receives a front's liquid is flung at (arrived mass / film) times its speed
        af_adv = max(af, af - lam * (qc[j] - qc[j - 1]))
        rhs[k] = u[j] + lam * ((s[j] - s[j - 1]) / af - adv / af_adv)
        kap = dt * 3.0 * oh / (af * dz * dz)
        right_visc = not (br == BC_OUTFLOW and j == n - 1)
        lo[k] = -kap * el
        di[k] = 1.0 + kap * el + (kap * er if right_visc else 0.0)
        up[k] = -kap * er if (right_visc and k < m - 1) else 0.0
        if k == 0:
            rhs[k] += kap * el * u0
            lo[k] = 0.0
    for k in range(1, m):
        w = lo[k] / di[k - 1]
        di[k] -= w * up[k - 1]
        rhs[k] -= w * rhs[k - 1]
    u_new[0] = u0
    u_new[m] = rhs[m - 1] / di[m - 1]
    for k in range(m - 2, -1, -1):
        u_new[k + 1] = (rhs[k] - up[k] * u_new[k + 2]) / di[k]
    u_new[n] = u_new[n - 1] if br == BC_OUTFLOW else 0.0

    # --- TVD fluxes of a (and of a A) with the new velocities (relative to the grid) ---
    for j in range(n + 1):
        ur[j] = u_new[j] - w_grid
    if bl == BC_NOZZLE:
        ur[0] = rel0
    _face_fluxes(ae, cz, cr, ur, lam, bl, br, lim, poly, flux, fz, fr)

    ok = True
    for i in range(n):
        an = a[i] - lam * (flux[i + 1] - flux[i])
        if not (an >= 0.0) or not np.isfinite(an):
            ok = False
        a_new[i] = an
    if not ok:
        return False, 0.0, 0.0

    # --- polymer: advect a A, stretch, relax ---
    if poly:
        c = dt * inv_de
        b = 1.0 - 3.0 * inv_l2
        for i in range(n):
            an = a_new[i]
            if an < a_film:
                azz_new[i] = 1.0  # no polymer in the regularising film
                arr_new[i] = 1.0
                continue
            qz = (a[i] * azz[i] - lam * (fz[i + 1] - fz[i])) / an
            qr = (a[i] * arr[i] - lam * (fr[i + 1] - fr[i])) / an
            uz = (u_new[i + 1] - u_new[i]) / dz
            qz = max(qz, 0.0) * np.exp(2.0 * uz * dt)
            qr = max(qr, 0.0) * np.exp(-uz * dt)
            # implicit relaxation: A = (A* + c) / (1 + c f(A)), f from tr A (exact root)
            big = qz + 2.0 * qr + 3.0 * c
            if inv_l2 > 0.0:
                bb = 1.0 + c * b + big * inv_l2
                tr = 2.0 * big / (bb + np.sqrt(max(bb * bb - 4.0 * big * inv_l2, 0.0)))
                f = b / max(1.0 - tr * inv_l2, 1e-12)
            else:
                f = 1.0
            azz_new[i] = (qz + c) / (1.0 + c * f)
            arr_new[i] = (qr + c) / (1.0 + c * f)
            if not (np.isfinite(azz_new[i]) and np.isfinite(arr_new[i])):
                return False, 0.0, 0.0
    else:
        for i in range(n):
            azz_new[i] = 1.0
            arr_new[i] = 1.0
    return True, flux[0], flux[n]
