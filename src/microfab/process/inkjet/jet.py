"""One-dimensional slender-jet solver: thinning, pinch-off and what happens after.

Model
-----
Axisymmetric slender-jet equations (Eggers & Dupont, J. Fluid Mech. 262, 205, 1994) with
the full curvature, a Newtonian solvent and a FENE-P / Oldroyd-B polymer, in
dimensionless form (length: nozzle radius ``R``; time: capillary time
``t_c = sqrt(rho R^3 / sigma)``; stress: ``sigma / R``)::

    d(h^2)/dt + d(h^2 v)/dz = 0
    h^2 (dv/dt + v dv/dz) = dS/dz
    S = 2 h / sqrt(1 + h_z^2) - h^2 kappa + h^2 (3 Oh v_z + tau_zz - tau_rr)

where ``kappa = 1 / (h sqrt(1 + h_z^2)) - h_zz / (1 + h_z^2)^(3/2)`` is the full mean
curvature. ``S`` is the axial force over pi carried by a cross-section: differentiating
it gives back ``-h^2 dkappa/dz`` for the capillary part (the identity
``d(2h / sqrt(1 + h_z^2))/dz = (h^2)_z kappa``), so the conservative form is the same
model as Eggers & Dupont's. In ``a = h^2`` the capillary part of ``S`` becomes
``4 a^2 (2 + a_zz) / (4 a + a_z^2)^(3/2)``, which is smooth where a drop tip has
``a = 0``; a sphere of radius ``r`` gives ``kappa = 2 / r`` exactly.

Discretisation
--------------
Lagrangian: nodes move with the fluid and every cell keeps its volume, so mass is
conserved by construction and the polymer conformation needs no advection. The cell
between the nozzle rim (fixed node, prescribed velocity) and the first moving node gains
exactly the volume the printhead pushes out. Cells are split where they grow longer than
``resolution`` times the local radius and merged where they crowd, which refines the
grid automatically in a thinning neck.

Time stepping is implicit and handed to an integrator object
(:class:`microfab.sim.integrators.SDIRK2` by default: two-stage, L-stable, stiffly
accurate, Alexander 1977, gamma = 1 - 1/sqrt 2, with an embedded first-order error
estimate filtered through the Newton matrix, Hairer & Wanner, Solving ODEs II, IV.8). This
module supplies what is specific to the jet (`microfab.sim.integrators.ImplicitProblem`):
the right-hand side and the banded Jacobian from :mod:`.jet_kernels`, the Newton matrix
factored by LAPACK ``gbtrf``/``gbtrs``, the boundary values held as algebraic constraints
and the error norm that judges cell lengths relatively.

A neck "breaks" when its radius drops below ``h_break``; the crossing time is
interpolated between steps. The jet may then be split into bodies with free tips that
are followed further (retraction, further breakups, coalescence), which gives the
satellite count.

The data classes (parameters, bodies, results) are in :mod:`.jet_bodies` and the
per-step problem handed to the integrator in :mod:`.jet_problem`; both are re-exported
here.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np

from microfab.core.arrays import readonly
from microfab.core.threads import single_threaded
from microfab.process.inkjet import jet_kernels as jk
from microfab.process.inkjet.breakup import classify_pinch
from microfab.process.inkjet.jet_bodies import _BC as _BC
from microfab.process.inkjet.jet_bodies import _BC_NAME as _BC_NAME
from microfab.process.inkjet.jet_bodies import (
    Body,
    Inflow,
    JetModel,
    JetRun,
    Numerics,
    PinchEvent,
    _State,
    cap_body,
    cap_volume,
    thread_body,
)
from microfab.process.inkjet.jet_bodies import BoundaryKind as BoundaryKind
from microfab.process.inkjet.jet_problem import _algebraic as _algebraic
from microfab.process.inkjet.jet_problem import _inner_cells as _inner_cells
from microfab.process.inkjet.jet_problem import _JetStep as _JetStep
from microfab.process.inkjet.jet_problem import _JetSystem
from microfab.process.inkjet.jet_problem import _w_at as _w_at
from microfab.sim.integrators import SDIRK2, ImplicitIntegrator

__all__ = [
    "Body",
    "Inflow",
    "JetModel",
    "JetRun",
    "Numerics",
    "PinchEvent",
    "cap_body",
    "run_jet",
    "thread_body",
]


@single_threaded
def run_jet(
    bodies: Sequence[Body],
    model: JetModel,
    numerics: Numerics | None = None,
    *,
    t0: float = 0.0,
    t_end: float,
    inflow: Inflow | None = None,
    a_nozzle: float = 1.0,
    on_pinch: Literal["stop", "split"] = "stop",
    snapshot_times: Sequence[float] = (),
    start_cap_height: float = 0.3,
    after_first_pinch: float = math.inf,
    progress: Callable[[float], None] | None = None,
    h0: float = 1e-4,
    integrator: ImplicitIntegrator | None = None,
    land_on_snapshots: bool = True,
) -> JetRun:
    """Integrate the slender-jet equations from ``t0`` to ``t_end`` (dimensionless).

    Parameters
    ----------
    bodies : sequence of Body
        Initial bodies, ordered along z. May be empty when ``inflow`` is given: the
        meniscus is then inside the nozzle and a jet body is started as a spherical cap
        once the pushed-out volume exceeds a cap of ``start_cap_height``.
    model : JetModel
        Fluid parameters.
    numerics : Numerics, optional
        Grid and tolerance settings.
    t0, t_end : float
        Time span.
    inflow : Inflow, optional
        Nozzle exit velocity for a body whose left end is "nozzle".
    a_nozzle : float, optional
        Squared rim radius (1 with the nozzle radius as the length unit).
    on_pinch : {"stop", "split"}
        Stop at the first breakup, or split the body there and go on to ``t_end``.
    snapshot_times : sequence of float
        Times at which the bodies are stored (see ``land_on_snapshots``).
    start_cap_height : float, optional
        Height of the cap that starts a jet from the dormant meniscus.
    after_first_pinch : float, optional
        With ``on_pinch="split"``, stop this long after the first breakup (default: go
        on to ``t_end``).
    progress : callable, optional
        Called with the current time after each step.
    h0 : float, optional
        First time step.
    integrator : ImplicitIntegrator, optional
        Time-stepping scheme and step-size control (default:
        :class:`microfab.sim.integrators.SDIRK2` with its default settings). It is handed
        the jet on the current grid for each step; regridding, inflow, breakup and
        coalescence happen between steps.
    land_on_snapshots : bool, optional
        True (default): steps are cut to land on each snapshot time exactly. False: the
        step sequence ignores the snapshots, and each stores the bodies of the first step
        that reaches its time (labelled with the requested time, at most one step late).
        The step sequence of a run near a breakup threshold decides its outcome, so
        landing makes the answer depend on how often pictures are taken (1 % NaAlg at
        50 V broke at 112, 99 µs or not at all with 10, 5 or 2 µs frames); drop-on-demand
        runs (:mod:`.droplet`) therefore follow.

    Returns
    -------
    JetRun

    Notes
    -----
    A collapsing step size, a grid outgrowing ``numerics.max_nodes`` or too many steps end
    the run early; what was computed up to then is returned, with the reason in
    ``stop_reason``.
    """
    nu = numerics or Numerics()
    solver = integrator if integrator is not None else SDIRK2()
    system = _JetSystem(model, nu, a_nozzle)
    st = _State.from_bodies(bodies)
    snaps_t = sorted(float(s) for s in snapshot_times if t0 <= s <= t_end)
    snapshots: list[tuple[float, tuple[Body, ...]]] = []
    events: list[PinchEvent] = []
    hist: dict[str, list[float]] = {
        k: [] for k in ("t", "neck", "neck_z", "tip_z", "tip_v", "vol", "inj", "nb")
    }
    u0 = inflow.displacement(t0) if inflow is not None else 0.0
    vol0 = float(st.w.sum())
    dormant = vol0 <= 0.0 and inflow is not None
    u_ref = u0
    w0_ref = float(st.w[0]) if st.w.size else 0.0
    removed = 0.0
    injected = 0.0
    t = t0
    h = h0
    steps = rejected = 0
    prev_neck = math.inf
    stop_reason = "end time reached"
    regridded = False

    def record() -> tuple[float, int]:
        a_min, k = jk.neck_minimum(st.y, st.w, st.starts, st.bcl, st.bcr, a_nozzle)
        r = math.sqrt(a_min) if math.isfinite(a_min) else math.inf
        hist["t"].append(t)
        hist["neck"].append(r)
        hist["neck_z"].append(0.5 * (st.y[k, 0] + st.y[k + 1, 0]) if k >= 0 else math.nan)
        if st.y.shape[0]:
            lead = st.starts[-1] - 1
            hist["tip_z"].append(float(st.y[lead, 0]))
            hist["tip_v"].append(float(st.y[lead, 1]))
        else:
            hist["tip_z"].append(0.0)
            hist["tip_v"].append(0.0)
        hist["vol"].append(float(st.w.sum()) + removed + (dormant_volume() if dormant else 0.0))
        hist["inj"].append(injected + (dormant_volume() - dormant_base if dormant else 0.0))
        hist["nb"].append(st.starts.size - 1)
        return r, k

    def dormant_volume() -> float:
        assert inflow is not None
        return dormant_base + a_nozzle * (inflow.displacement(t) - dormant_u)

    dormant_base = 0.0
    dormant_u = u0
    record()
    while t < t_end - 1e-12 * max(1.0, abs(t_end)):
        if steps + rejected > nu.max_steps:
            stop_reason = "step limit"
            break
        if dormant and st.y.shape[0] == 0:
            assert inflow is not None
            # only a meniscus inside or at the nozzle: wait on a coarse clock
            dt = min(0.01, t_end - t)
            if land_on_snapshots and snaps_t and snaps_t[0] < t + dt:
                dt = max(snaps_t[0] - t, 0.0)
            t += dt
        else:
            h = min(h, t_end - t)
            if land_on_snapshots and snaps_t and snaps_t[0] > t:
                h = min(h, snaps_t[0] - t)
            piston = bool(
                inflow is not None
                and st.bcl.size
                and st.bcl[0] == jk.BC_NOZZLE
                and (st.y[0, 0] < 0.0 or inflow.velocity(t) < 0.0)
            )
            result = solver.step(system.at_step(st, t, inflow, w0_ref, u_ref, piston), t, st.y, h)
            y_new, err = result.y, result.error
            if y_new is not None and regridded:
                # A regrid excites fast viscous transients that the L-stable stages
                # damp but that the error estimate cannot tell from truncation error;
                # the first step on a new grid keeps the step size already controlled.
                err = min(err, 1.0)
            if y_new is None or not solver.accepts(err):  # a NaN error fails too
                rejected += 1
                h = solver.step_after_rejection(h, None if y_new is None else err)
                if h < solver.min_step:
                    stop_reason = f"time step collapsed at t = {t:.6g}"
                    break
                continue
            steps += 1
            t += h
            st.y = y_new
            if inflow is not None and st.bcl.size and st.bcl[0] == jk.BC_NOZZLE:
                if not piston:
                    st.w[0] = w0_ref + a_nozzle * (inflow.displacement(t) - u_ref)
                    injected += a_nozzle * (inflow.displacement(t) - u_ref)
                elif st.y[0, 0] > 0.0:
                    # the meniscus came back out past the exit: the overshoot is inflow
                    st.w[0] += a_nozzle * st.y[0, 0]
                    injected += a_nozzle * st.y[0, 0]
                    st.y[0, 0] = 0.0
            h = solver.step_after_acceptance(h, err)
        if dormant and inflow is not None:
            vol = dormant_volume()
            if vol >= cap_volume(start_cap_height, a_nozzle):
                cap = cap_body(vol, velocity=inflow.velocity(t), a_nozzle=a_nozzle)
                injected += vol - dormant_base
                st = _State.from_bodies([cap, *st.bodies()])
                dormant = False
                h = h0
        neck, k = record()
        if neck < nu.h_break and k >= 0:
            ev = _pinch_event(st, k, t, neck, prev_neck, nu.h_break, hist)
            events.append(ev)
            if on_pinch == "stop":
                stop_reason = "pinch-off"
                _take_snapshots(snaps_t, t, st, snapshots)
                break
            st, remnant, lost = _split(st, k, nu.cut_radius_factor * nu.h_break)
            removed += lost
            if remnant > 0.0:
                dormant, dormant_base = True, remnant
                dormant_u = inflow.displacement(t) if inflow is not None else 0.0
            prev_neck = math.inf
        else:
            prev_neck = neck
        before = st
        st, gone = _tidy(st, nu, a_nozzle, inflow is not None, start_cap_height)
        regridded = st is not before
        if gone is not None:
            # the jet attached to the nozzle has withdrawn: back to a dormant meniscus
            dormant, dormant_base = True, gone
            dormant_u = inflow.displacement(t) if inflow is not None else 0.0
        if st.y.shape[0] > nu.max_nodes:
            stop_reason = f"grid limit ({nu.max_nodes} nodes) reached"
            break
        if inflow is not None:
            u_ref = inflow.displacement(t)
        w0_ref = float(st.w[0]) if st.w.size else 0.0
        _take_snapshots(snaps_t, t, st, snapshots)
        if progress is not None:
            progress(t)
        if st.y.shape[0] == 0 and inflow is None:
            stop_reason = "no liquid left"
            break
        if events and t >= events[0].t + after_first_pinch:
            stop_reason = "followed long enough after the first breakup"
            break
    arr = {k: np.asarray(v, float) for k, v in hist.items()}
    return JetRun(
        t=readonly(arr["t"]),
        neck_radius=readonly(arr["neck"]),
        neck_z=readonly(arr["neck_z"]),
        tip_z=readonly(arr["tip_z"]),
        tip_v=readonly(arr["tip_v"]),
        volume=readonly(arr["vol"]),
        injected=readonly(arr["inj"]),
        n_bodies=readonly(arr["nb"].astype(int)),
        events=tuple(events),
        snapshots=tuple(snapshots),
        bodies=st.bodies(),
        steps=steps,
        rejected=rejected,
        stop_reason=stop_reason,
    )


def _take_snapshots(
    snaps_t: list[float],
    t: float,
    st: _State,
    out: list[tuple[float, tuple[Body, ...]]],
) -> None:
    # every body, the free ones too while the nozzle's meniscus is dormant (a drop that
    # pinched off at the exit keeps flying and must stay in the pictures)
    while snaps_t and snaps_t[0] <= t + 1e-12 * max(1.0, abs(t)):
        out.append((snaps_t.pop(0), st.bodies()))


def _pinch_event(
    st: _State,
    k: int,
    t: float,
    neck: float,
    prev_neck: float,
    h_break: float,
    hist: dict[str, list[float]],
) -> PinchEvent:
    """Breakup time interpolated linearly in neck radius between the last two steps."""
    t_cross = t
    if math.isfinite(prev_neck) and prev_neck > neck:
        frac = (prev_neck - h_break) / (prev_neck - neck)
        t_prev = hist["t"][-2]
        t_cross = t_prev + min(max(frac, 0.0), 1.0) * (t - t_prev)
    b = int(np.searchsorted(st.starts, k, side="right") - 1)
    k0, k1 = int(st.starts[b]), int(st.starts[b + 1])
    z_neck = 0.5 * (st.y[k, 0] + st.y[k + 1, 0])
    z_tip = float(st.y[k1 - 1, 0])
    z_tail = float(st.y[k0, 0])
    attached = bool(st.bcl[b] == jk.BC_NOZZLE)
    mode = classify_pinch(z_neck, z_tip, z_tail)
    return PinchEvent(t_cross, float(z_neck), z_tip, z_tail, attached, mode)


def _split(st: _State, k: int, h_cut: float) -> tuple[_State, float, float]:
    """Cut the body at neck cell ``k``, taking out the thread thinner than ``h_cut`` there.

    The cut removes the contiguous run of cells around ``k`` whose radius is below
    ``h_cut`` (`Numerics.cut_radius_factor` times the breakup radius; the neck cell
    itself always goes). The run's volume goes to the cells on either side (the part
    left of the neck's middle to the left, the rest to the right), as the ends of a
    broken thread recoil into the liquid behind them.

    Returns the new state, the volume over pi of a nozzle-side remnant too short to be a
    body (it becomes the dormant meniscus), and the volume of a detached fragment too
    short to be followed (reported as lost, so the volume balance stays exact).
    """
    b = int(np.searchsorted(st.starts, k, side="right") - 1)
    k0, k1 = int(st.starts[b]), int(st.starts[b + 1])
    bodies = list(st.bodies())
    body = bodies[b]
    j = k - k0
    nc = k1 - k0 - 1
    thin = body.w < h_cut**2 * np.diff(body.z)
    ja, jb = j, j
    while ja > 0 and thin[ja - 1]:
        ja -= 1
    while jb < nc - 1 and thin[jb + 1]:
        jb += 1
    to_left = float(body.w[ja:j].sum()) + 0.5 * float(body.w[j])
    to_right = float(body.w[j + 1 : jb + 1].sum()) + 0.5 * float(body.w[j])
    w = body.w.copy()
    if ja > 0:
        w[ja - 1] += to_left
    if jb < nc - 1:
        w[jb + 1] += to_right
    new: list[Body] = []
    remnant = lost = 0.0
    left_volume = float(w[:ja].sum()) if ja > 0 else to_left
    if ja >= 2:
        new.append(
            Body(
                z=body.z[: ja + 1],
                v=body.v[: ja + 1],
                w=w[:ja],
                a_zz=body.a_zz[:ja],
                a_rr=body.a_rr[:ja],
                left=body.left,
                right="tip",
            )
        )
    elif body.left == "nozzle":
        remnant = left_volume
    else:
        lost += left_volume
    if nc - 1 - jb >= 2:
        new.append(
            Body(
                z=body.z[jb + 1 :],
                v=body.v[jb + 1 :],
                w=w[jb + 1 :],
                a_zz=body.a_zz[jb + 1 :],
                a_rr=body.a_rr[jb + 1 :],
                left="tip",
                right=body.right,
            )
        )
    else:
        lost += float(w[jb + 1 :].sum()) if jb < nc - 1 else to_right
    bodies[b : b + 1] = new
    return _State.from_bodies(bodies), remnant, lost


def _tidy(
    st: _State,
    nu: Numerics,
    a_nozzle: float,
    has_inflow: bool,
    start_cap_height: float,
) -> tuple[_State, float | None]:
    """Regrid, merge bodies that touch, and retire a nozzle jet that has withdrawn.

    Returns the new state and, if the nozzle body was retired, its volume over pi.
    """
    if st.y.shape[0] == 0:
        return st, None
    gone: float | None = None
    nb = st.starts.size - 1
    # coalescence: a body's tip reaching the tail of the body ahead
    if nb > 1:
        z_end = st.y[st.starts[1:] - 1, 0]
        z_begin = st.y[st.starts[:-1], 0]
        closing = st.y[st.starts[1:-1] - 1, 1] > st.y[st.starts[1:-1], 1]
        # touching and closing in: the two ends of a fresh cut move apart
        touching = np.nonzero((z_end[:-1] >= z_begin[1:] - 0.02) & closing)[0]
        if touching.size:
            st = _coalesce(st, [int(i) for i in touching])
    # a nozzle jet that has drawn back into the nozzle
    if has_inflow and st.bcl[0] == jk.BC_NOZZLE:
        k1 = int(st.starts[1])
        if st.y[k1 - 1, 0] < 0.5 * start_cap_height and st.y[k1 - 1, 1] < 0.0:
            gone = float(st.w[: k1 - 1].sum())
            bodies = list(st.bodies())[1:]
            st = _State.from_bodies(bodies)
            if st.y.shape[0] == 0:
                return st, gone
    n = st.y.shape[0]
    out_y = np.empty((9 * n + 8, 4))
    out_w = np.empty(9 * n + 8)
    out_starts = np.empty_like(st.starts)
    n_out = jk.regrid(
        st.y,
        st.w,
        st.starts,
        st.bcl,
        st.bcr,
        a_nozzle,
        nu.resolution,
        nu.dz_min,
        nu.dz_max,
        out_y,
        out_w,
        out_starts,
    )
    if (
        n_out != n
        or not np.array_equal(out_starts, st.starts)
        or not np.array_equal(out_y[:n], st.y)
    ):
        st = _State(
            y=out_y[:n_out].copy(),
            w=out_w[:n_out].copy(),
            starts=out_starts,
            bcl=st.bcl,
            bcr=st.bcr,
        )
    return st, gone


def _coalesce(st: _State, pairs: list[int]) -> _State:
    """Join body ``i`` to body ``i + 1`` for each ``i`` in ``pairs`` (tip meets tail)."""
    bodies = list(st.bodies())
    for i in sorted(pairs, reverse=True):
        a, b = bodies[i], bodies[i + 1]
        if a.right != "tip" or b.left != "tip":
            continue
        ma, mb = 0.5 * a.w[-1], 0.5 * b.w[0]
        z_mid = 0.5 * (a.z[-1] + b.z[0])
        v_mid = (ma * a.v[-1] + mb * b.v[0]) / (ma + mb)
        if not (a.z[-2] < z_mid < b.z[1]):
            continue
        bodies[i : i + 2] = [
            Body(
                z=np.concatenate((a.z[:-1], [z_mid], b.z[1:])),
                v=np.concatenate((a.v[:-1], [v_mid], b.v[1:])),
                w=np.concatenate((a.w, b.w)),
                a_zz=np.concatenate((a.a_zz, b.a_zz)),
                a_rr=np.concatenate((a.a_rr, b.a_rr)),
                left=a.left,
                right=b.right,
            )
        ]
    return _State.from_bodies(bodies)
