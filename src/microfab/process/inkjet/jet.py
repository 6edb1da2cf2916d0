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
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np
from scipy.linalg import lapack

from microfab.core.arrays import readonly
from microfab.core.threads import single_threaded
from microfab.process.inkjet import jet_kernels as jk
from microfab.process.inkjet.breakup import BreakupMode, classify_pinch
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

BoundaryKind = Literal["nozzle", "wall", "tip"]
_BC = {"nozzle": jk.BC_NOZZLE, "wall": jk.BC_WALL, "tip": jk.BC_TIP}
_BC_NAME = {v: k for k, v in _BC.items()}


class Inflow(Protocol):
    """Dimensionless velocity through the nozzle exit and its time integral."""

    def velocity(self, t: float) -> float:
        """Mean axial velocity at the nozzle exit (positive out of the nozzle)."""
        ...

    def displacement(self, t: float) -> float:
        """Integral of :meth:`velocity` from the start of time to ``t``."""
        ...


@dataclass(frozen=True, kw_only=True)
class JetModel:
    """Dimensionless fluid parameters of the slender-jet model.

    Parameters
    ----------
    ohnesorge : float
        Solvent Ohnesorge number ``eta_s / sqrt(rho sigma R)`` (> 0).
    polymer_ohnesorge : float, optional
        Polymer Ohnesorge number ``eta_p / sqrt(rho sigma R)`` (default 0: Newtonian).
    deborah : float, optional
        Relaxation time over the capillary time ``lambda / t_c`` (needed if the polymer
        Ohnesorge number is positive).
    extensibility_l2 : float, optional
        FENE-P finite extensibility ``L^2`` (default inf: Oldroyd-B).

    Examples
    --------
    >>> JetModel(ohnesorge=0.1, polymer_ohnesorge=0.5, deborah=2.0).polymer_modulus
    0.25
    """

    ohnesorge: float
    polymer_ohnesorge: float = 0.0
    deborah: float = 0.0
    extensibility_l2: float = math.inf

    def __post_init__(self) -> None:
        if not self.ohnesorge > 0.0:
            raise ValueError(f"solvent Ohnesorge number must be > 0, got {self.ohnesorge}")
        if not self.polymer_ohnesorge >= 0.0:
            raise ValueError(f"polymer Ohnesorge number must be >= 0, got {self.polymer_ohnesorge}")
        if self.polymer_ohnesorge > 0.0 and not self.deborah > 0.0:
            raise ValueError(f"a polymer needs a Deborah number > 0, got {self.deborah}")
        if not self.extensibility_l2 > 3.0:
            raise ValueError(f"FENE-P extensibility L^2 must exceed 3, got {self.extensibility_l2}")

    @property
    def polymer_modulus(self) -> float:
        """Dimensionless polymer modulus ``G R / sigma = Oh_p / De``."""
        return self.polymer_ohnesorge / self.deborah if self.polymer_ohnesorge > 0 else 0.0


