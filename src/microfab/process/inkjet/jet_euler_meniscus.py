"""Numba kernels of the Eulerian jet's time march: the meniscus in the bore and its acoustics.

The grid and one time step are in :mod:`.jet_euler_kernels`; this module marches them in
time with what happens at the nozzle. All quantities are dimensionless (length: nozzle
radius ``R``; time: capillary time ``t_c = sqrt(rho R^3 / sigma)``; pressure:
``sigma / R``).

The meniscus
------------
The bore of the nozzle is a straight tube of radius ``R`` (1) behind the exit plane
``z = 0``. The liquid column in it ends in the meniscus, whose centre sits at
``z_m <= 0``. The column moves with the nozzle flow ``u_c`` (the upstream model's output,
positive out of the nozzle), so over a step the column advances by
``Δ = ∫ u_c dt``:

* **pinned** (``z_m = 0``): the meniscus is held by the rim. Outflow (``Δ > 0``) enters
  the grid through its left face with the full nozzle area behind it (the ghost cell
  ``a = 1``). Suction (``Δ < 0``) draws liquid back out of the grid's first cell, as
  long as the liquid at the rim is at least as wide as the bore (``a_0 >= 1``: the
  meniscus bulges out, so the suction drains the bulge); once it is narrower, the
  meniscus lets go of the rim;
* **retracted** (``z_m < 0``): the meniscus is a material surface that moves with the
  column, ``z_m <- min(0, z_m + Δ)``; no liquid crosses it, and the liquid outside is
  attached to it, so a retreating meniscus pulls the root of the jet into the bore
  (the grid moves with it: :mod:`.jet_euler_kernels`, "Moving meniscus"). When it comes
  back to the rim it is pinned again, and the rest of the step's advance enters the grid.

With ``MENISCUS_PINNED`` the meniscus never leaves the rim, and suction always drains the
grid's first cell (the earlier model, kept for the solver checks and comparison).

The meniscus pressure (two-way coupling)
----------------------------------------
The upstream model (the dispenser's acoustics) needs the pressure ``p_m`` that the
meniscus and the liquid outside exert on the liquid in the bore; it replaces the lumped
meniscus spring of :mod:`microfab.plants.printhead`, so the meniscus is counted once, here:

* pinned: the normal stress at the root of the liquid outside, taken in the grid's first
  cell: capillary pressure ``κ`` (full curvature, with the rim's ``a = 1`` as its left
  neighbour; zero in the film, so a flat meniscus at rest gives ``p_m = 0``) minus the
  axial viscous stress ``3 Oh u_z`` and the polymer stress ``G f (A_zz - A_rr)``, these
  two over the root's section ``min(a_0, 1)`` of the bore (so the film pulls on nothing);
  the rim takes the axial pull of the surface tension ring;
* retracted: a concave spherical cap of the bore's radius and the mean depth
  ``δ = -z_m`` (the volume drawn back over the bore area): with ``d`` its centre depth,
  ``δ = d (3 + d²) / 6`` and ``p_m = -4 d / (1 + d²)`` (Laplace: ``2 / R_c`` with
  ``R_c = (1 + d²) / (2 d)``) up to the hemisphere (``δ = 2/3``, ``p_m = -2``); deeper,
  the contact line slides along the wall with the hemisphere's pressure ``-2`` (a fully
  wetting wall, ASSUMPTION: clean glass and water). For small depths this is ``-8 δ``,
  the lumped compliance ``C_m = π R⁴ / (8 σ)``. The pull of the thread attached to the
  meniscus (a force ``π h² σ / h`` with ``h << R``) is neglected.

The upstream model is linear and time invariant, sampled at a fixed step ``dt_u`` with
its inputs held over each step: state ``x``, ``x <- Φ x + γ_v s_k + γ_p p_m``, nozzle
velocity ``u_c = c·x``; ``s_k`` is the drive's mean voltage slope over step ``k`` and
``p_m`` is evaluated from the grid when the step is taken (an explicit coupling, lagging
by at most one upstream step). Its velocity is linear between the samples and its
displacement is integrated exactly from that.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from microfab.process.inkjet import jet_euler_kernels as ek

__all__ = ["advance", "cap_depth", "meniscus_pressure", "static_meniscus"]

#: Mean depth of the hemispherical meniscus (volume ``2 π R³ / 3`` over the bore area).
HEMISPHERE_DEPTH = 2.0 / 3.0

#: Under suction a pinned meniscus drains the liquid outside through the rim while the
#: root of that liquid (the grid's first cell) is at least this wide (squared radius over
#: the bore's, i.e. a root radius of half the bore): it is then a bulge. A thinner root is
#: a thread on the meniscus, which lets go of the rim and retracts into the bore with the
#: column, pulling the thread. ASSUMPTION: the seed does not image the meniscus; a root
#: half the bore wide is taken as where a bulge has become a neck.
DEPIN_AREA = 0.25


@njit(cache=True)
def cap_depth(mean_depth: float) -> float:
    """Centre depth ``d`` of a spherical cap in a unit bore with mean depth ``δ``.

    The root of ``d³ + 3 d - 6 δ = 0`` (Cardano; the cubic is monotone), so that
    ``δ = d (3 + d²) / 6``. Negative ``δ`` gives the mirror image.
    """
    q = 3.0 * mean_depth
    r = np.sqrt(q * q + 1.0)
    return np.cbrt(q + r) + np.cbrt(q - r)


@njit(cache=True)
def cap_pressure(z_m: float) -> float:
    """Laplace pressure of a spherical-cap meniscus spanning the bore, mean position ``z_m``.

    ``z_m < 0``: concave, drawn into the bore (``-2``, the hemisphere, from a mean depth
    of 2/3 on: the contact line slides); ``z_m > 0``: a convex cap bulging out of the rim.
    ``p = 4 d / (1 + d²)`` with ``d`` the signed centre height (:func:`cap_depth`).
    """
    if z_m <= -HEMISPHERE_DEPTH:
        return -2.0
    d = cap_depth(z_m)
    return 4.0 * d / (1.0 + d * d)


def static_meniscus(back_pressure: float) -> float:
    """Mean position of the meniscus at rest under a static back pressure (dimensionless).

    The liquid in the bore at rest is at the back pressure ``p_b`` (``sigma / R``), which
    the meniscus balances with its Laplace pressure (:func:`cap_pressure`): a convex cap on
    the rim for ``p_b > 0``, a concave one in the bore for ``p_b < 0``, with centre height
    ``d`` from ``4 d / (1 + d²) = |p_b|`` (the smaller root) and mean position
    ``± d (3 + d²) / 6``. Beyond the hemisphere's ``|p_b| = 2`` (``2 sigma / R``) no cap
    holds the liquid: it drips out or is drawn into the bore.

    Parameters
    ----------
    back_pressure : float
        Static pressure on the liquid in the bore over ambient, ``sigma / R``, in
        ``(-2, 2)``.

    Returns
    -------
    float
        Mean meniscus position in nozzle radii (> 0 out of the rim, < 0 in the bore).

    Raises
    ------
    ValueError
        For ``|back_pressure| >= 2`` or a value that is not finite.

    Examples
    --------
    >>> static_meniscus(0.0)
    0.0
    >>> round(float(cap_pressure(static_meniscus(-0.8))), 12)
    -0.8
    """
    p = float(back_pressure)
    if not (np.isfinite(p) and abs(p) < 2.0):
        raise ValueError(
            f"back pressure {back_pressure!r} (sigma / R) must lie in (-2, 2): beyond the "
            "bore's Laplace pressure 2 sigma / R no meniscus holds"
        )
    if p == 0.0:
        return 0.0
    q = abs(p)
    d = (2.0 - np.sqrt(4.0 - q * q)) / q
    return float(np.copysign(d * (3.0 + d * d) / 6.0, p))


@njit(cache=True)
def _cap_integral(z: float, d: float) -> float:
    """``∫_0^z h² dz'`` of a convex cap of centre height ``d`` pinned at the rim (``z <= d``)."""
    rc = (1.0 + d * d) / (2.0 * d)
    zc = d - rc
    return rc * rc * z - ((z - zc) ** 3 - (-zc) ** 3) / 3.0


