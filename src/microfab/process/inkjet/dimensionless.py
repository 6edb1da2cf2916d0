"""Dimensionless groups of a drop-on-demand jet and the printability window.

Length-scale convention (used consistently everywhere in this module)
---------------------------------------------------------------------
* Reynolds, Weber, Ohnesorge and Z use the length ``L`` = the nozzle **diameter**
  ``D = 2R`` by default (``length_m`` overrides it)::

      Re = ρ v L / η0,   We = ρ v² L / σ,   Oh = η0 / sqrt(ρ σ L) = sqrt(We) / Re,   Z = 1/Oh

  This is the convention in which the printability window of Derby (2010, Annu. Rev. Mater.
  Res. 40:395) is usually quoted for DOD nozzles; with the radius instead, Oh would be
  larger by sqrt(2).
* The capillary (Rayleigh) time, the intrinsic Deborah number and the elasto-capillary number
  use the nozzle **radius** R, as in capillary-thinning work::

      t_c = sqrt(ρ R³ / σ),   De = λ / t_c,   t_v = η0 R / σ,   Ec = λ σ / (η0 R) = λ / t_v

  (Ec after Anna & McKinley 2001, J. Rheol. 45:115.)
* Viscosities are zero-shear values ``η0 = η_s + η_p``.

Printability window (Derby 2010)
--------------------------------
* ``1 <= Z <= 10`` (Reis & Derby 2000): Z < 1 is too viscous to form drops; Z > 10 gives
  satellite drops;
* ``We > 4``: below it the fluid has too little kinetic energy to overcome surface tension
  and be ejected (Duineveld et al. 2002, via Derby 2010);
* ``We^(1/2) Re^(1/4) < 50``: above it drops splash on impact (Stow & Hadfield 1981, via
  Derby 2010). The jet speed stands in for the impact speed.

When several limits fail, the category reported is the first of: no ejection, splashing,
too viscous, satellites.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from microfab.core.validate import check_nonnegative, check_positive
from microfab.process.inkjet.fluids import Fluid, NaAlgTable, naalg

__all__ = [
    "CATEGORIES",
    "SPLASH_LIMIT",
    "WEBER_MIN",
    "Z_MAX",
    "Z_MIN",
    "Dimensionless",
    "RegimeMap",
    "numbers",
    "regime_map",
]

#: Lower end of the printable window in Z = 1/Oh (Reis & Derby 2000; Derby 2010).
Z_MIN = 1.0
#: Upper end of the printable window in Z: satellites above it (Reis & Derby 2000; Derby 2010).
Z_MAX = 10.0
#: Minimum Weber number for drop ejection (Duineveld et al. 2002; Derby 2010).
WEBER_MIN = 4.0
#: Splashing onset We^(1/2) Re^(1/4) (Stow & Hadfield 1981; Derby 2010).
SPLASH_LIMIT = 50.0

#: Category names, indexed by the integer codes of `RegimeMap.category`.
CATEGORIES: tuple[str, ...] = (
    "too viscous",
    "printable",
    "satellites",
    "no ejection",
    "splashing",
)


def _category_code(weber: float, z_number: float, splash: float) -> int:
    if weber < WEBER_MIN:
        return CATEGORIES.index("no ejection")
    if splash > SPLASH_LIMIT:
        return CATEGORIES.index("splashing")
    if z_number < Z_MIN:
        return CATEGORIES.index("too viscous")
    if z_number > Z_MAX:
        return CATEGORIES.index("satellites")
    return CATEGORIES.index("printable")


@dataclass(frozen=True)
class Dimensionless:
    """Dimensionless groups of one fluid at one jet speed (conventions: module docstring).

    Attributes
    ----------
    reynolds, weber, ohnesorge : float
        Re, We, Oh with the length ``length_m`` (default: nozzle diameter).
    deborah : float
        Intrinsic Deborah number λ / t_c (radius-based).
    elastocapillary : float
        Ec = λ σ / (η0 R) (radius-based).
    z_number : float
        Z = 1/Oh.
    capillary_time_s : float
        t_c = sqrt(ρ R³ / σ), s.
    viscous_time_s : float
        t_v = η0 R / σ, s.
    length_m : float
        Length used for Re, We, Oh, m.
    radius_m : float
        Nozzle radius used for t_c, t_v, De, Ec, m.
    """

    reynolds: float
    weber: float
    ohnesorge: float
    deborah: float
    elastocapillary: float
    z_number: float
    capillary_time_s: float
    viscous_time_s: float
    length_m: float
    radius_m: float

    @property
    def splash_parameter(self) -> float:
        """We^(1/2) Re^(1/4); splashing above `SPLASH_LIMIT` (Stow & Hadfield 1981)."""
        return math.sqrt(self.weber) * self.reynolds**0.25

    @property
    def category(self) -> str:
        """One of `CATEGORIES` (first failing limit; ``"printable"`` if none fails)."""
        return CATEGORIES[_category_code(self.weber, self.z_number, self.splash_parameter)]

    @property
    def printable(self) -> bool:
        """True inside Derby's window: 1 <= Z <= 10, We > 4, We^1/2 Re^1/4 <= 50."""
        return self.category == "printable"

    @property
    def window(self) -> str:
        """Which printability limit applies, in words, with the numbers."""
        z, we, k = self.z_number, self.weber, self.splash_parameter
        cat = self.category
        if cat == "no ejection":
            return (
                f"no ejection: We = {we:.3g} < {WEBER_MIN:g}, too little kinetic energy to "
                "overcome surface tension (Duineveld et al. 2002; Derby 2010)"
            )
        if cat == "splashing":
            return (
                f"splashing: We^1/2 Re^1/4 = {k:.3g} > {SPLASH_LIMIT:g} "
                "(Stow & Hadfield 1981; Derby 2010)"
            )
        if cat == "too viscous":
            return (
                f"too viscous: Z = 1/Oh = {z:.3g} < {Z_MIN:g}, viscous dissipation prevents "
                "drop ejection (Reis & Derby 2000; Derby 2010)"
            )
        if cat == "satellites":
            return (
                f"satellites: Z = 1/Oh = {z:.3g} > {Z_MAX:g}, the tail breaks into satellite "
                "drops (Reis & Derby 2000; Derby 2010)"
            )
        return (
            f"printable: {Z_MIN:g} <= Z = {z:.3g} <= {Z_MAX:g}, We = {we:.3g} > {WEBER_MIN:g}, "
            f"We^1/2 Re^1/4 = {k:.3g} <= {SPLASH_LIMIT:g} (Derby 2010 window)"
        )


