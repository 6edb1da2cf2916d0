"""Eulerian slender-jet solver on a fixed grid, regularised by a thin film.

Model
-----
The same one-dimensional axisymmetric slender-jet model as :mod:`.jet` (Eggers & Dupont,
J. Fluid Mech. 262, 205, 1994, with the full curvature, a Newtonian solvent and a FENE-P
or Oldroyd-B polymer; parameters from :class:`.jet.JetModel`), in dimensionless form
(length: nozzle radius ``R``; time: capillary time ``t_c = sqrt(rho R^3 / sigma)``;
stress: ``sigma / R``), written for a fixed grid in the variables ``a = h^2``, ``u``,
``A_zz``, ``A_rr``::

    da/dt + d(a u)/dz = 0
    du/dt + u du/dz = (1 / a) dS/dz
    S = 4 a^2 (2 + a_zz) / (4 a + a_z^2)^(3/2) + a (3 Oh u_z + G f (A_zz - A_rr))
    dA/dt + u dA/dz = upper-convected stretching - (f A - 1) / De

with ``G = Oh_p / De`` and ``f = (1 - 3/L^2) / (1 - tr A / L^2)``. The capillary part of
``S`` is ``2 h / sqrt(1 + h_z^2) - h^2 kappa`` with the full curvature, regular where
``a`` vanishes (derivation in :mod:`.jet`).

Discretisation
--------------
In the manner of Driessen & Jeurissen, "A regularised one-dimensional drop formation and
coalescence model using a total variation diminishing (TVD) scheme on a single Eulerian
grid", Int. J. Comput. Fluid Dyn. 25, 333-343 (2011): one uniform grid from the nozzle
exit, staggered (``a`` and the conformation at cell centres, ``u`` at the faces). The
mass equation is conservative with a flux-limited (van Leer by default, or minmod)
Lax-Wendroff/upwind TVD flux (Sweby 1984), so the squared radius stays positive and
monotone where it should and mass is conserved to round-off; the momentum advection is
written in the conservative staggered form of Stelling & Duinmeijer (Int. J. Numer.
Meth. Fluids 43, 1329, 2003: cell-centred mass fluxes carry limited upwind face
velocities), so a recoiling rim that sweeps up a thread conserves momentum and moves at
the Taylor-Culick speed rather than at a Burgers shock speed; the momentum that liquid
brings to a face is divided by the face's mass after its arrival where that is larger
(the conservative update), so a front running into the film moves the film's faces at
the front's speed instead of (arrived mass / film mass) times it; the polymer
content ``a A`` is carried by the mass flux times a limited face value of ``A``, so a
uniform conformation stays uniform. Time stepping is first order, forward-backward:
the face velocities are advanced with the capillary and polymer tension of the old
profile and an implicit solvent viscosity (one tridiagonal solve per step), then the
profile and the conformation with the new velocities; stretching is integrated exactly
over the step and the FENE-P relaxation implicitly (a quadratic in ``tr A``). The step
is limited by advection, capillary waves (``dt <= min(2 cfl, 0.9) dz^2 / sqrt(2
h_max)``) and polymer waves (:func:`.jet_euler_kernels.time_step_limit`); a step that
would make ``a`` negative is retried at half the size (counted in ``JetRun.rejected``).

Regularisation
--------------
Where there is no liquid the grid holds a film of area ``a_film = film^2`` (default
``film = 1e-3``, a twentieth of the usual breakup radius 0.02): the initial state
outside the nozzle is this film, and the coefficients of the momentum equation (the
``1 / a`` in front of ``dS/dz``, the area in the capillary tension and in the viscous
stress) use ``max(a, a_film)``, so the equations stay defined wherever the liquid has
gone. The capillary tension is switched off smoothly in the film (weight 0 at
``a <= a_film``, 1 from ``a >= 4 a_film``, a smoothstep between): otherwise the film,
a thread of radius ``film``, would retract at its Taylor-Culick speed ``sqrt(2 / film)``
from every place where it ends (the nozzle rim, each drop) and drain itself. Mass is
never added or removed: ``a`` follows the conservative update and may thin below the
film (it stays >= 0). The film holds no polymer (the conformation is reset to 1 where
``a < a_film``) and has a negligible volume (``30 film^2`` over the default domain). A
jet, its pinch-off, the recoil of the broken ends and the coalescence of drops are all
one field on one grid, with no change of topology.

Breakup bookkeeping
-------------------
A cell holds liquid (is *wet*) while ``h > h_break``; a cell that has dried is wet again
only above ``rewet_factor * h_break``. Runs of at least two wet cells are bodies (a run
touching a nozzle boundary is attached to the nozzle). A breakup is a body that splits
into two bodies (or into the nozzle and a body) across cells that dried during the step;
its time is interpolated linearly in ``h`` between the two steps. Details in
:func:`.jet_euler_breakup.analyse`.

The settings, the initial states and the state on the grid are in :mod:`.jet_euler_grid`,
re-exported here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from microfab.core.arrays import readonly
from microfab.process.inkjet import jet_euler_kernels as ek
from microfab.process.inkjet import jet_euler_meniscus as em
from microfab.process.inkjet.breakup import classify_pinch
from microfab.process.inkjet.jet import Body, Inflow, JetModel, JetRun, PinchEvent
from microfab.process.inkjet.jet_euler_grid import (
    _LEFT,
    _LIMITERS,
    _RIGHT,
    EulerInitial,
    EulerNumerics,
    _Field,
    euler_thread,
)
from microfab.process.inkjet.jet_euler_grid import LeftEnd as LeftEnd
from microfab.process.inkjet.jet_euler_grid import RightEnd as RightEnd
from microfab.process.inkjet.jet_euler_upstream import Upstream, UpstreamArrays

__all__ = [
    "MENISCUS_KINDS",
    "EulerInitial",
    "EulerNumerics",
    "MeniscusKind",
    "Upstream",
    "euler_thread",
    "run_jet_euler",
]

#: How the meniscus behaves (:mod:`.jet_euler_meniscus`): held at the rim, suction
#: draining the grid's first cell ("pinned"), or free to retract into the bore with the
#: liquid column and come back ("retracting").
MeniscusKind = Literal["pinned", "retracting"]
MENISCUS_KINDS: tuple[MeniscusKind, ...] = ("pinned", "retracting")
_MENISCUS = {"pinned": ek.MENISCUS_PINNED, "retracting": ek.MENISCUS_RETRACTING}


def run_jet_euler(
    model: JetModel,
    numerics: EulerNumerics | None = None,
    *,
    t_end: float,
    t0: float = 0.0,
    inflow: Inflow | None = None,
    initial: EulerInitial | None = None,
    a_nozzle: float = 1.0,
    snapshot_times: Sequence[float] = (),
    after_first_pinch: float = math.inf,
    on_pinch: Literal["stop", "split"] = "split",
    progress: Callable[[float], None] | None = None,
    meniscus: MeniscusKind = "pinned",
    upstream: Upstream | None = None,
    meniscus_z0: float = 0.0,
    bore_length: float = math.inf,
    depin_area: float = em.DEPIN_AREA,
    back_pressure: float = 0.0,
) -> JetRun:
    """Integrate the Eulerian slender-jet model from ``t0`` to ``t_end`` (dimensionless).

    Parameters
    ----------
    model : JetModel
        Fluid parameters (the same as for :func:`.jet.run_jet`).
    numerics : EulerNumerics, optional
        Grid, step and breakup settings.
    t_end : float
        End time.
    t0 : float, optional
        Start time (the inflow is read from ``t0`` on).
    inflow : Inflow, optional
        Nozzle exit velocity (positive out of the nozzle; negative values suck liquid
        back through the exit). Needs a nozzle at the left end.
    initial : EulerInitial, optional
        Initial state, which also fixes the grid and the ends. Default: a flat meniscus at
        the nozzle exit and the film everywhere on ``[0, numerics.length]``, cells of
        ``numerics.dz``, open far end.
    a_nozzle : float, optional
        Squared rim radius (1 with the nozzle radius as the length unit).
    snapshot_times : sequence of float
        Times at which the bodies are stored (steps land on them exactly).
    after_first_pinch : float, optional
        With ``on_pinch="split"``, stop this long after the first breakup.
    on_pinch : {"stop", "split"}
        Stop at the first breakup, or go on (the grid needs no split) and record later
        breakups too.
    progress : callable, optional
        Called with the current time whenever the kernels hand back control (at
        snapshots, breakups and every few thousand steps).
    meniscus : {"pinned", "retracting"}, optional
        Held at the rim (suction drains the grid's first cell), or free to retract into
        the bore with the liquid column, pulling the jet's root with it
        (:mod:`.jet_euler_meniscus`). Needs a nozzle at the left end.
    upstream : Upstream, optional
        A linear model that produces the nozzle flow from the meniscus pressure (two-way
        coupling), instead of a given ``inflow``.
    meniscus_z0 : float, optional
        Initial mean meniscus position: 0 flat at the rim; with ``meniscus="retracting"``
        also < 0 (a concave cap in the bore) or > 0 (a convex cap on the rim, below the
        hemisphere's 2/3; handed to the grid at the first step if taller than
        ``numerics.cap_cells``). `jet_euler_meniscus.static_meniscus` gives the position
        at rest under ``back_pressure``.
    bore_length : float, optional
        Depth of the straight bore behind the exit; the run stops if the meniscus
        retracts deeper (default: no limit).
    depin_area : float, optional
        Squared radius of the liquid at the rim (over the bore's) below which suction
        lets the meniscus go into the bore instead of draining the bulge through the rim
        (default `jet_euler_meniscus.DEPIN_AREA`, an assumption), in ``(0, 1]``.
    back_pressure : float, optional
        Static pressure on the liquid in the bore over ambient (the reservoir's back
        pressure), ``sigma / R``, in ``(-2, 2)`` (default 0): added to what the upstream
        model feels (it pushes the column out against the meniscus). Needs ``upstream``
        and ``meniscus="retracting"``; start the meniscus where it balances it
        (``meniscus_z0``).

    Returns
    -------
    JetRun
        The same record as :func:`.jet.run_jet`, with these meanings: ``neck_radius``
        the thinnest local minimum of ``h`` inside a body (not at a free end), ``tip_z``
        where ``h`` falls through ``h_break`` at the right end of the leading body,
        ``tip_v`` the velocity of the face behind it, ``volume`` the integral of ``a``
        over the whole grid (film included) plus what left through the far end,
        ``injected`` the volume that crossed the nozzle exit (the numerical flux: exactly
        ``a_nozzle`` times the inflow displacement while the exit pushes out; while it
        sucks, the liquid in the first cell goes back), so ``volume - volume[0] -
        injected`` is conserved to round-off. Bodies are the wet runs of at least two
        cells converted to :class:`.jet.Body` (nodes at the cell faces, ``w = a dz``);
        the left end of a run at the nozzle is "nozzle" (at a wall "wall"), other ends
        are "tip" (at a right wall "wall"). With a retracting meniscus all positions are
        in the lab frame (the grid's left end is the meniscus, ``meniscus_z``), and a
        body on the nozzle starts there.

    Raises
    ------
    ValueError
        For an end time not after the start, an inflow without a nozzle, an unknown
        ``on_pinch`` or a negative ``after_first_pinch``.
    """
    nu = numerics or EulerNumerics()
    if not t_end > t0:
        raise ValueError(f"t_end {t_end} must be after t0 {t0}")
    if on_pinch not in ("stop", "split"):
        raise ValueError(f"on_pinch must be 'stop' or 'split', got {on_pinch!r}")
    if not after_first_pinch >= 0.0:
        raise ValueError(f"after_first_pinch must be >= 0, got {after_first_pinch}")
    if not a_nozzle > 0.0:
        raise ValueError(f"a_nozzle must be > 0, got {a_nozzle}")
    if meniscus not in _MENISCUS:
        raise ValueError(f"meniscus must be one of {list(MENISCUS_KINDS)}, got {meniscus!r}")
    if not (math.isfinite(meniscus_z0) and meniscus_z0 < em.HEMISPHERE_DEPTH):
        raise ValueError(
            f"meniscus_z0 must be below the hemisphere's {em.HEMISPHERE_DEPTH:.4g}, got "
            f"{meniscus_z0}"
        )
    if meniscus_z0 != 0.0 and meniscus != "retracting":
        raise ValueError("a meniscus off the rim (meniscus_z0 != 0) needs meniscus='retracting'")
    if not (math.isfinite(back_pressure) and abs(back_pressure) < 2.0):
        raise ValueError(
            f"back_pressure must lie in (-2, 2) (the bore's Laplace pressure), got {back_pressure}"
        )
    if back_pressure != 0.0 and (upstream is None or meniscus != "retracting"):
        raise ValueError("a back pressure needs an upstream model and meniscus='retracting'")
    if not bore_length > 0.0:
        raise ValueError(f"bore_length must be > 0, got {bore_length}")
    if not 0.0 < depin_area <= 1.0:
        raise ValueError(f"depin_area must lie in (0, 1], got {depin_area}")
    if upstream is not None and inflow is not None:
        raise ValueError("give either an inflow or an upstream model, not both")
    if initial is None:
        n = nu.cells_for(nu.length)
        initial = EulerInitial(
            length=n * nu.dz,
            a=np.full(n, nu.film**2),
            left="nozzle",
            right="outflow",
        )
    if (inflow is not None or upstream is not None) and initial.left != "nozzle":
        raise ValueError("an inflow needs a nozzle at the left end (initial.left='nozzle')")
    if meniscus == "retracting" and initial.left != "nozzle":
        raise ValueError("a retracting meniscus needs a nozzle at the left end")
    dz = initial.dz
    par = np.zeros(ek.N_PAR)
    par[ek.P_DZ] = dz
    par[ek.P_OH] = model.ohnesorge
    par[ek.P_GP] = model.polymer_modulus
    par[ek.P_INV_DE] = 1.0 / model.deborah if model.deborah > 0 else 0.0
    par[ek.P_INV_L2] = 0.0 if math.isinf(model.extensibility_l2) else 1.0 / model.extensibility_l2
    par[ek.P_A_FILM] = nu.film**2
    par[ek.P_A_NOZ] = a_nozzle if initial.left == "nozzle" else 0.0
    par[ek.P_CFL] = nu.cfl
    par[ek.P_H_BREAK] = nu.h_break
    par[ek.P_REWET] = nu.rewet_factor
    par[ek.P_DT_MAX] = nu.dt_max
    par[ek.P_BORE] = bore_length
    par[ek.P_DEPIN] = depin_area
    par[ek.P_BACK] = back_pressure
    cap = nu.cap_cells * dz  # centre height of the bulge the grid takes over
    par[ek.P_CAP] = cap * (3.0 + cap * cap) / 6.0 if meniscus == "retracting" else math.inf
    ipar = np.array(
        [
            _LEFT[initial.left],
            _RIGHT[initial.right],
            _LIMITERS[nu.limiter],
            _MENISCUS[meniscus],
            int(upstream is not None),
        ],
        dtype=np.int64,
    )
    if upstream is None:
        d_tab, tab_dt = _inflow_table(inflow, t0, t_end, nu.inflow_dt)
        up = UpstreamArrays.idle()
    else:
        tab_dt = upstream.dt
        size = math.ceil((t_end - t0) / tab_dt) + 3
        d_tab = np.zeros(size)
        up = UpstreamArrays.of(upstream, size)

    a = np.array(initial.a, float)
    u = np.array(initial.u, float)
    azz = np.array(initial.a_zz, float)
    arr = np.array(initial.a_rr, float)
    wet = np.sqrt(a) > nu.h_break
    field = _Field(a, u, azz, arr, wet, dz, initial.left, initial.right)
    snaps_t = sorted(float(s) for s in snapshot_times if t0 <= s <= t_end)
    snapshots: list[tuple[float, tuple[Body, ...]]] = []
    events: list[PinchEvent] = []
    counters = np.zeros(3, dtype=np.int64)
    acc = np.array([0.0, 0.0, meniscus_z0, 0.0])
    ev = np.zeros((32, ek.EV_COLS))
    hist = np.empty((ek.HIST_ROWS, 4096))
    stats = np.empty(5)
    ek.analyse(a, a, u, wet, wet, par, ipar, t0, t0, stats, ev, meniscus_z0)
    hist[:, 0] = (
        t0, stats[0], stats[1], stats[2], stats[3], a.sum() * dz, 0.0, stats[4], meniscus_z0,
    )  # fmt: skip
    field.z_off = meniscus_z0
    n_hist = 1
    t = t0
    stop_at = t_end
    stop_reason = "end time reached"
    _take_snapshots(snaps_t, t, field, snapshots)
    chunk = 5000
    while True:
        target = min(stop_at, snaps_t[0]) if snaps_t else stop_at
        limit = min(nu.max_steps, int(counters[0]) + chunk)
        t, n_hist, status, n_ev = em.advance(
            a, u, azz, arr, wet, t, target, par, ipar, d_tab, t0, tab_dt,
            hist, n_hist, limit, counters, acc, ev,
            up.u_tab, up.x, up.phi, up.g_drive, up.g_pressure, up.c_row, up.slopes,
        )  # fmt: skip
        field.z_off = float(acc[2])
        if progress is not None:
            progress(t)
        if status == 2:
            hist = np.concatenate((hist, np.empty_like(hist)), axis=1)
            continue
        if status == 3:
            if counters[0] >= nu.max_steps:
                stop_reason = "step limit"
                break
            continue
        if status == 4:
            stop_reason = f"time step collapsed at t = {t:.6g}"
            break
        if status == 5:
            stop_reason = f"liquid reached the end of the domain at t = {t:.6g}"
            break
        if status == 6:
            stop_reason = (
                f"the meniscus retracted deeper than the bore ({bore_length:g} radii) at "
                f"t = {t:.6g}"
            )
            break
        if status == 1:
            for row in ev[:n_ev]:
                events.append(_event(row))
            if on_pinch == "stop":
                stop_reason = "pinch-off"
                _take_snapshots(snaps_t, t, field, snapshots)
                break
            stop_at = min(t_end, events[0].t + after_first_pinch)
        _take_snapshots(snaps_t, t, field, snapshots)
        if t >= stop_at - 1e-12 * max(1.0, abs(stop_at)):
            if stop_at < t_end:
                stop_reason = "followed long enough after the first breakup"
            break
    h = hist[:, :n_hist]
    return JetRun(
        t=readonly(h[0]),
        neck_radius=readonly(h[1]),
        neck_z=readonly(h[2]),
        tip_z=readonly(h[3]),
        tip_v=readonly(h[4]),
        volume=readonly(h[5]),
        injected=readonly(h[6]),
        n_bodies=readonly(h[7], int),
        events=tuple(events),
        snapshots=tuple(snapshots),
        bodies=field.bodies(),
        steps=int(counters[0]),
        rejected=int(counters[1]),
        stop_reason=stop_reason,
        meniscus_z=readonly(h[8]) if meniscus == "retracting" else None,
        upstream_velocity=None if upstream is None else readonly(up.u_tab[: counters[2] + 1]),
        upstream_dt=0.0 if upstream is None else upstream.dt,
    )


def _inflow_table(
    inflow: Inflow | None, t0: float, t_end: float, spacing: float
) -> tuple[np.ndarray, float]:
    """Inflow displacement on a uniform table from ``t0`` to ``t_end`` (kernels interpolate)."""
    if inflow is None:
        return np.zeros(2), t_end - t0
    m = max(2, math.ceil((t_end - t0) / spacing))
    dt = (t_end - t0) / m
    d0 = inflow.displacement(t0)
    tab = np.array([inflow.displacement(min(t0 + k * dt, t_end)) - d0 for k in range(m + 1)])
    return tab, dt


def _event(row: np.ndarray) -> PinchEvent:
    t, z, z_tip, z_tail, attached = (float(x) for x in row[:5])
    return PinchEvent(t, z, z_tip, z_tail, bool(attached), classify_pinch(z, z_tip, z_tail))


def _take_snapshots(
    snaps_t: list[float],
    t: float,
    field: _Field,
    out: list[tuple[float, tuple[Body, ...]]],
) -> None:
    while snaps_t and snaps_t[0] <= t + 1e-12 * max(1.0, abs(t)):
        out.append((snaps_t.pop(0), field.bodies()))