@njit(cache=True)
def _take_back(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    wet: np.ndarray,
    par: np.ndarray,
) -> float:
    """Lump a bulge on the rim back into a cap if it is no larger than a handed-over one.

    The inverse of :func:`_hand_over`, so that a small bulge is a lumped cap whichever
    way it goes: the liquid body hanging on the rim (the run of wet cells from the
    first), if its volume over pi is at most the hand-over volume ``par[P_CAP]``, leaves
    the grid (its cells go back to the film, exactly: the volume removed is what was above
    the film) and becomes a cap of that mean height. Returns the height (0: none taken).
    """
    n = a.size
    dz = par[ek.P_DZ]
    a_film = par[ek.P_A_FILM]
    j = 0
    vol = 0.0
    while j < n and wet[j]:
        vol += (a[j] - a_film) * dz
        j += 1
        if vol > par[ek.P_CAP]:
            return 0.0  # a jet, not a bulge: no need to measure all of it
    if j == n or vol <= 0.0:
        return 0.0
    for i in range(j):
        a[i] = a_film
        u[i + 1] = 0.0
        azz[i] = 1.0
        arr[i] = 1.0
        wet[i] = False
    return vol


@njit(cache=True)
def _hand_over(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    wet: np.ndarray,
    z_cap: float,
    u_cap: float,
    par: np.ndarray,
) -> float:
    """Put a lumped convex cap of mean height ``z_cap`` on the grid at the rim.

    The grid's origin moves from the cap's mean surface to the rim: what hung on the
    meniscus moves out to the cap's apex at ``d`` (conservative overlap remap of the cell
    contents, linear interpolation of the face velocities), and the cells over ``[0, d]``
    get the cap's exact cell means, moving at ``u_cap``, with unstretched polymer.
    Returns the volume over pi that left through the far end.

    :func:`advance` ends the step at which a growing cap reaches ``par[P_CAP]``, so
    ``z_cap`` is that height and the apex lies on the face ``cap_cells`` from the rim,
    whatever the step sequence (only a cap that starts taller, ``meniscus_z0``, is handed
    over at its own height).
    """
    n = a.size
    dz = par[ek.P_DZ]
    d = cap_depth(z_cap)
    a0 = a.copy()
    qz = a * azz
    qr = a * arr
    u0 = u.copy()
    total = 0.0
    for i in range(n):
        total += a0[i]
    kept = 0.0
    for i in range(n):
        lo = i * dz
        hi = lo + dz
        vol = 0.0
        mz = 0.0
        mr = 0.0
        if lo < d:
            top = min(hi, d)
            vol += _cap_integral(top, d) - _cap_integral(lo, d)
            mz += vol
            mr += vol
        # old contents: old cell j covers [d + j dz, d + (j + 1) dz]
        s_lo = max(lo, d) - d
        s_hi = hi - d
        if s_hi > s_lo:
            j0 = int(s_lo / dz)
            j1 = min(int(np.ceil(s_hi / dz)), n)
            for j in range(j0, j1):
                ov = min(s_hi, (j + 1) * dz) - max(s_lo, j * dz)
                if ov > 0.0:
                    f = ov / dz
                    vol += a0[j] * ov
                    mz += qz[j] * ov
                    mr += qr[j] * ov
                    kept += a0[j] * f
        a[i] = vol / dz
        if a[i] > 0.0:
            azz[i] = mz / (a[i] * dz)
            arr[i] = mr / (a[i] * dz)
        else:
            azz[i] = 1.0
            arr[i] = 1.0
        wet[i] = np.sqrt(a[i]) > par[ek.P_H_BREAK]
    for j in range(n + 1):
        z = j * dz
        if z <= d * (1.0 + 1e-9):  # the apex on a face (the cap height, to round-off)
            u[j] = u_cap
        else:
            x = (z - d) / dz
            k = min(int(x), n - 1)
            fr = x - k
            u[j] = (1.0 - fr) * u0[k] + fr * u0[k + 1]
    return (total - kept) * dz