def numbers(
    fluid: Fluid,
    *,
    nozzle_radius_m: float = 60e-6,
    speed_m_s: float,
    length_m: float | None = None,
) -> Dimensionless:
    """Dimensionless groups of a fluid jetted from a nozzle at a given speed.

    Parameters
    ----------
    fluid : Fluid
        The liquid (zero-shear viscosity is used).
    nozzle_radius_m : float, optional
        Nozzle radius R, m (default 60 µm: the seed's 120 µm MicroFab orifice). Used for
        t_c, t_v, De and Ec.
    speed_m_s : float
        Jet (drop) speed v, m/s (>= 0).
    length_m : float, optional
        Length for Re, We and Oh; default the nozzle diameter 2R.

    Returns
    -------
    Dimensionless
        Re, We, Oh, Z, De, Ec and the time scales.

    Raises
    ------
    ValueError
        If the radius or length is not positive, or the speed is negative or not finite.

    Examples
    --------
    >>> from microfab.process.inkjet.fluids import WATER
    >>> d = numbers(WATER, speed_m_s=5.0)
    >>> round(d.ohnesorge, 5), round(d.z_number, 1), d.category
    (0.00959, 104.3, 'satellites')
    >>> abs(d.ohnesorge - d.weber**0.5 / d.reynolds) < 1e-12
    True
    """
    r = check_positive("nozzle radius", nozzle_radius_m, "m")
    length = check_positive("length", 2.0 * r if length_m is None else length_m, "m")
    v = check_nonnegative("jet speed", speed_m_s, "m/s")
    rho = fluid.density_kg_m3
    sigma = fluid.surface_tension_n_m
    eta0 = fluid.zero_shear_viscosity_pa_s
    lam = fluid.relaxation_time_s
    oh = eta0 / math.sqrt(rho * sigma * length)
    t_c = math.sqrt(rho * r**3 / sigma)
    t_v = eta0 * r / sigma
    return Dimensionless(
        reynolds=rho * v * length / eta0,
        weber=rho * v**2 * length / sigma,
        ohnesorge=oh,
        deborah=lam / t_c,
        elastocapillary=lam / t_v,
        z_number=1.0 / oh,
        capillary_time_s=t_c,
        viscous_time_s=t_v,
        length_m=length,
        radius_m=r,
    )


