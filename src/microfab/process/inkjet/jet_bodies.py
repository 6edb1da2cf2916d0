"""Data of the slender-jet solvers: parameters, bodies, inflow, results, initial shapes.

What :func:`.jet.run_jet` takes and returns, kept apart from the solver: the fluid and
grid parameters (`JetModel`, `Numerics`), the liquid bodies on the Lagrangian grid
(`Body`) and their packed form for the kernels (`_State`), the nozzle inflow (`Inflow`),
the record of a run (`PinchEvent`, `JetRun`) and initial bodies (`thread_body`,
`cap_body`). The Eulerian solver (:mod:`.jet_euler`) returns the same record. The model,
its units and the discretisation are described in :mod:`.jet`, which re-exports these
names.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np

from microfab.core.arrays import readonly
from microfab.process.inkjet import jet_kernels as jk
from microfab.process.inkjet.breakup import BreakupMode

__all__ = [
    "Body",
    "BoundaryKind",
    "Inflow",
    "JetModel",
    "JetRun",
    "Numerics",
    "PinchEvent",
    "cap_body",
    "cap_volume",
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