@dataclass(frozen=True, kw_only=True)
class Numerics:
    """Grid, tolerance and breakup settings of the solver (all dimensionless).

    Parameters
    ----------
    resolution : float
        Target cell length over the local radius.
    dz_min, dz_max : float
        Bounds of the target cell length.
    rtol, atol : float
        Local error tolerances of the time stepper (cell lengths are judged relatively).
    h_break : float
        Neck radius at which the jet counts as broken.
    cut_radius_factor : float
        With ``on_pinch="split"``, a cut also removes the thread next to the neck that is
        thinner than this many ``h_break`` (its volume recoils into the liquid on either
        side). At 1 the cut takes only what has broken, and a long thread hanging just
        above ``h_break`` unzips one cell at a time: the 1 % NaAlg drop-on-demand run
        (:mod:`.droplet`, 50 V, followed 20 µs past its first breakup) then makes 278
        cuts, spends 15 200 of its 19 600 steps after the first breakup and counts 18
        satellites of a few µm; at 1.5 it makes 3 cuts, spends 2 800 of 7 200 steps
        there and counts 2 satellites (2 at a factor of 2 as well). The first breakup is
        the same either way.
    max_steps : int
        Safety limit on time steps.
    max_nodes : int
        Safety limit on grid nodes.
    """

    resolution: float = 0.4
    dz_min: float = 1e-4
    dz_max: float = 0.25
    rtol: float = 2e-3
    atol: float = 1e-4
    h_break: float = 0.02
    cut_radius_factor: float = 1.5
    max_steps: int = 400_000
    max_nodes: int = 20_000

    def __post_init__(self) -> None:
        for name in ("resolution", "dz_min", "dz_max", "rtol", "atol", "h_break"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.cut_radius_factor >= 1.0:
            raise ValueError(f"cut_radius_factor must be >= 1, got {self.cut_radius_factor}")
        if self.dz_min >= self.dz_max:
            raise ValueError(f"dz_min {self.dz_min} must be below dz_max {self.dz_max}")


@dataclass(frozen=True, kw_only=True)
class Body:
    """One liquid body on the Lagrangian grid (dimensionless).

    Parameters
    ----------
    z, v : numpy.ndarray
        Node positions (strictly increasing) and velocities, length ``n``.
    w : numpy.ndarray
        Cell volumes over pi, length ``n - 1`` (all > 0).
    a_zz, a_rr : numpy.ndarray
        Polymer conformation per cell, length ``n - 1`` (1 at rest).
    left, right : {"nozzle", "wall", "tip"}
        End conditions (``right`` cannot be "nozzle").
    """

    z: np.ndarray
    v: np.ndarray
    w: np.ndarray
    a_zz: np.ndarray
    a_rr: np.ndarray
    left: BoundaryKind
    right: BoundaryKind

    def __post_init__(self) -> None:
        for name in ("z", "v", "w", "a_zz", "a_rr"):
            object.__setattr__(self, name, readonly(np.asarray(getattr(self, name), float)))
        n = self.z.size
        if n < 3:
            raise ValueError(f"a body needs at least 3 nodes, got {n}")
        if self.v.size != n or self.w.size != n - 1:
            raise ValueError("v must have one entry per node and w one per cell")
        if self.a_zz.size != n - 1 or self.a_rr.size != n - 1:
            raise ValueError("a_zz and a_rr must have one entry per cell")
        if np.any(np.diff(self.z) <= 0.0) or np.any(self.w <= 0.0):
            raise ValueError("node positions must increase and cell volumes be positive")
        if self.left not in _BC or self.right not in ("wall", "tip"):
            raise ValueError(f"bad end conditions {self.left!r}, {self.right!r}")

    @property
    def a(self) -> np.ndarray:
        """Mean squared radius of each cell."""
        return self.w / np.diff(self.z)

    @property
    def volume(self) -> float:
        """Volume over pi (dimensionless)."""
        return float(self.w.sum())

    def profile(self, a_nozzle: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Silhouette ``(z, r)``: cell centres plus the two ends.

        Tips have radius 0, a nozzle end ``sqrt(a_nozzle)``, a wall end its cell's.
        """
        a = self.a
        zc = 0.5 * (self.z[1:] + self.z[:-1])
        r_left = {"nozzle": math.sqrt(a_nozzle), "wall": math.sqrt(a[0]), "tip": 0.0}
        r_right = {"wall": math.sqrt(a[-1]), "tip": 0.0}
        z = np.concatenate(([self.z[0]], zc, [self.z[-1]]))
        r = np.concatenate(([r_left[self.left]], np.sqrt(a), [r_right[self.right]]))
        return z, r


@dataclass(frozen=True)
class PinchEvent:
    """A neck that broke: time, position, and the tip of the body it was in."""

    t: float
    z: float
    z_tip: float
    z_tail: float
    attached: bool
    mode: BreakupMode


@dataclass(frozen=True)
class JetRun:
    """Result of :func:`run_jet`: history per step, pinch events, snapshots.

    Attributes
    ----------
    t, neck_radius, neck_z, tip_z, tip_v, volume, injected, n_bodies : numpy.ndarray
        One entry per accepted step (dimensionless): time, thinnest neck radius, its
        position, leading tip position and velocity, total liquid volume over pi, volume
        over pi pushed through the nozzle since the start, number of bodies.
    events : tuple of PinchEvent
        Breakups in time order.
    snapshots : tuple of (float, tuple of Body)
        The bodies at each requested snapshot time (or at the first step after it, see
        `run_jet`'s ``land_on_snapshots``).
    bodies : tuple of Body
        The state at the end.
    steps, rejected : int
        Accepted and rejected time steps.
    stop_reason : str
        Why the run ended.
    meniscus_z : numpy.ndarray or None
        Position of the meniscus centre per step (0 at the rim, negative inside the
        bore); None for a model that holds it at the rim (:func:`run_jet`).
    upstream_velocity : numpy.ndarray or None
        Nozzle velocity of a coupled upstream model at its own samples (spacing
        ``upstream_dt`` from the first time of `t`); None without one.
    upstream_dt : float
        Sample spacing of `upstream_velocity` (0 without one).
    """

    t: np.ndarray
    neck_radius: np.ndarray
    neck_z: np.ndarray
    tip_z: np.ndarray
    tip_v: np.ndarray
    volume: np.ndarray
    injected: np.ndarray
    n_bodies: np.ndarray
    events: tuple[PinchEvent, ...]
    snapshots: tuple[tuple[float, tuple[Body, ...]], ...]
    bodies: tuple[Body, ...]
    steps: int
    rejected: int
    stop_reason: str
    meniscus_z: np.ndarray | None = None
    upstream_velocity: np.ndarray | None = None
    upstream_dt: float = 0.0


def thread_body(
    length: float,
    radius: Callable[[np.ndarray], np.ndarray],
    *,
    cells: int = 200,
    velocity: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Body:
    """A thread between two symmetry walls at ``z = 0`` and ``z = length``.

    Parameters
    ----------
    length : float
        Domain length (dimensionless).
    radius : callable
        ``h(z)`` of the initial thread; cell volumes are integrated with 8-point
        Gauss-Legendre per cell.
    cells : int, optional
        Number of cells (uniform).
    velocity : callable, optional
        Initial ``v(z)`` at the nodes (default at rest).

    Returns
    -------
    Body

    Examples
    --------
    >>> b = thread_body(3.0, lambda z: 1.0 + 0.0 * z, cells=30)
    >>> round(b.volume, 12)
    3.0
    """
    z = np.linspace(0.0, length, cells + 1)
    x, wq = np.polynomial.legendre.leggauss(8)
    half = 0.5 * np.diff(z)
    pts = 0.5 * (z[1:] + z[:-1])[:, None] + half[:, None] * x[None, :]
    w = (radius(pts) ** 2 * wq[None, :]).sum(axis=1) * half
    v = np.zeros_like(z) if velocity is None else np.asarray(velocity(z), float)
    v = v.copy()
    v[0] = v[-1] = 0.0
    ones = np.ones(cells)
    return Body(z=z, v=v, w=w, a_zz=ones, a_rr=ones, left="wall", right="wall")


def cap_volume(height: float, a_nozzle: float = 1.0) -> float:
    """Volume over pi of a spherical cap of ``height`` on a rim of radius² ``a_nozzle``."""
    return height * (3.0 * a_nozzle + height * height) / 6.0


def cap_body(
    volume: float, *, velocity: float = 0.0, cells: int = 24, a_nozzle: float = 1.0
) -> Body:
    """A spherical-cap meniscus of a given volume over pi, pinned to the nozzle rim.

    Parameters
    ----------
    volume : float
        Cap volume over pi (dimensionless, > 0).
    velocity : float, optional
        Uniform initial velocity.
    cells : int, optional
        Number of cells, uniform in z.
    a_nozzle : float, optional
        Squared rim radius (1: the nozzle radius is the length unit).

    Returns
    -------
    Body
        Nozzle-to-tip body.

    Examples
    --------
    >>> b = cap_body(cap_volume(0.5))
    >>> round(float(b.z[-1]), 12)
    0.5
    """
    if not volume > 0.0:
        raise ValueError(f"cap volume must be > 0, got {volume}")
    # height from the cubic h^3 + 3 a h - 6 V = 0 (one real root)
    p = 3.0 * a_nozzle
    q = -6.0 * volume
    disc = math.sqrt(q * q / 4.0 + p**3 / 27.0)
    height = math.copysign(abs(-q / 2 + disc) ** (1 / 3), -q / 2 + disc) + math.copysign(
        abs(-q / 2 - disc) ** (1 / 3), -q / 2 - disc
    )
    rc = (a_nozzle + height * height) / (2.0 * height)
    zc = height - rc
    z = np.linspace(0.0, height, cells + 1)

    def prim(x: np.ndarray) -> np.ndarray:
        return rc * rc * x - (x - zc) ** 3 / 3.0

    w = np.diff(prim(z))
    ones = np.ones(cells)
    return Body(
        z=z,
        v=np.full(cells + 1, velocity),
        w=w,
        a_zz=ones,
        a_rr=ones,
        left="nozzle",
        right="tip",
    )


@dataclass
class _State:
    y: np.ndarray
    w: np.ndarray
    starts: np.ndarray
    bcl: np.ndarray
    bcr: np.ndarray
    fixed_z: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def from_bodies(cls, bodies: Sequence[Body]) -> _State:
        ys, ws, starts = [], [], [0]
        for b in bodies:
            blk = np.zeros((b.z.size, 4))
            blk[:, 0] = b.z
            blk[:, 1] = b.v
            blk[:-1, 2] = b.a_zz
            blk[:-1, 3] = b.a_rr
            blk[-1, 2:] = 1.0
            ys.append(blk)
            ws.append(np.append(b.w, 0.0))
            starts.append(starts[-1] + b.z.size)
        y = np.concatenate(ys) if ys else np.zeros((0, 4))
        w = np.concatenate(ws) if ws else np.zeros(0)
        return cls(
            y=y,
            w=w,
            starts=np.array(starts, dtype=np.int64),
            bcl=np.array([_BC[b.left] for b in bodies], dtype=np.int64),
            bcr=np.array([_BC[b.right] for b in bodies], dtype=np.int64),
        )

    def bodies(self) -> tuple[Body, ...]:
        out = []
        for b in range(self.starts.size - 1):
            k0, k1 = self.starts[b], self.starts[b + 1]
            blk = self.y[k0:k1]
            out.append(
                Body(
                    z=blk[:, 0].copy(),
                    v=blk[:, 1].copy(),
                    w=self.w[k0 : k1 - 1].copy(),
                    a_zz=blk[:-1, 2].copy(),
                    a_rr=blk[:-1, 3].copy(),
                    left=_BC_NAME[int(self.bcl[b])],
                    right=_BC_NAME[int(self.bcr[b])],
                )
            )
        return tuple(out)


class _JetSystem:
    """Fluid parameters of the kernels, fixed for a run; hands out per-step problems."""

    def __init__(self, model: JetModel, numerics: Numerics, a_nozzle: float) -> None:
        self.nu = numerics
        self.a_nozzle = a_nozzle
        self.args = (
            a_nozzle,
            model.ohnesorge,
            model.polymer_modulus,
            1.0 / model.deborah if model.deborah > 0 else 0.0,
            0.0 if math.isinf(model.extensibility_l2) else 1.0 / model.extensibility_l2,
        )

    def at_step(
        self,
        st: _State,
        t: float,
        inflow: Inflow | None,
        w0_ref: float,
        u_ref: float,
        piston: bool,
    ) -> _JetStep:
        """The jet on its current grid, as an `ImplicitProblem` for one step from ``t``."""
        return _JetStep(self, st, t, inflow, w0_ref, u_ref, piston)


class _JetStep:
    """One step of the jet on a fixed grid, seen by the integrator (`ImplicitProblem`).

    The state ``y`` has shape (nodes, 4): position, velocity, and the conformation
    ``a_zz``, ``a_rr`` of the cell to the right of each node. The nozzle cell's volume
    follows the inflow over the step (unless the meniscus retracts as a piston), the end
    nodes of walls and the nozzle are algebraic constraints, and the Newton matrix is
    the banded ``I - gh J`` factored by LAPACK.
    """

    def __init__(
        self,
        system: _JetSystem,
        st: _State,
        t0: float,
        inflow: Inflow | None,
        w0_ref: float,
        u_ref: float,
        piston: bool,
    ) -> None:
        self.sys = system
        self.st = st
        self.t0 = t0
        self.inflow = inflow
        self.w0_ref = w0_ref
        self.u_ref = u_ref
        self.piston = piston
        self.alg_idx, self._alg_val = _algebraic(st, inflow, u_ref, piston)
        self._lu: np.ndarray | None = None
        self._piv: np.ndarray | None = None
        self._stage_t = math.nan
        self._stage_w = st.w
        self._stage_targets = np.zeros(0)

    def _w(self, t: float) -> np.ndarray:
        """Cell volumes at ``t``: the state's own at the start of the step."""
        if self.piston or t == self.t0:
            return self.st.w
        return _w_at(self.st, t, self.inflow, self.w0_ref, self.u_ref, self.sys.a_nozzle)

    def _stage(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if t != self._stage_t:
            self._stage_t = t
            self._stage_w = self._w(t)
            self._stage_targets = self._alg_val(t)
        return self._stage_w, self._stage_targets

    def _f(self, y: np.ndarray, w: np.ndarray, out: np.ndarray) -> bool:
        st = self.st
        return bool(jk.rhs(y, w, st.starts, st.bcl, st.bcr, *self.sys.args, out))

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray | None:
        out = np.empty_like(y)
        return out if self._f(y, self._w(t), out) else None

    def factor(self, t: float, y: np.ndarray, f: np.ndarray, gh: float) -> bool:
        st = self.st
        kl = jk.KL
        ab = np.empty((3 * kl + 1, y.size))
        jk.jacobian_banded(y, self._w(t), st.starts, st.bcl, st.bcr, *self.sys.args, f, ab)
        ab *= -gh
        ab[2 * kl, :] += 1.0
        lu, piv, info = lapack.dgbtrf(ab, kl, kl, overwrite_ab=1)
        if info != 0:
            return False
        self._lu, self._piv = lu, piv
        return True

    def residual(self, t: float, y: np.ndarray, base: np.ndarray, gh: float) -> np.ndarray | None:
        w, targets = self._stage(t)
        fy = np.empty_like(y)
        if not self._f(y, w, fy):
            return None
        res = y - base - gh * fy
        res_flat = res.ravel()
        res_flat[self.alg_idx] = y.ravel()[self.alg_idx] - targets
        return res

    def solve(self, r: np.ndarray) -> np.ndarray | None:
        kl = jk.KL
        delta, info = lapack.dgbtrs(self._lu, kl, kl, r.ravel(), self._piv)
        if info != 0:
            return None
        return delta.reshape(r.shape)

    def filter_error(self, est: np.ndarray) -> np.ndarray:
        kl = jk.KL
        est_flat = est.ravel()
        est_flat[self.alg_idx] = 0.0
        err, _ = lapack.dgbtrs(self._lu, kl, kl, est_flat, self._piv)
        return err.reshape(est.shape)

    def norm(self, e: np.ndarray, y: np.ndarray) -> float:
        nu = self.sys.nu
        return float(jk.error_norm(e, y, self.st.starts, nu.rtol, nu.atol))

    def admissible(self, y: np.ndarray) -> bool:
        return not np.any(np.diff(y[:, 0])[_inner_cells(self.st)] <= 0.0)


def _inner_cells(st: _State) -> np.ndarray:
    mask = np.ones(st.y.shape[0] - 1, dtype=bool)
    mask[st.starts[1:-1] - 1] = False
    return mask


def _w_at(
    st: _State,
    t: float,
    inflow: Inflow | None,
    w0_ref: float,
    u_ref: float,
    a_nozzle: float,
) -> np.ndarray:
    if inflow is None or st.bcl.size == 0 or st.bcl[0] != jk.BC_NOZZLE:
        return st.w
    w = st.w.copy()
    w[0] = w0_ref + a_nozzle * (inflow.displacement(t) - u_ref)
    return w


def _algebraic(
    st: _State, inflow: Inflow | None, u_ref: float, piston: bool
) -> tuple[np.ndarray, Callable[[float], np.ndarray]]:
    idx: list[int] = []
    const: list[float] = []
    nozzle_pos = -1
    for b in range(st.starts.size - 1):
        k0, k1 = int(st.starts[b]), int(st.starts[b + 1])
        if st.bcl[b] != jk.BC_TIP:
            idx += [4 * k0, 4 * k0 + 1]
            const += [st.y[k0, 0], 0.0]
            if st.bcl[b] == jk.BC_NOZZLE:
                nozzle_pos = len(idx) - 2
        if st.bcr[b] != jk.BC_TIP:
            idx += [4 * (k1 - 1), 4 * (k1 - 1) + 1]
            const += [st.y[k1 - 1, 0], 0.0]
    base = np.array(const)

    def values(ts: float) -> np.ndarray:
        if nozzle_pos < 0 or inflow is None:
            return base
        out = base.copy()
        out[nozzle_pos + 1] = inflow.velocity(ts)
        if piston:
            out[nozzle_pos] = base[nozzle_pos] + inflow.displacement(ts) - u_ref
        return out

    return np.array(idx, dtype=np.int64), values


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
