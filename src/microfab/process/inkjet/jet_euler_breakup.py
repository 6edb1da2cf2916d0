"""Numba kernels of the Eulerian jet's breakup bookkeeping: wet cells, bodies, pinch-offs.

After each time step (:func:`.jet_euler_kernels.step`) the time march of
:mod:`.jet_euler_meniscus` calls `analyse`: it updates the wet mask (with its
hysteresis), finds the bodies of the previous step that now hold several (the breakups,
their times interpolated between the steps) and measures the neck, the tip and the body
count for the run's history. It needs nothing of the time step, so it sits apart; the
grid, the codes and the units are described in :mod:`.jet_euler_kernels`, which
re-exports `analyse`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from microfab.process.inkjet.jet_euler_codes import (
    BC_NOZZLE,
    BC_OUTFLOW,
    BC_WALL,
    I_BL,
    I_BR,
    MIN_CELLS,
    P_A_NOZ,
    P_DZ,
    P_H_BREAK,
    P_REWET,
)

__all__ = ["analyse"]


@njit(cache=True)
def _cross_left(h: np.ndarray, i: int, hb: float, dz: float) -> float:
    """Where ``h`` rises through ``hb`` between the centres of cells ``i - 1`` and ``i``."""
    zc = (i + 0.5) * dz
    if i == 0:
        return zc - 0.5 * dz
    d = h[i] - h[i - 1]
    frac = (h[i] - hb) / d if d > 0.0 else 0.5
    return zc - dz * min(max(frac, 0.0), 1.0)


@njit(cache=True)
def _cross_right(h: np.ndarray, i: int, hb: float, dz: float) -> float:
    """Where ``h`` falls through ``hb`` between the centres of cells ``i`` and ``i + 1``."""
    zc = (i + 0.5) * dz
    if i == h.size - 1:
        return zc + 0.5 * dz
    d = h[i] - h[i + 1]
    frac = (h[i] - hb) / d if d > 0.0 else 0.5
    return zc + dz * min(max(frac, 0.0), 1.0)


@njit(cache=True)
def _runs(wet: np.ndarray, lo: int, hi: int, starts: np.ndarray, ends: np.ndarray) -> int:
    """Runs of wet cells within ``[lo, hi]``: first and last cell of each; returns count."""
    k = 0
    i = lo
    while i <= hi:
        if wet[i]:
            j = i
            while j + 1 <= hi and wet[j + 1]:
                j += 1
            starts[k] = i
            ends[k] = j
            k += 1
            i = j + 1
        else:
            i += 1
    return k


@njit(cache=True)
def analyse(
    a: np.ndarray,
    a_prev: np.ndarray,
    u: np.ndarray,
    wet_prev: np.ndarray,
    wet: np.ndarray,
    par: np.ndarray,
    ipar: np.ndarray,
    t_prev: float,
    t: float,
    stats: np.ndarray,
    ev: np.ndarray,
    z_off: float = 0.0,
) -> int:
    """Update the wet mask, find breakups, and measure neck and tip; returns the event count.

    A cell is *wet* (liquid) while ``h > h_break``; a dry cell becomes wet again only
    above ``rewet h_break`` (hysteresis, so that a neck hovering at ``h_break`` does not
    break and heal over and over). Runs of at least ``MIN_CELLS`` wet cells are bodies;
    a nozzle boundary counts as a wet run of any length on the left. A *breakup* is a
    body of the previous step that now holds two or more bodies (or the nozzle and a
    body) separated by dry cells; each separation is one event, at the thinnest cell
    between the two, its time interpolated linearly in ``h`` between the steps.

    ``stats`` receives: neck radius (thinnest local minimum of ``h`` over cells inside a
    body, not a body's end cell unless that end is the nozzle or a wall; ``inf`` if
    none), neck z, tip z (the leading body's right end, where ``h`` falls through
    ``h_break`` by linear interpolation between cell centres), tip velocity (face to the
    right of the last wet cell), number of bodies. ``ev`` rows: t, neck z, tip z and tail
    z of the body that broke (tail 0 when it hung on the nozzle), attached (1/0), cell.
    Positions are in the lab frame: the grid's left end lies at ``z_off`` (a retracted
    meniscus), which is then also the tail of a body hanging on the nozzle.
    """
    n = a.size
    dz = par[P_DZ]
    hb = par[P_H_BREAK]
    rew = par[P_REWET]
    bl = ipar[I_BL]
    br = ipar[I_BR]
    h = np.sqrt(a)
    hp = np.sqrt(a_prev)
    for i in range(n):
        wet[i] = h[i] > hb if wet_prev[i] else h[i] > rew * hb
    nozzle = bl == BC_NOZZLE
    starts = np.empty(n + 1, dtype=np.int64)
    ends = np.empty(n + 1, dtype=np.int64)
    sub_s = np.empty(n + 1, dtype=np.int64)
    sub_e = np.empty(n + 1, dtype=np.int64)
    n_ev = 0
    # --- breakups: previous bodies that now hold several ---
    n_prev = _runs(wet_prev, 0, n - 1, starts, ends)
    for r in range(n_prev):
        p0 = starts[r]
        p1 = ends[r]
        on_nozzle = nozzle and p0 == 0
        if p1 - p0 + 1 < MIN_CELLS and not on_nozzle:
            continue
        k = _runs(wet, p0, p1, sub_s, sub_e)
        # keep only the sub-runs that are bodies; the nozzle is one on the left
        sig_s = np.empty(k + 1, dtype=np.int64)
        sig_e = np.empty(k + 1, dtype=np.int64)
        ns = 0
        if on_nozzle:
            sig_s[0] = -1
            sig_e[0] = -1
            ns = 1
        for q in range(k):
            if sub_e[q] - sub_s[q] + 1 >= MIN_CELLS:
                if on_nozzle and ns == 1 and sub_s[q] == 0:
                    sig_e[0] = sub_e[q]  # the nozzle's own body
                    continue
                sig_s[ns] = sub_s[q]
                sig_e[ns] = sub_e[q]
                ns += 1
        if ns < 2:
            continue
        z_tip = _cross_right(h, sig_e[ns - 1], hb, dz)
        z_tip += z_off
        z_tail = z_off if on_nozzle else _cross_left(h, sig_s[0], hb, dz) + z_off
        for q in range(ns - 1):
            g0 = sig_e[q] + 1
            g1 = sig_s[q + 1] - 1
            kmin = g0
            for i in range(g0, g1 + 1):
                if h[i] < h[kmin]:
                    kmin = i
            frac = 1.0
            if hp[kmin] > h[kmin]:
                frac = min(max((hp[kmin] - hb) / (hp[kmin] - h[kmin]), 0.0), 1.0)
            if n_ev < ev.shape[0]:
                ev[n_ev, 0] = t_prev + frac * (t - t_prev)
                ev[n_ev, 1] = (kmin + 0.5) * dz + z_off
                ev[n_ev, 2] = z_tip
                ev[n_ev, 3] = z_tail
                ev[n_ev, 4] = 1.0 if on_nozzle else 0.0
                ev[n_ev, 5] = kmin
                n_ev += 1
    # --- neck, tip, body count on the new mask ---
    nr = _runs(wet, 0, n - 1, starts, ends)
    neck = np.inf
    neck_z = np.nan
    n_bodies = 0
    last = -1
    for r in range(nr):
        r0 = starts[r]
        r1 = ends[r]
        if r1 - r0 + 1 < MIN_CELLS:
            continue
        n_bodies += 1
        last = r1
        for i in range(r0, r1 + 1):
            left_closed = i > r0 or (i == 0 and bl != BC_OUTFLOW)
            right_closed = i < r1 or (i == n - 1 and br == BC_WALL)
            if not (left_closed and right_closed):
                continue
            if i > 0:
                hl = h[i - 1]
            elif nozzle:
                hl = np.sqrt(par[P_A_NOZ])
            else:
                hl = h[i]
            hr = h[i + 1] if i < n - 1 else h[i]
            if h[i] <= hl and h[i] <= hr and h[i] < neck:
                neck = h[i]
                neck_z = (i + 0.5) * dz
    stats[0] = neck
    stats[1] = neck_z + z_off
    if last >= 0:
        stats[2] = _cross_right(h, last, hb, dz) + z_off
        stats[3] = u[last + 1]
    else:
        stats[2] = z_off
        stats[3] = 0.0
    stats[4] = n_bodies
    return n_ev
