"""Numba kernels of the Lagrangian slender-jet model (right-hand side, Jacobian, regrid).

The model is the one-dimensional, axisymmetric slender-jet approximation of Eggers &
Dupont (J. Fluid Mech. 262, 205, 1994) with the full curvature, written for a Lagrangian
mesh: nodes move with the fluid, each cell between two nodes keeps its volume. All
quantities are dimensionless: lengths in units of the nozzle radius ``R``, time in units
of the capillary time ``sqrt(rho R^3 / sigma)``, stresses in units of ``sigma / R``.

State of one node row ``k`` of the array ``y`` (shape ``(n, 4)``):

* ``y[k, 0]`` position ``z``, ``y[k, 1]`` axial velocity ``v``;
* ``y[k, 2]``, ``y[k, 3]`` the polymer conformation ``A_zz``, ``A_rr`` of the cell to
  the right of node ``k`` (unused on the last node of a body).

``w[k]`` is the reduced volume (volume / pi, i.e. the integral of ``a = h^2`` over the
cell) of the cell to the right of node ``k``; the cell's mean squared radius is
``a = w / dz``. Several bodies (the jet still attached to the nozzle, detached drops)
are stored one after another; ``starts`` holds the first node of each body and the
total count at the end.

Axial momentum per node (mass ``(w_left + w_right) / 2``) is driven by the difference of
the axial tension carried by the two neighbouring cells (force / pi)::

    S = T(a, a_z, a_zz) + a (3 Oh v_z + G f (A_zz - A_rr)),
    T = 4 a^2 (2 + a_zz) / (4 a + a_z^2)^(3/2),

where ``T`` is the capillary tension ``2 h / sqrt(1 + h_z^2) - h^2 kappa`` with the full
curvature ``kappa`` written in ``a = h^2`` (derivation in ``jet.py``; it is regular at a
drop tip, where ``a = 0``). The polymer is FENE-P in conformation form (Oldroyd-B when
``1/L^2 = 0``), upper-convected derivative in one dimension::

    dA_zz/dt = 2 v_z A_zz - (f A_zz - 1) / De,
    dA_rr/dt = -v_z A_rr - (f A_rr - 1) / De,
    f = (1 - 3/L^2) / (1 - tr A / L^2).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "BC_NOZZLE",
    "BC_TIP",
    "BC_WALL",
    "KL",
    "error_norm",
    "jacobian_banded",
    "neck_minimum",
    "rhs",
]

#: Left end pinned to the nozzle rim: fixed position, prescribed velocity, a = a_nozzle.
BC_NOZZLE = 0
#: Symmetry plane: fixed position, zero velocity, mirrored profile.
BC_WALL = 1
#: Free drop tip: a = 0, the node moves with the fluid.
BC_TIP = 2

#: Half band width of the Jacobian: a node couples to two nodes either side, 4 unknowns each.
KL = 11


@njit(cache=True)
def _fit(
    xl: float, ll: float, fl: float, lc: float, fc: float, xr: float, lr: float, fr: float
) -> tuple:
    """Parabola ``p0 + p1 x + p2 x^2 / 2`` (x from the centre cell's middle) with given means.

    The centre cell (length ``lc``) has mean ``fc``; the left and right items, centred at
    offsets ``xl < 0 < xr`` with lengths ``ll``, ``lr``, have means ``fl``, ``fr`` (a length
    of 0 makes an item a point value: a nozzle rim or a drop tip). Returns the point value
    ``p0`` at the centre, slope ``p1`` and second derivative ``p2``. Fitting cell *means*
    rather than treating them as point values makes a volume-conserving split of a cell
    reproduce the same parabola, so the forces do not jump when the grid is refined.
    """
    el = 0.5 * (xl * xl + (ll * ll - lc * lc) / 12.0)
    er = 0.5 * (xr * xr + (lr * lr - lc * lc) / 12.0)
    gl = fl - fc
    gr = fr - fc
    det = xl * er - xr * el
    p1 = (gl * er - gr * el) / det
    p2 = (xl * gr - xr * gl) / det
    p0 = fc - p2 * lc * lc / 24.0
    return p0, p1, p2


@njit(cache=True)
def _neighbours(
    y: np.ndarray, a: np.ndarray, j: int, k0: int, nc: int, bl: int, br: int, an: float
) -> tuple:
    """Left and right items (offset, length, mean) of cell ``j`` for :func:`_fit`."""
    k = k0 + j
    zl = y[k, 0]
    zr = y[k + 1, 0]
    c0 = 0.5 * (zl + zr)
    lc = zr - zl
    if j > 0:
        ll = zl - y[k - 1, 0]
        xl, fl = -0.5 * (lc + ll), a[j - 1]
    elif bl == BC_NOZZLE:
        ll, xl, fl = 0.0, zl - c0, an
    elif bl == BC_TIP:
        ll, xl, fl = 0.0, zl - c0, 0.0
    else:
        ll, xl, fl = lc, -lc, a[j]
    if j < nc - 1:
        lr = y[k + 2, 0] - zr
        xr, fr = 0.5 * (lc + lr), a[j + 1]
    elif br == BC_TIP:
        lr, xr, fr = 0.0, zr - c0, 0.0
    else:
        lr, xr, fr = lc, lc, a[j]
    return xl, ll, fl, lc, xr, lr, fr


@njit(cache=True)
def rhs(
    y: np.ndarray,
    w: np.ndarray,
    starts: np.ndarray,
    bcl: np.ndarray,
    bcr: np.ndarray,
    a_nozzle: float,
    oh: float,
    gp: float,
    inv_de: float,
    inv_l2: float,
    out: np.ndarray,
) -> bool:
    """Time derivative of the state; returns False if the mesh is tangled.

    Rows of fixed nodes (nozzle, wall) get zero; the caller imposes them algebraically.
    """
    out[:] = 0.0
    nb = starts.size - 1
    nmax = y.shape[0]
    a = np.empty(nmax)
    c = np.empty(nmax)
    vz = np.empty(nmax)
    s = np.empty(nmax)
    ok = True
    for b in range(nb):
        k0 = starts[b]
        k1 = starts[b + 1]
        nc = k1 - k0 - 1
        for j in range(nc):
            k = k0 + j
            dz = y[k + 1, 0] - y[k, 0]
            if dz <= 0.0 or w[k] <= 0.0:
                ok = False
                dz = 1e-300
            a[j] = w[k] / dz
            c[j] = 0.5 * (y[k + 1, 0] + y[k, 0])
            vz[j] = (y[k + 1, 1] - y[k, 1]) / dz
        for j in range(nc):
            k = k0 + j
            xl, ll, fl, lc, xr, lr, fr = _neighbours(y, a, j, k0, nc, bcl[b], bcr[b], a_nozzle)
            a0, a1, a2 = _fit(xl, ll, fl, lc, a[j], xr, lr, fr)
            a0 = max(a0, 0.0)
            q = 4.0 * a0 + a1 * a1
            tension = 4.0 * a0 * a0 * (2.0 + a2) / (q * np.sqrt(q)) if q > 0.0 else 0.0
            azz = y[k, 2]
            arr = y[k, 3]
            den = 1.0 - (azz + 2.0 * arr) * inv_l2
            if den <= 0.0:
                ok = False
                den = 1e-300
            f = (1.0 - 3.0 * inv_l2) / den
            s[j] = tension + a[j] * (3.0 * oh * vz[j] + gp * f * (azz - arr))
            if gp > 0.0:
                out[k, 2] = 2.0 * vz[j] * azz - (f * azz - 1.0) * inv_de
                out[k, 3] = -vz[j] * arr - (f * arr - 1.0) * inv_de
        for i in range(nc + 1):
            k = k0 + i
            sl = s[i - 1] if i > 0 else 0.0
            sr = s[i] if i < nc else 0.0
            m = 0.5 * ((w[k - 1] if i > 0 else 0.0) + (w[k] if i < nc else 0.0))
            out[k, 0] = y[k, 1]
            out[k, 1] = (sr - sl) / m
        # fixed end nodes carry no equation of motion
        if bcl[b] != BC_TIP:
            out[k0, 0] = 0.0
            out[k0, 1] = 0.0
        if bcr[b] != BC_TIP:
            out[k1 - 1, 0] = 0.0
            out[k1 - 1, 1] = 0.0
    return ok


@njit(cache=True)
def jacobian_banded(
    y: np.ndarray,
    w: np.ndarray,
    starts: np.ndarray,
    bcl: np.ndarray,
    bcr: np.ndarray,
    a_nozzle: float,
    oh: float,
    gp: float,
    inv_de: float,
    inv_l2: float,
    f0: np.ndarray,
    ab: np.ndarray,
) -> None:
    """Jacobian of :func:`rhs` by coloured finite differences, in LAPACK band storage.

    A node couples to at most two nodes either side, so perturbing every fifth node at
    once (one of the four unknowns at a time) gives 20 evaluations for the whole band.
    ``ab`` has shape ``(3 KL + 1, 4 n)``, the layout of ``dgbtrf`` with ``KL`` rows of
    fill on top; entry ``(i, j)`` of the matrix is ``ab[2 KL + i - j, j]``.
    """
    n_nodes = y.shape[0]
    ab[:, :] = 0.0
    yp = y.copy()
    fp = np.empty_like(y)
    scale = (1.0, 1.0, 1.0, 1.0)
    for mod in range(5):
        for var in range(4):
            for k in range(mod, n_nodes, 5):
                eps = 1e-7 * max(abs(y[k, var]), scale[var])
                yp[k, var] = y[k, var] + eps
            rhs(yp, w, starts, bcl, bcr, a_nozzle, oh, gp, inv_de, inv_l2, fp)
            for k in range(mod, n_nodes, 5):
                eps = yp[k, var] - y[k, var]
                col = 4 * k + var
                for kk in range(max(0, k - 2), min(n_nodes, k + 3)):
                    for vv in range(4):
                        row = 4 * kk + vv
                        ab[2 * KL + row - col, col] = (fp[kk, vv] - f0[kk, vv]) / eps
                yp[k, var] = y[k, var]


@njit(cache=True)
def error_norm(
    e: np.ndarray,
    y: np.ndarray,
    starts: np.ndarray,
    rtol: float,
    atol: float,
) -> float:
    """Largest scaled error: cell lengths relative, velocities and conformation mixed.

    The radius of a cell follows from its length, so node positions are judged by the
    relative error of each cell length rather than by absolute position.
    """
    worst = 0.0
    nb = starts.size - 1
    for b in range(nb):
        k0 = starts[b]
        k1 = starts[b + 1]
        for k in range(k0, k1):
            if k < k1 - 1:
                dz = y[k + 1, 0] - y[k, 0]
                r = abs(e[k + 1, 0] - e[k, 0]) / (rtol * dz)
                if r > worst:
                    worst = r
                for v in (2, 3):
                    r = abs(e[k, v]) / (atol + rtol * abs(y[k, v]))
                    if r > worst:
                        worst = r
            r = abs(e[k, 1]) / (atol + rtol * abs(y[k, 1]))
            if r > worst:
                worst = r
            r = abs(e[k, 0]) / (atol + rtol * abs(y[k, 0]))
            if r > worst:
                worst = r
    return worst


@njit(cache=True)
def neck_minimum(
    y: np.ndarray,
    w: np.ndarray,
    starts: np.ndarray,
    bcl: np.ndarray,
    bcr: np.ndarray,
    a_nozzle: float,
) -> tuple:
    """Thinnest neck: ``(a_min, cell index)`` over cells that are local minima of ``a``.

    A neck is a cell thinner than both neighbours (the nozzle rim counts as a neighbour
    of radius 1); cells touching a free tip are never necks. Returns ``(inf, -1)`` if
    there is none.
    """
    best = np.inf
    arg = -1
    nb = starts.size - 1
    for b in range(nb):
        k0 = starts[b]
        k1 = starts[b + 1]
        nc = k1 - k0 - 1
        for j in range(nc):
            k = k0 + j
            if (j == 0 and bcl[b] == BC_TIP) or (j == nc - 1 and bcr[b] == BC_TIP):
                continue
            aj = w[k] / (y[k + 1, 0] - y[k, 0])
            if j > 0:
                left = w[k - 1] / (y[k, 0] - y[k - 1, 0])
            elif bcl[b] == BC_NOZZLE:
                left = a_nozzle
            else:
                left = aj
            if j < nc - 1:
                right = w[k + 1] / (y[k + 2, 0] - y[k + 1, 0])
            else:
                right = aj
            if aj <= left and aj <= right and aj < best:
                best = aj
                arg = k
    return best, arg


@njit(cache=True)
def _shape(y: np.ndarray, a: np.ndarray, j: int, k0: int, nc: int, bl: int, br: int, an: float):
    """The parabola of :func:`_fit` for cell ``j``, as :func:`rhs` sees it."""
    xl, ll, fl, lc, xr, lr, fr = _neighbours(y, a, j, k0, nc, bl, br, an)
    return _fit(xl, ll, fl, lc, a[j], xr, lr, fr)


@njit(cache=True)
def _interp_v(y: np.ndarray, k: int, k0: int, k1: int, z: float) -> float:
    """Velocity at ``z`` inside cell ``k``: cubic through four nodes where there are four."""
    lo = max(k - 1, k0)
    hi = min(k + 2, k1 - 1)
    if hi - lo < 3:
        zl, zr = y[k, 0], y[k + 1, 0]
        return y[k, 1] + (z - zl) / (zr - zl) * (y[k + 1, 1] - y[k, 1])
    out = 0.0
    for i in range(lo, hi + 1):
        li = 1.0
        for m in range(lo, hi + 1):
            if m != i:
                li *= (z - y[m, 0]) / (y[i, 0] - y[m, 0])
        out += li * y[i, 1]
    return out


@njit(cache=True)
def _minmod_slope(y: np.ndarray, w: np.ndarray, k: int, k0: int, k1: int, col: int) -> float:
    """Minmod-limited slope of a cell quantity (conformation) across cell ``k``."""
    if k - 1 < k0 or k + 2 > k1 - 1:
        return 0.0
    cl = 0.5 * (y[k - 1, 0] + y[k, 0])
    c0 = 0.5 * (y[k, 0] + y[k + 1, 0])
    cr = 0.5 * (y[k + 1, 0] + y[k + 2, 0])
    sl = (y[k, col] - y[k - 1, col]) / (c0 - cl)
    sr = (y[k + 1, col] - y[k, col]) / (cr - c0)
    if sl * sr <= 0.0:
        return 0.0
    return sl if abs(sl) < abs(sr) else sr


@njit(cache=True)
def regrid(
    y: np.ndarray,
    w: np.ndarray,
    starts: np.ndarray,
    bcl: np.ndarray,
    bcr: np.ndarray,
    a_nozzle: float,
    resolution: float,
    dz_min: float,
    dz_max: float,
    out_y: np.ndarray,
    out_w: np.ndarray,
    out_starts: np.ndarray,
) -> int:
    """Split cells longer than the local target and merge pairs far shorter than it.

    The target cell length is ``resolution`` times the local radius (the thinnest of a
    cell and its neighbours), clipped to ``[dz_min, dz_max]``. Once any cell of a body
    is longer than 1.5 targets, every cell of that body longer than 0.9 targets is cut
    into equal pieces of at most 0.75 targets, whose volumes are the means of the
    parabola :func:`rhs` fits there (they add up to the cell's volume exactly) and whose
    conformation follows a limited linear profile with the same integral; two neighbours
    whose joint length is under half a target are merged (conformation averaged by
    volume). Bodies keep at least four cells. Returns the new node count; ``out_*`` must
    have room (``out_y`` at least 9 times the rows of ``y``).
    """
    nb = starts.size - 1
    n_out = 0
    a = np.empty(y.shape[0])
    tgt = np.empty(y.shape[0])
    for b in range(nb):
        k0 = starts[b]
        k1 = starts[b + 1]
        nc = k1 - k0 - 1
        bl = bcl[b]
        br = bcr[b]
        for j in range(nc):
            k = k0 + j
            a[j] = w[k] / (y[k + 1, 0] - y[k, 0])
        for j in range(nc):
            lo = a[j]
            if j > 0 and a[j - 1] < lo and not (j - 1 == 0 and bl == BC_TIP):
                lo = a[j - 1]
            if j < nc - 1 and a[j + 1] < lo and not (j + 1 == nc - 1 and br == BC_TIP):
                lo = a[j + 1]
            if (j == 0 and bl == BC_TIP and nc > 1) or (j == nc - 1 and br == BC_TIP and nc > 1):
                nbr = a[1] if j == 0 else a[nc - 2]
                lo = max(lo, nbr)
            tgt[j] = min(max(resolution * np.sqrt(lo), dz_min), dz_max)
        # refine the whole body at once when any cell is too long: one disturbance of
        # the time stepper per batch instead of one per cell
        split_at = np.inf
        for j in range(nc):
            if y[k0 + j + 1, 0] - y[k0 + j, 0] > 1.5 * tgt[j]:
                split_at = 0.9
                break
        out_starts[b] = n_out
        out_y[n_out, :] = y[k0, :]
        n_out += 1
        cells_left = nc
        j = 0
        while j < nc:
            k = k0 + j
            dz = y[k + 1, 0] - y[k, 0]
            if (
                j + 1 < nc
                and cells_left > 4
                and dz + (y[k + 2, 0] - y[k + 1, 0]) < 0.5 * min(tgt[j], tgt[j + 1])
            ):
                wt = w[k] + w[k + 1]
                out_w[n_out - 1] = wt
                out_y[n_out - 1, 2] = (w[k] * y[k, 2] + w[k + 1] * y[k + 1, 2]) / wt
                out_y[n_out - 1, 3] = (w[k] * y[k, 3] + w[k + 1] * y[k + 1, 3]) / wt
                out_y[n_out, :] = y[k + 2, :]
                n_out += 1
                cells_left -= 1
                j += 2
                continue
            if dz > split_at * tgt[j]:
                n_sub = min(8, int(np.ceil(dz / (0.75 * tgt[j]))))
                p0, s1, s2 = _shape(y, a, j, k0, nc, bl, br, a_nozzle)
                d = dz / n_sub
                # sub-cell means of the fitted parabola: they add up to w[k] exactly
                lowest = np.inf
                for i in range(n_sub):
                    off = (i + 0.5) * d - 0.5 * dz
                    val = p0 + s1 * off + 0.5 * s2 * (off * off + d * d / 12.0)
                    lowest = min(lowest, val)
                quad = lowest > 0.3 * a[j]
                if not quad:
                    lim = a[j] / dz
                    s1 = min(max(s1, -lim), lim)
                zl = y[k, 0]
                first = n_out - 1
                for i in range(n_sub):
                    off = (i + 0.5) * d - 0.5 * dz
                    if quad:
                        val = p0 + s1 * off + 0.5 * s2 * (off * off + d * d / 12.0)
                    else:
                        val = a[j] + s1 * off
                    out_w[n_out - 1] = d * val
                    if i < n_sub - 1:
                        zi = zl + (i + 1) * d
                        out_y[n_out, 0] = zi
                        out_y[n_out, 1] = _interp_v(y, k, k0, k1, zi)
                        n_out += 1
                # the last piece takes the rounding remainder so the volume is exact
                acc = 0.0
                for i in range(n_sub - 1):
                    acc += out_w[first + i]
                out_w[n_out - 1] = w[k] - acc
                # conformation: limited linear profile, shifted to keep its volume integral
                for col in (2, 3):
                    sl = _minmod_slope(y, w, k, k0, k1, col)
                    tot = 0.0
                    for i in range(n_sub):
                        off = (i + 0.5) * d - 0.5 * dz
                        tot += out_w[first + i] * sl * off
                    shift = tot / w[k]
                    for i in range(n_sub):
                        off = (i + 0.5) * d - 0.5 * dz
                        out_y[first + i, col] = y[k, col] + sl * off - shift
                out_y[n_out, :] = y[k + 1, :]
                n_out += 1
                j += 1
                continue
            out_w[n_out - 1] = w[k]
            out_y[n_out - 1, 2] = y[k, 2]
            out_y[n_out - 1, 3] = y[k, 3]
            out_y[n_out, :] = y[k + 1, :]
            n_out += 1
            j += 1
        out_w[n_out - 1] = 0.0
    out_starts[nb] = n_out
    return n_out
