"""Settings and state of the Eulerian jet's fixed grid: numerics, initial profiles, bodies.

What :func:`.jet_euler.run_jet_euler` is given and what it keeps between calls of its
kernels, apart from the driver: the grid, step and breakup settings (`EulerNumerics`), an
initial state that defines the grid (`EulerInitial`, `euler_thread`), and the state on
the grid with its ends, whose wet runs are the bodies of the run (`_Field`). The model
and its discretisation are described in :mod:`.jet_euler`, which re-exports these names.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from microfab.core.arrays import readonly
from microfab.process.inkjet import jet_euler_kernels as ek
from microfab.process.inkjet.jet_bodies import Body

__all__ = [
    "EulerInitial",
    "EulerNumerics",
    "LeftEnd",
    "RightEnd",
    "euler_thread",
]

LeftEnd = Literal["nozzle", "wall"]
RightEnd = Literal["outflow", "wall"]
_LEFT = {"nozzle": ek.BC_NOZZLE, "wall": ek.BC_WALL}
_RIGHT = {"outflow": ek.BC_OUTFLOW, "wall": ek.BC_WALL}
_LIMITERS = {"van_leer": 0, "minmod": 1}


@dataclass(frozen=True, kw_only=True)
class EulerNumerics:
    """Grid, step and breakup settings of the Eulerian solver (all dimensionless).

    Parameters
    ----------
    dz : float
        Grid spacing in nozzle radii (default 0.04: 25 cells per radius).
    length : float
        Domain length from the nozzle exit (default 30 nozzle radii). ``dz`` and
        ``length`` are only used when the run starts from the nozzle (no ``initial``
        profile, which brings its own grid).
    cfl : float
        Safety factor on the stable step, in ``(0, 0.9]`` (default 0.4): the advective
        Courant number; the polymer-wave limit is scaled by it and the capillary-wave
        limit by ``min(2 cfl, 0.9)`` (1 is the stability edge of the forward-backward
        scheme).
    film : float
        Radius of the regularising film, below ``h_break`` (default 1e-3).
    h_break : float
        Neck radius at which the jet counts as broken (default 0.02; ``droplet.py`` sets
        it from the camera resolution).
    rewet_factor : float
        A dried cell counts as liquid again above this many ``h_break`` (>= 1, default
        1.5).
    limiter : {"van_leer", "minmod"}
        Flux limiter of the TVD fluxes.
    dt_max : float
        Largest time step (default 0.02).
    inflow_dt : float
        Spacing of the table of the nozzle displacement the kernels interpolate
        (default 1e-3).
    max_steps : int
        Safety limit on time steps (default 2 000 000).
    cap_cells : float
        With a retracting meniscus: a bulge out of the rim is held as a lumped spherical
        cap (:mod:`.jet_euler_meniscus`) until its centre is this many cells high
        (default 5), then handed to the grid with exactly that shape (the step ends when
        the column has pushed it there). A bulge of a cell or two is not a free surface
        the grid can carry: liquid pushed into the film at the rim spreads into cells a
        few percent of the bore wide.

    Examples
    --------
    >>> EulerNumerics(dz=0.05).cells_for(30.0)
    600
    """

    dz: float = 0.04
    length: float = 30.0
    cfl: float = 0.4
    film: float = 1e-3
    h_break: float = 0.02
    rewet_factor: float = 1.5
    limiter: Literal["van_leer", "minmod"] = "van_leer"
    dt_max: float = 0.02
    inflow_dt: float = 1e-3
    max_steps: int = 2_000_000
    cap_cells: float = 5.0

    def __post_init__(self) -> None:
        for name in ("dz", "length", "film", "h_break", "dt_max", "inflow_dt"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not 0.0 < self.cfl <= 0.9:
            raise ValueError(f"cfl must lie in (0, 0.9] for the TVD fluxes, got {self.cfl}")
        if self.h_break >= 1.0:
            raise ValueError(
                f"h_break {self.h_break} must be below the nozzle radius 1 (lengths are in "
                "nozzle radii)"
            )
        if self.film >= self.h_break:
            raise ValueError(
                f"film radius {self.film} must be below h_break {self.h_break}: lower `film` "
                "or raise `h_break`"
            )
        if self.rewet_factor < 1.0:
            raise ValueError(f"rewet_factor must be >= 1, got {self.rewet_factor}")
        if self.limiter not in _LIMITERS:
            raise ValueError(f"limiter must be one of {sorted(_LIMITERS)}, got {self.limiter!r}")
        if self.cells_for(self.length) < 8:
            raise ValueError(
                f"length {self.length} holds fewer than 8 cells of dz {self.dz}: lower `dz`"
            )
        if not (math.isfinite(self.cap_cells) and self.cap_cells >= 1.0):
            raise ValueError(f"cap_cells must be a finite number >= 1, got {self.cap_cells!r}")
        if self.cap_cells * self.dz >= 0.5:
            raise ValueError(
                f"cap_cells {self.cap_cells} x dz {self.dz} must stay below half the nozzle "
                "radius: lower `cap_cells` or `dz`"
            )
        if not (isinstance(self.max_steps, int) and self.max_steps >= 1):
            raise ValueError(f"max_steps must be a positive integer, got {self.max_steps!r}")

    def cells_for(self, length: float) -> int:
        """Number of cells that cover ``length`` at spacing ``dz`` (rounded)."""
        return round(length / self.dz)


@dataclass(frozen=True, kw_only=True)
class EulerInitial:
    """An initial state on the grid, which then defines the grid.

    Parameters
    ----------
    length : float
        Domain length; the grid has ``a.size`` cells of ``length / a.size``.
    a : numpy.ndarray
        Cell means of the squared radius, shape ``(n,)``, all > 0 (``n >= 8``).
    u : numpy.ndarray, optional
        Face velocities, shape ``(n + 1,)`` (default at rest; a wall's face is set to 0).
    a_zz, a_rr : numpy.ndarray, optional
        Conformation per cell, shape ``(n,)`` (default 1: at rest).
    left : {"nozzle", "wall"}
        Nozzle exit (inflow) or symmetry plane at ``z = 0``.
    right : {"outflow", "wall"}
        Open end or symmetry plane at ``z = length``.
    """

    length: float
    a: np.ndarray
    u: np.ndarray | None = None
    a_zz: np.ndarray | None = None
    a_rr: np.ndarray | None = None
    left: LeftEnd = "wall"
    right: RightEnd = "wall"

    def __post_init__(self) -> None:
        a = readonly(self.a)
        n = a.size
        if a.ndim != 1 or n < 8:
            raise ValueError(f"the initial profile needs at least 8 cells, got shape {a.shape}")
        if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
            raise ValueError("the initial squared radius must be finite and > 0 in every cell")
        if not (math.isfinite(self.length) and self.length > 0.0):
            raise ValueError(f"length must be > 0, got {self.length}")
        object.__setattr__(self, "a", a)
        u = np.zeros(n + 1) if self.u is None else np.array(self.u, float)
        if u.shape != (n + 1,):
            raise ValueError(f"u needs one value per face ({n + 1}), got shape {u.shape}")
        if self.left == "wall":
            u[0] = 0.0
        if self.right == "wall":
            u[-1] = 0.0
        object.__setattr__(self, "u", readonly(u))
        for name in ("a_zz", "a_rr"):
            v = np.ones(n) if getattr(self, name) is None else np.asarray(getattr(self, name))
            if v.shape != (n,) or np.any(~(v > 0.0)):
                raise ValueError(f"{name} needs one positive value per cell ({n})")
            object.__setattr__(self, name, readonly(v))
        if self.left not in _LEFT or self.right not in _RIGHT:
            raise ValueError(
                f"left must be one of {sorted(_LEFT)} and right one of {sorted(_RIGHT)}, got "
                f"{self.left!r}, {self.right!r}"
            )

    @property
    def dz(self) -> float:
        """Grid spacing."""
        return self.length / self.a.size


def euler_thread(
    length: float,
    radius: Callable[[np.ndarray], np.ndarray],
    *,
    cells: int = 200,
    velocity: Callable[[np.ndarray], np.ndarray] | None = None,
) -> EulerInitial:
    """A thread between two symmetry walls at ``z = 0`` and ``z = length``.

    Parameters
    ----------
    length : float
        Domain length (dimensionless).
    radius : callable
        ``h(z)`` of the initial thread; cell means of ``h^2`` are integrated with
        8-point Gauss-Legendre per cell.
    cells : int, optional
        Number of cells.
    velocity : callable, optional
        Initial ``u(z)`` at the faces (default at rest).

    Returns
    -------
    EulerInitial

    Examples
    --------
    >>> th = euler_thread(3.0, lambda z: 1.0 + 0.0 * z, cells=30)
    >>> round(float(th.a.sum() * th.dz), 12)
    3.0
    """
    z = np.linspace(0.0, length, cells + 1)
    x, wq = np.polynomial.legendre.leggauss(8)
    half = 0.5 * np.diff(z)
    pts = 0.5 * (z[1:] + z[:-1])[:, None] + half[:, None] * x[None, :]
    a = 0.5 * (radius(pts) ** 2 * wq[None, :]).sum(axis=1)
    u = None if velocity is None else np.asarray(velocity(z), float)
    return EulerInitial(length=length, a=a, u=u, left="wall", right="wall")


@dataclass
class _Field:
    """The state on the grid (arrays updated in place by the kernels) and its ends."""

    a: np.ndarray
    u: np.ndarray
    azz: np.ndarray
    arr: np.ndarray
    wet: np.ndarray
    dz: float
    left: LeftEnd
    right: RightEnd
    z_off: float = 0.0

    def bodies(self) -> tuple[Body, ...]:
        """Wet runs of at least two cells as :class:`.jet.Body` (nodes at the cell faces)."""
        n = self.a.size
        out = []
        i = 0
        while i < n:
            if not self.wet[i]:
                i += 1
                continue
            j = i
            while j + 1 < n and self.wet[j + 1]:
                j += 1
            if j - i + 1 >= ek.MIN_CELLS:
                left = self.left if i == 0 else "tip"
                right = "wall" if (j == n - 1 and self.right == "wall") else "tip"
                out.append(
                    Body(
                        z=self.z_off + self.dz * np.arange(i, j + 2),
                        v=self.u[i : j + 2],
                        w=self.a[i : j + 1] * self.dz,
                        a_zz=self.azz[i : j + 1],
                        a_rr=self.arr[i : j + 1],
                        left=left,
                        right=right,
                    )
                )
            i = j + 1
        return tuple(out)