@njit(cache=True)
def meniscus_pressure(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    z_m: float,
    par: np.ndarray,
) -> float:
    """Pressure ``p_m`` that the meniscus and the jet exert on the liquid in the bore."""
    if z_m != 0.0:
        return cap_pressure(z_m)
    a_film = par[ek.P_A_FILM]
    dz = par[ek.P_DZ]
    a0 = a[0]
    sw = ek._film_switch(a0, a_film)
    if sw == 0.0:
        return 0.0
    am = par[ek.P_A_NOZ]
    e0 = max(a0, a_film)
    ep = max(a[1], a_film)
    az = (ep - am) / (2.0 * dz)
    q = 4.0 * e0 + az * az
    s_cap = ek._tension(am, e0, ep, dz)
    kappa = (4.0 * e0 / np.sqrt(q) - s_cap) / e0
    tau = 3.0 * par[ek.P_OH] * (u[1] - u[0]) / dz
    if par[ek.P_GP] > 0.0:
        f = ek._fene(azz[0], arr[0], par[ek.P_INV_L2])
        tau += par[ek.P_GP] * f * (azz[0] - arr[0])
    # the axial stress pulls on the bore over the root's section (none in the film)
    return sw * kappa - min(a0, 1.0) * tau


@njit(cache=True)
def _displacement(d_tab: np.ndarray, t0: float, dtab: float, t: float) -> float:
    """Inflow displacement at ``t`` by linear interpolation in the table."""
    x = (t - t0) / dtab
    if x <= 0.0:
        return d_tab[0]
    k = int(x)
    if k >= d_tab.size - 1:
        return d_tab[d_tab.size - 1]
    return d_tab[k] + (x - k) * (d_tab[k + 1] - d_tab[k])