@dataclass(frozen=True, eq=False)
class RegimeMap:
    """Dimensionless groups of NaAlg over a concentration × speed grid.

    Every 2-D array has shape ``(len(concentrations_pct), len(speeds_m_s))``.

    Attributes
    ----------
    concentrations_pct, speeds_m_s : ndarray
        Grid axes, % w/v and m/s.
    nozzle_radius_m, length_m : float
        Radius (t_c, De, Ec) and length (Re, We, Oh) used.
    reynolds, weber, ohnesorge, z_number, deborah, elastocapillary, splash_parameter : ndarray
        The groups (Oh, Z, De, Ec do not depend on the speed).
    category : ndarray of int
        Index into `CATEGORIES`.
    printable : ndarray of bool
        Inside Derby's window.
    table : NaAlgTable or None
        Property table used (``None``: package default).
    """

    concentrations_pct: NDArray[np.float64]
    speeds_m_s: NDArray[np.float64]
    nozzle_radius_m: float
    length_m: float
    reynolds: NDArray[np.float64]
    weber: NDArray[np.float64]
    ohnesorge: NDArray[np.float64]
    z_number: NDArray[np.float64]
    deborah: NDArray[np.float64]
    elastocapillary: NDArray[np.float64]
    splash_parameter: NDArray[np.float64]
    category: NDArray[np.int_]
    printable: NDArray[np.bool_]
    table: NaAlgTable | None = None


def regime_map(
    concentrations_pct: ArrayLike,
    speeds_m_s: ArrayLike,
    *,
    nozzle_radius_m: float = 60e-6,
    length_m: float | None = None,
    table: NaAlgTable | None = None,
) -> RegimeMap:
    """Evaluate `numbers` for NaAlg over a concentration × speed grid.

    Parameters
    ----------
    concentrations_pct : array_like
        NaAlg concentrations, % w/v (each within the property table, 0 to 2 %).
    speeds_m_s : array_like
        Jet speeds, m/s.
    nozzle_radius_m : float, optional
        Nozzle radius, m (default 60 µm).
    length_m : float, optional
        Length for Re, We, Oh (default: nozzle diameter).
    table : NaAlgTable, optional
        Property table (e.g. a calibrated one); default: the package table.

    Returns
    -------
    RegimeMap
        2-D arrays over (concentration, speed).

    Examples
    --------
    >>> m = regime_map([0.15, 1.0, 2.0], [1.0, 3.0, 6.0])
    >>> m.weber.shape, bool(m.printable.any())
    ((3, 3), True)
    """
    cs = np.atleast_1d(np.asarray(concentrations_pct, dtype=float))
    vs = np.atleast_1d(np.asarray(speeds_m_s, dtype=float))
    if cs.ndim != 1 or vs.ndim != 1 or cs.size == 0 or vs.size == 0:
        raise ValueError("concentrations and speeds must be non-empty 1-D sequences")
    shape = (cs.size, vs.size)
    out = {
        k: np.empty(shape)
        for k in (
            "reynolds",
            "weber",
            "ohnesorge",
            "z_number",
            "deborah",
            "elastocapillary",
            "splash_parameter",
        )
    }
    cat = np.empty(shape, dtype=int)
    used_length = 2.0 * nozzle_radius_m if length_m is None else float(length_m)
    for i, c in enumerate(cs):
        fluid = naalg(float(c), table=table)
        for j, v in enumerate(vs):
            d = numbers(
                fluid, nozzle_radius_m=nozzle_radius_m, speed_m_s=float(v), length_m=length_m
            )
            for k, arr in out.items():
                arr[i, j] = getattr(d, k)
            cat[i, j] = CATEGORIES.index(d.category)
            used_length = d.length_m
    return RegimeMap(
        concentrations_pct=cs,
        speeds_m_s=vs,
        nozzle_radius_m=float(nozzle_radius_m),
        length_m=used_length,
        category=cat,
        printable=cat == CATEGORIES.index("printable"),
        table=table,
        **out,
    )
