"""The `Fluid` record: what the slender-jet models need to know of a liquid, in SI units.

A `Fluid` carries density, surface tension, solvent and polymer viscosities, relaxation
time and FENE-P extensibility (an Oldroyd-B or FENE-P polymer with one relaxation time);
`newtonian` builds a liquid without polymer and `WATER` is pure water at 25 °C. The NaAlg
property table (:mod:`.fluids_table`) and its interpolation laws (:mod:`.fluids`) build
on it, so it sits apart, below both; :mod:`.fluids` re-exports these names.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from microfab.core.validate import check_nonnegative, check_positive

__all__ = ["WATER", "Fluid", "newtonian"]


@dataclass(frozen=True, kw_only=True)
class Fluid:
    """A (visco-elastic) liquid for the jet model, SI units.

    The polymer contribution follows an Oldroyd-B model (``extensibility_l2 = inf``) or a
    FENE-P model (finite ``extensibility_l2``) with one relaxation time.

    Parameters
    ----------
    name : str
        Label used in reports.
    density_kg_m3 : float
        Density ρ, kg/m³ (> 0).
    surface_tension_n_m : float
        Liquid-air surface tension σ, N/m (> 0).
    solvent_viscosity_pa_s : float
        Solvent (Newtonian) viscosity η_s, Pa·s (> 0).
    polymer_viscosity_pa_s : float
        Polymer contribution η_p to the zero-shear viscosity, Pa·s (>= 0).
    relaxation_time_s : float
        Polymer relaxation time λ, s (>= 0; 0 means Newtonian).
    extensibility_l2 : float, optional
        FENE-P extensibility L² (> 3, dimensionless); ``math.inf`` (default) is Oldroyd-B.
    concentration_pct : float or None, optional
        Polymer concentration, % w/v, for bookkeeping (``None`` if not a solution).

    Raises
    ------
    ValueError
        If a property is out of range; the message names the quantity, value and unit.

    Examples
    --------
    >>> f = Fluid(name="ink", density_kg_m3=1000.0, surface_tension_n_m=0.07,
    ...           solvent_viscosity_pa_s=1e-3, polymer_viscosity_pa_s=4e-3,
    ...           relaxation_time_s=1e-4)
    >>> round(f.zero_shear_viscosity_pa_s, 6), round(f.polymer_modulus_pa, 3)
    (0.005, 40.0)
    >>> f.with_(relaxation_time_s=0.0).is_newtonian
    True
    """

    name: str
    density_kg_m3: float
    surface_tension_n_m: float
    solvent_viscosity_pa_s: float
    polymer_viscosity_pa_s: float
    relaxation_time_s: float
    extensibility_l2: float = math.inf
    concentration_pct: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"fluid name must be a non-empty string, got {self.name!r}")
        check_positive("density", self.density_kg_m3, "kg/m³")
        check_positive("surface tension", self.surface_tension_n_m, "N/m")
        check_positive("solvent viscosity", self.solvent_viscosity_pa_s, "Pa·s")
        check_nonnegative("polymer viscosity", self.polymer_viscosity_pa_s, "Pa·s")
        check_nonnegative("relaxation time", self.relaxation_time_s, "s")
        l2 = self.extensibility_l2
        if math.isnan(l2) or not l2 > 3.0:
            raise ValueError(
                f"FENE-P extensibility L² must be > 3 (the equilibrium trace) or inf, "
                f"got {l2!r} (dimensionless)"
            )
        c = self.concentration_pct
        if c is not None:
            check_nonnegative("concentration", c, "% w/v")

    @property
    def zero_shear_viscosity_pa_s(self) -> float:
        """Zero-shear viscosity η0 = η_s + η_p, Pa·s."""
        return self.solvent_viscosity_pa_s + self.polymer_viscosity_pa_s

    @property
    def is_newtonian(self) -> bool:
        """True if there is no polymer stress (η_p = 0 or λ = 0)."""
        return self.polymer_viscosity_pa_s == 0.0 or self.relaxation_time_s == 0.0

    @property
    def polymer_modulus_pa(self) -> float:
        """Polymer elastic modulus G = η_p/λ, Pa (0 for a Newtonian fluid)."""
        if self.is_newtonian:
            return 0.0
        return self.polymer_viscosity_pa_s / self.relaxation_time_s

    def with_(self, **changes: Any) -> Fluid:
        """Copy with some fields changed (validated again).

        Parameters
        ----------
        **changes
            Field names and their new values.

        Returns
        -------
        Fluid
            The modified copy.

        Examples
        --------
        >>> WATER.with_(name="warm water", solvent_viscosity_pa_s=0.65e-3).name
        'warm water'
        """
        return dataclasses.replace(self, **changes)


def newtonian(
    name: str, density_kg_m3: float, surface_tension_n_m: float, viscosity_pa_s: float
) -> Fluid:
    """A Newtonian liquid (no polymer, λ = 0).

    Parameters
    ----------
    name : str
        Label.
    density_kg_m3 : float
        Density, kg/m³.
    surface_tension_n_m : float
        Surface tension, N/m.
    viscosity_pa_s : float
        Dynamic viscosity, Pa·s.

    Returns
    -------
    Fluid
        With ``polymer_viscosity_pa_s = relaxation_time_s = 0``.

    Examples
    --------
    >>> glycerol = newtonian("glycerol 50 %", 1126.0, 0.068, 5.0e-3)
    >>> glycerol.is_newtonian, glycerol.zero_shear_viscosity_pa_s
    (True, 0.005)
    """
    return Fluid(
        name=name,
        density_kg_m3=density_kg_m3,
        surface_tension_n_m=surface_tension_n_m,
        solvent_viscosity_pa_s=viscosity_pa_s,
        polymer_viscosity_pa_s=0.0,
        relaxation_time_s=0.0,
    )


#: Pure water at 25 °C (standard handbook values: ρ = 997.05 kg/m³, σ = 71.97 mN/m,
#: η = 0.890 mPa·s); the same values are the solvent entries of ``data/naalg.toml``.
WATER = newtonian("water (25 °C)", 997.05, 0.07197, 0.89e-3)