@njit(cache=True)
def _time_of_advance(
    d_tab: np.ndarray, t0: float, dtab: float, t_a: float, t_b: float, rise: float
) -> float:
    """First time in ``[t_a, t_b]`` at which the displacement has grown by ``rise`` (> 0).

    The displacement is linear between the table's samples (:func:`_displacement`), so the
    crossing is found exactly, piece by piece; ``t_b`` if it is not reached.
    """
    d_a = _displacement(d_tab, t0, dtab, t_a)
    goal = d_a + rise
    if _displacement(d_tab, t0, dtab, t_b) < goal:
        return t_b
    lo = t_a
    d_lo = d_a
    k = int((t_a - t0) / dtab) + 1
    while True:
        hi = min(t0 + k * dtab, t_b)
        d_hi = _displacement(d_tab, t0, dtab, hi)
        if d_hi >= goal:
            if d_hi <= d_lo:
                return hi
            return min(max(lo + (goal - d_lo) / (d_hi - d_lo) * (hi - lo), lo), hi)
        if hi >= t_b:
            return t_b
        lo = hi
        d_lo = d_hi
        k += 1


@njit(cache=True)
def _fill_upstream(
    t_need: float,
    tab_t0: float,
    tab_dt: float,
    d_tab: np.ndarray,
    u_tab: np.ndarray,
    x: np.ndarray,
    phi: np.ndarray,
    g_drive: np.ndarray,
    g_press: np.ndarray,
    c_row: np.ndarray,
    slopes: np.ndarray,
    counters: np.ndarray,
    p_m: float,
) -> None:
    """Step the upstream model until its table covers ``t_need`` (``counters[2]`` filled)."""
    k_need = min(int(np.ceil((t_need - tab_t0) / tab_dt - 1e-9)) + 1, d_tab.size - 1)
    k = counters[2]
    nx = x.size
    tmp = np.empty(nx)
    while k < k_need:
        s = slopes[k] if k < slopes.size else 0.0
        for i in range(nx):
            acc = g_drive[i] * s + g_press[i] * p_m
            for j in range(nx):
                acc += phi[i, j] * x[j]
            tmp[i] = acc
        vel = 0.0
        for i in range(nx):
            x[i] = tmp[i]
            vel += c_row[i] * tmp[i]
        u_tab[k + 1] = vel
        d_tab[k + 1] = d_tab[k] + 0.5 * (u_tab[k] + vel) * tab_dt
        k += 1
    counters[2] = k


@njit(cache=True)
def advance(
    a: np.ndarray,
    u: np.ndarray,
    azz: np.ndarray,
    arr: np.ndarray,
    wet: np.ndarray,
    t: float,
    t_stop: float,
    par: np.ndarray,
    ipar: np.ndarray,
    d_tab: np.ndarray,
    tab_t0: float,
    tab_dt: float,
    hist: np.ndarray,
    n_hist: int,
    max_steps: int,
    counters: np.ndarray,
    acc: np.ndarray,
    ev: np.ndarray,
    u_tab: np.ndarray,
    x: np.ndarray,
    phi: np.ndarray,
    g_drive: np.ndarray,
    g_press: np.ndarray,
    c_row: np.ndarray,
    slopes: np.ndarray,
) -> tuple:
    """Step from ``t`` towards ``t_stop`` (landing on it exactly); state updated in place.

    Returns ``(t, n_hist, status, n_events)``. Status: 0 ``t_stop`` reached, 1 breakup
    (events in ``ev``), 2 history array full, 3 step limit, 4 step size collapsed, 5
    liquid reached the open far end, 6 the meniscus retracted deeper than the bore
    (``par[P_BORE]``). ``counters`` holds accepted and rejected steps and, when coupled,
    the filled length of the upstream table; ``acc`` the volume over pi injected at the
    left end and lost at the right end, the meniscus position and the frame velocity of
    the last step. One history column (``HIST_ROWS`` rows) is written per accepted step.

    ``d_tab`` holds the nozzle displacement at the times ``tab_t0 + k tab_dt``; with
    ``ipar[I_COUPLED]`` it is filled here, step by step, from the upstream model (``x``,
    ``phi``, ``g_drive``, ``g_press``, ``c_row``, ``slopes``; velocities in ``u_tab``),
    otherwise it is given whole and the upstream arrays are not used.

    A step during which a cap on the rim would grow past the hand-over height
    ``par[P_CAP]`` is cut at the time the column has pushed it exactly there
    (:func:`_time_of_advance`), and the cap is handed to the grid (:func:`_hand_over`).
    """
    n = a.size
    a_new = np.empty(n)
    u_new = np.empty(n + 1)
    zz_new = np.empty(n)
    rr_new = np.empty(n)
    a_old = np.empty(n)
    wet_new = np.empty(n, dtype=np.bool_)
    stats = np.empty(5)
    dz = par[ek.P_DZ]
    retracting = ipar[ek.I_MENISCUS] == ek.MENISCUS_RETRACTING
    coupled = ipar[ek.I_COUPLED] == 1
    eps_t = 1e-12 * max(1.0, abs(t_stop))
    while True:
        if t >= t_stop - eps_t:
            return t, n_hist, 0, 0
        if counters[0] >= max_steps:
            return t, n_hist, 3, 0
        if n_hist >= hist.shape[1]:
            return t, n_hist, 2, 0
        z_m = acc[2]
        dt = ek.time_step_limit(a, u, azz, arr, par, acc[3])
        if retracting and z_m == 0.0 and wet[0] and u[0] < 0.0:
            acc[2] = _take_back(a, u, azz, arr, wet, par)
            acc[0] -= acc[2]
            z_m = acc[2]
        last = False
        if t + dt >= t_stop - eps_t:
            dt = t_stop - t
            last = True
        elif t + 1.5 * dt > t_stop:
            dt = 0.5 * (t_stop - t)  # two even steps rather than a sliver
        if coupled:
            # the back pressure on the liquid in the bore acts against the meniscus
            p_m = meniscus_pressure(a, u, azz, arr, z_m, par) - par[ek.P_BACK]
            _fill_upstream(
                t + dt, tab_t0, tab_dt, d_tab, u_tab, x, phi, g_drive, g_press, c_row,
                slopes, counters, p_m,
            )  # fmt: skip
        if retracting and 0.0 < z_m < par[ek.P_CAP]:
            # a growing cap is handed over when it is exactly `P_CAP` tall: the step ends
            # when the column has pushed it there, so the grid receives the same shape
            # whatever the phase of the step sequence (a taller cap put a sliver of it
            # into one more cell, whose face the next step flung forward)
            t_cap = _time_of_advance(d_tab, tab_t0, tab_dt, t, t + dt, par[ek.P_CAP] - z_m)
            if t_cap < t + dt:
                dt = t_cap - t
                last = t_cap >= t_stop - eps_t
        while True:
            d0 = _displacement(d_tab, tab_t0, tab_dt, t)
            d1 = _displacement(d_tab, tab_t0, tab_dt, t + dt)
            adv = d1 - d0
            z_new = z_m
            if retracting and (z_m != 0.0 or not wet[0] or (adv < 0.0 and a[0] < par[ek.P_DEPIN])):
                z_new = z_m + adv  # the meniscus moves with the column
                if z_m < par[ek.P_CAP] and abs(z_new - par[ek.P_CAP]) <= 1e-12:
                    z_new = par[ek.P_CAP]  # the cut step's round-off
            w = (z_new - z_m) / dt
            rel = (adv - (z_new - z_m)) / dt
            u_left = adv / dt
            a_left = np.nan
            if z_new != z_m and not wet[0]:
                # nothing hangs on the moving meniscus: the film stays where it is, at rest
                u_left = 0.0
                rel = -w
                a_left = par[ek.P_A_FILM]
            ok, f_in, f_out = ek.step(
                a, u, azz, arr, dt, u_left, par, ipar, a_new, u_new, zz_new, rr_new,
                w, rel, a_left,
            )  # fmt: skip
            if ok:
                break
            counters[1] += 1
            dt *= 0.5
            last = False
            if dt < 1e-13:
                return t, n_hist, 4, 0
        t_prev = t
        t = t_stop if last else t + dt
        acc[0] += f_in * dt
        acc[1] += f_out * dt
        if z_new >= par[ek.P_CAP]:
            # the bulge is tall enough for the grid to carry its free surface
            acc[1] += _hand_over(a_new, u_new, zz_new, rr_new, wet, z_new, adv / dt, par)
            acc[0] += z_new
            z_new = 0.0
        acc[2] = z_new
        acc[3] = w
        a_old[:] = a
        a[:] = a_new
        u[:] = u_new
        azz[:] = zz_new
        arr[:] = rr_new
        counters[0] += 1
        n_ev = ek.analyse(a, a_old, u, wet, wet_new, par, ipar, t_prev, t, stats, ev, z_new)
        wet[:] = wet_new
        vol = 0.0
        for i in range(n):
            vol += a[i]
        hist[0, n_hist] = t
        hist[1, n_hist] = stats[0]
        hist[2, n_hist] = stats[1]
        hist[3, n_hist] = stats[2]
        hist[4, n_hist] = stats[3]
        hist[5, n_hist] = vol * dz + acc[1]
        hist[6, n_hist] = acc[0]
        hist[7, n_hist] = stats[4]
        hist[8, n_hist] = z_new
        n_hist += 1
        if n_ev > 0:
            return t, n_hist, 1, n_ev
        if ipar[ek.I_BR] == ek.BC_OUTFLOW and (wet[n - 1] or wet[n - 2] or wet[n - 3]):
            return t, n_hist, 5, 0
        if -z_new > par[ek.P_BORE]:
            return t, n_hist, 6, 0
