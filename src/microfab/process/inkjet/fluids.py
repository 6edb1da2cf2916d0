"""Fluid properties for the inkjet jet model: Newtonian liquids and sodium alginate solutions.

A `Fluid` carries what a 1D Oldroyd-B / FENE-P jet model needs, in SI units: density,
surface tension, solvent and polymer viscosities, relaxation time and FENE-P extensibility.

Sodium alginate (NaAlg) in deionised water is the ink of seed 003 part 1
(``../shared/seeds/003_4915b267b12a78d4.txt``, Xu et al.): 0.15, 0.20, 0.25, 1, 1.5 and
2 % w/v through a 120 µm MicroFab orifice. The seed gives no fluid properties, so they live
in ``microfab/data/naalg.toml`` with a ``*_source`` string for every value. No measured values
of these solutions could be retrieved (see the file header): all entries are documented
assumptions, and the relaxation law is calibrated from the seed's two breakup times
(:mod:`microfab.machines.printhead.calibration`, ``microfab droplet calibrate``).

Interpolation between the table points (`naalg`)
------------------------------------------------
* zero-shear viscosity: power law (straight line in log-log) of the specific viscosity
  ``η_sp = η0/η_s - 1`` between neighbouring points, i.e.
  ``η_sp(c) = η_sp,i · (c/c_i)^k_i`` with ``k_i = ln(η_sp,i+1/η_sp,i) / ln(c_i+1/c_i)``;
* below the first point (0.15 %): dilute (Huggins) limit ``η_sp ∝ c``, so ``η0 → η_s`` at
  ``c = 0``;
* density and surface tension: linear in c between points, and linear to pure water
  (c = 0) below the first point;
* polymer viscosity ``η_p = s_p · (η0 - η_w)`` with ``s_p`` the law's ``polymer_share`` (1 when
  the table gives none): the elastic share of what the polymer adds to water's viscosity; the
  rest (its fast modes) acts as Newtonian solvent, ``η_s = η0 - η_p``;
* relaxation time ``λ(c) = λ_ref · (c/c_ref)^exponent`` from the ``[relaxation]`` table.

Exactly at a table point the tabulated density and surface tension are returned unchanged,
and ``η_s + η_p`` reproduces the tabulated η0 to within one floating-point rounding (an exact
split is not always representable).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from microfab.core.validate import (
    check_finite,
    check_in_range,
    check_nonnegative,
    check_positive,
)
from microfab.data import read_text as read_data_text

__all__ = [
    "DEFAULT_JET_MODEL",
    "SEED_CONCENTRATIONS_PCT",
    "WATER",
    "Fluid",
    "NaAlgTable",
    "RelaxationLaw",
    "fluid_table_rows",
    "load_table",
    "naalg",
    "newtonian",
    "split_viscosity",
]

#: NaAlg concentrations (% w/v) printed in seed 003 part 1 ("Materials").
SEED_CONCENTRATIONS_PCT: tuple[float, ...] = (0.15, 0.20, 0.25, 1.0, 1.5, 2.0)

_TABLE_FILE = "naalg.toml"

#: The jet model every command runs unless asked for another, and whose calibrated
#: relaxation law the table gives by default (re-exported by :mod:`.droplet`). The
#: Eulerian model (meniscus in the bore) is closer to the seed and faster.
DEFAULT_JET_MODEL = "eulerian"


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


@dataclass(frozen=True, kw_only=True)
class RelaxationLaw:
    """A relaxation law ``λ(c) = lambda_ref_s · (c/reference_pct)^exponent``.

    A calibrated law belongs to the jet model it was calibrated with: the two models
    of :mod:`.droplet` reach the seed's breakup times with different relaxation times.

    Attributes
    ----------
    lambda_ref_s : float
        λ at the reference concentration, s.
    reference_pct : float
        Reference concentration, % w/v.
    exponent : float
        Power of the concentration.
    status, note : str
        ``"calibrated"`` or ``"uncalibrated"``, and how it was obtained.
    polymer_share : float
        Share of the polymer's added viscosity ``η0 - η_w`` that relaxes with λ (the rest
        acts as Newtonian solvent), in (0, 1]; 1 when the table gives none.
    """

    lambda_ref_s: float
    reference_pct: float
    exponent: float
    status: str
    note: str = ""
    polymer_share: float = 1.0

    def time_s(self, concentration_pct: float) -> float:
        """λ at ``concentration_pct`` (% w/v, >= 0), s."""
        check_nonnegative("NaAlg concentration", concentration_pct, "% w/v")
        return float(self.lambda_ref_s * (concentration_pct / self.reference_pct) ** self.exponent)


@dataclass(frozen=True, kw_only=True, eq=False)
class NaAlgTable:
    """The NaAlg property table of ``data/naalg.toml`` (read-only arrays, SI units).

    Attributes
    ----------
    concentration_pct, density_kg_m3, surface_tension_n_m, zero_shear_viscosity_pa_s : ndarray
        One value per table point, concentrations strictly increasing.
    solvent_viscosity_pa_s, solvent_density_kg_m3, solvent_surface_tension_n_m : float
        Pure water (the c = 0 end of the interpolation).
    extensibility_l2 : float
        FENE-P L² used for every concentration.
    lambda_ref_s, reference_pct, exponent : float
        Relaxation law ``λ(c) = lambda_ref_s · (c/reference_pct)^exponent`` of the
        Lagrangian jet model (``[relaxation]``).
    relaxation_status, relaxation_note : str
        ``"uncalibrated"`` or ``"calibrated"``, and the note of the ``[relaxation]`` table.
    lambda_ref_bounds_s, exponent_bounds : tuple of float
        Plausible (low, high) ranges for a calibration of the relaxation law.
    sources : tuple of dict
        Per table point, ``{"density": ..., "surface_tension": ..., "zero_shear_viscosity":
        ...}`` source strings.
    global_sources : dict
        Source strings of the solvent properties and of ``extensibility_l2``.
    model_laws : dict
        Relaxation laws of other jet models by name (``[relaxation_<model>]`` tables,
        e.g. ``"eulerian"``).
    back_pressure_pa, back_pressure_source : float, str
        Static back pressure of the reservoir over ambient, Pa, and its source (the
        optional ``[jetting]`` table; 0 without it): what the seed's pneumatic controller
        sets (:func:`microfab.process.inkjet.droplet.simulate_droplet`).
    """

    concentration_pct: NDArray[np.float64]
    density_kg_m3: NDArray[np.float64]
    surface_tension_n_m: NDArray[np.float64]
    zero_shear_viscosity_pa_s: NDArray[np.float64]
    solvent_viscosity_pa_s: float
    solvent_density_kg_m3: float
    solvent_surface_tension_n_m: float
    extensibility_l2: float
    lambda_ref_s: float
    reference_pct: float
    exponent: float
    relaxation_status: str
    relaxation_note: str
    lambda_ref_bounds_s: tuple[float, float]
    exponent_bounds: tuple[float, float]
    sources: tuple[dict[str, str], ...] = field(default=())
    global_sources: dict[str, str] = field(default_factory=dict)
    model_laws: dict[str, RelaxationLaw] = field(default_factory=dict)
    back_pressure_pa: float = 0.0
    back_pressure_source: str = ""

    def law(self, model: str = DEFAULT_JET_MODEL) -> RelaxationLaw:
        """The relaxation law calibrated with jet model ``model``.

        Raises
        ------
        ValueError
            If the table holds no law for that model.
        """
        if model == "lagrangian":
            return RelaxationLaw(
                lambda_ref_s=self.lambda_ref_s,
                reference_pct=self.reference_pct,
                exponent=self.exponent,
                status=self.relaxation_status,
                note=self.relaxation_note,
            )
        if model not in self.model_laws:
            have = ", ".join(["lagrangian", *self.model_laws])
            raise ValueError(
                f"the NaAlg table has no relaxation law for the {model!r} jet model (it has: "
                f"{have}); calibrate one with microfab droplet calibrate --model {model} --write"
            )
        return self.model_laws[model]

    @property
    def max_concentration_pct(self) -> float:
        """Highest tabulated concentration, % w/v."""
        return float(self.concentration_pct[-1])

    @property
    def specific_viscosity(self) -> NDArray[np.float64]:
        """Specific viscosity η_sp = η0/η_s - 1 at the table points."""
        return self.zero_shear_viscosity_pa_s / self.solvent_viscosity_pa_s - 1.0

    def relaxation_time_s(self, concentration_pct: float, model: str = DEFAULT_JET_MODEL) -> float:
        """Relaxation time λ(c) = lambda_ref_s · (c/reference_pct)^exponent, s.

        Parameters
        ----------
        concentration_pct : float
            Concentration, % w/v (>= 0).
        model : str, optional
            Jet model whose calibrated law to use (`law`).

        Returns
        -------
        float
            λ in s (0 at c = 0 when ``exponent > 0``).

        Examples
        --------
        >>> t = load_table()
        >>> law = t.law()  # the default jet model's (`DEFAULT_JET_MODEL`)
        >>> t.relaxation_time_s(law.reference_pct) == law.lambda_ref_s
        True
        >>> t.relaxation_time_s(t.reference_pct, model="lagrangian") == t.lambda_ref_s
        True
        """
        return self.law(model).time_s(concentration_pct)


def _frozen(values: list[float]) -> NDArray[np.float64]:
    arr = np.asarray(values, dtype=float)
    arr.setflags(write=False)
    return arr


def _bounds(raw: Any, name: str) -> tuple[float, float]:
    lo, hi = (float(v) for v in raw)
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"relaxation bounds for {name} must be finite with low < high: {raw}")
    return lo, hi


def _parse_table(data: Mapping[str, Any], origin: str) -> NaAlgTable:
    try:
        rows = sorted(data["solution"], key=lambda r: float(r["concentration_pct"]))
        c = _frozen([float(r["concentration_pct"]) for r in rows])
        rho = _frozen([float(r["density_kg_m3"]) for r in rows])
        sig = _frozen([float(r["surface_tension_n_m"]) for r in rows])
        eta = _frozen([float(r["zero_shear_viscosity_pa_s"]) for r in rows])
        sources = tuple(
            {
                "density": str(r["density_source"]),
                "surface_tension": str(r["surface_tension_source"]),
                "zero_shear_viscosity": str(r["zero_shear_viscosity_source"]),
            }
            for r in rows
        )
        rel = data["relaxation"]
        bounds = rel["bounds"]
        table = NaAlgTable(
            concentration_pct=c,
            density_kg_m3=rho,
            surface_tension_n_m=sig,
            zero_shear_viscosity_pa_s=eta,
            solvent_viscosity_pa_s=float(data["solvent_viscosity_pa_s"]),
            solvent_density_kg_m3=float(data["solvent_density_kg_m3"]),
            solvent_surface_tension_n_m=float(data["solvent_surface_tension_n_m"]),
            extensibility_l2=float(data["extensibility_l2"]),
            lambda_ref_s=float(rel["lambda_ref_s"]),
            reference_pct=float(rel["reference_pct"]),
            exponent=float(rel["exponent"]),
            relaxation_status=str(rel["status"]),
            relaxation_note=str(rel.get("note", "")),
            lambda_ref_bounds_s=_bounds(bounds["lambda_ref_s"], "lambda_ref_s"),
            exponent_bounds=_bounds(bounds["exponent"], "exponent"),
            sources=sources,
            global_sources={
                "solvent_viscosity": str(data.get("solvent_viscosity_source", "")),
                "solvent_density": str(data.get("solvent_density_source", "")),
                "solvent_surface_tension": str(data.get("solvent_surface_tension_source", "")),
                "extensibility_l2": str(data.get("extensibility_l2_source", "")),
            },
        )
        laws = {}
        for key, raw in data.items():
            if key.startswith("relaxation_") and isinstance(raw, Mapping):
                laws[key.removeprefix("relaxation_")] = RelaxationLaw(
                    lambda_ref_s=float(raw["lambda_ref_s"]),
                    reference_pct=float(raw["reference_pct"]),
                    exponent=float(raw["exponent"]),
                    status=str(raw["status"]),
                    note=str(raw.get("note", "")),
                    polymer_share=float(raw.get("polymer_share", 1.0)),
                )
        jetting = data.get("jetting", {})
        table = dataclasses.replace(
            table,
            model_laws=laws,
            back_pressure_pa=float(jetting.get("back_pressure_pa", 0.0)),
            back_pressure_source=str(jetting.get("back_pressure_pa_source", "")),
        )
    except (KeyError, TypeError) as exc:
        raise ValueError(f"{origin}: malformed NaAlg table ({exc!r})") from exc
    for name, law in table.model_laws.items():
        check_positive(f"{origin}: [relaxation_{name}] reference concentration",
                       law.reference_pct, "% w/v")  # fmt: skip
        check_positive(f"{origin}: [relaxation_{name}] λ_ref", law.lambda_ref_s, "s")
        check_finite(f"{origin}: [relaxation_{name}] exponent", law.exponent)
        check_in_range(f"{origin}: [relaxation_{name}] polymer_share", law.polymer_share,
                       0.0, 1.0, low_closed=False)  # fmt: skip

    if c.size < 1 or c[0] <= 0.0 or np.any(np.diff(c) <= 0.0):
        raise ValueError(f"{origin}: concentrations must be positive and distinct: {list(c)}")
    for name, arr, unit in (
        ("density", rho, "kg/m³"),
        ("surface tension", sig, "N/m"),
        ("zero-shear viscosity", eta, "Pa·s"),
    ):
        for ci, v in zip(c, arr, strict=True):
            check_positive(f"{origin}: {name} at {ci} % w/v", v, unit)
    # Fluid validation of the solvent and of L² (raises with quantity, value and unit).
    newtonian(
        "solvent",
        table.solvent_density_kg_m3,
        table.solvent_surface_tension_n_m,
        table.solvent_viscosity_pa_s,
    ).with_(extensibility_l2=table.extensibility_l2)
    if np.any(eta <= table.solvent_viscosity_pa_s):
        raise ValueError(f"{origin}: every zero-shear viscosity must exceed the solvent's")
    check_positive("reference concentration", table.reference_pct, "% w/v")
    check_positive("reference relaxation time", table.lambda_ref_s, "s")
    check_finite(f"{origin}: relaxation exponent", table.exponent)
    check_finite(f"{origin}: [jetting] back_pressure_pa", table.back_pressure_pa)
    return table


def load_table(path: str | os.PathLike[str] | None = None) -> NaAlgTable:
    """Read the NaAlg property table.

    Parameters
    ----------
    path : str or os.PathLike, optional
        A TOML file with the layout of ``microfab/data/naalg.toml``; default: that package
        file.

    Returns
    -------
    NaAlgTable
        The validated table.

    Raises
    ------
    ValueError
        If the file is not valid TOML or its content is incomplete or out of range.

    Examples
    --------
    >>> t = load_table()
    >>> [float(c) for c in t.concentration_pct]
    [0.15, 0.2, 0.25, 1.0, 1.5, 2.0]
    >>> t.relaxation_status
    'calibrated'
    """
    if path is None:
        text = read_data_text(_TABLE_FILE)
        origin = f"microfab/data/{_TABLE_FILE}"
    else:
        text = Path(path).read_text(encoding="utf-8")
        origin = str(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{origin}: not valid TOML ({exc})") from exc
    return _parse_table(data, origin)


@functools.lru_cache(maxsize=1)
def _default_table() -> NaAlgTable:
    return load_table()


def _interp_specific_viscosity(table: NaAlgTable, c: float) -> float:
    """η_sp(c): linear below the first point, power law between points."""
    cs = table.concentration_pct
    sp = table.specific_viscosity
    if c <= cs[0]:
        return float(sp[0] * c / cs[0])
    i = int(np.searchsorted(cs, c, side="left")) - 1  # cs[i] < c <= cs[i+1]
    k = math.log(sp[i + 1] / sp[i]) / math.log(cs[i + 1] / cs[i])
    return float(sp[i] * (c / cs[i]) ** k)


def _polymer_part(eta0: float, eta_s: float) -> float:
    """η_p = η0 - η_s, nudged by ulps so that ``eta_s + η_p == eta0`` holds exactly."""
    p = max(eta0 - eta_s, 0.0)
    for _ in range(8):
        total = eta_s + p
        if total == eta0 or p == 0.0:
            break
        p = math.nextafter(p, math.inf if total < eta0 else -math.inf)
    return p


def split_viscosity(eta0: float, eta_w: float, share: float) -> tuple[float, float]:
    """``(η_s, η_p)`` of a polymer solution of zero-shear viscosity ``eta0`` in a solvent.

    The polymer adds ``η0 - η_w``; its share ``share`` relaxes (``η_p``), the rest, its
    fast modes, acts as solvent: ``η_s = η_w + (1 - share) (η0 - η_w)``, ``η_p = η0 - η_s``
    (so ``η_s + η_p == η0`` exactly, `_polymer_part`). Viscosities in Pa·s.
    """
    eta_s = eta_w if share >= 1.0 else eta_w + (1.0 - share) * (eta0 - eta_w)
    return eta_s, _polymer_part(eta0, eta_s)


def naalg(
    concentration_pct: float,
    *,
    relaxation_time_s: float | None = None,
    table: NaAlgTable | None = None,
    model: str = DEFAULT_JET_MODEL,
    polymer_share: float | None = None,
) -> Fluid:
    """Sodium alginate in deionised water at 25 °C, at any concentration of the table range.

    Parameters
    ----------
    concentration_pct : float
        Concentration, % w/v, between 0 and the highest table point (2 %).
    relaxation_time_s : float, optional
        Override the table's relaxation law λ(c) (e.g. during a calibration).
    table : NaAlgTable, optional
        Property table; default: ``load_table()`` (package data, read once).
    model : str, optional
        Jet model whose calibrated relaxation law to use (`NaAlgTable.law`): "eulerian"
        (default, `DEFAULT_JET_MODEL`) or "lagrangian".
    polymer_share : float, optional
        Override the law's share of ``η0 - η_w`` that is elastic (in (0, 1]; a calibration).

    Returns
    -------
    Fluid
        Named ``"NaAlg <c> % w/v"``; at c = 0 pure water (η_p = 0, λ = 0).

    Raises
    ------
    ValueError
        If the concentration is NaN, negative or above the table.

    Notes
    -----
    Interpolation laws (see the module docstring): power law of η_sp between neighbouring
    points, ``η_sp ∝ c`` below the first point, density and surface tension linear in c
    (to water at c = 0), ``η_p = η0 - η_s``, and ``λ = lambda_ref·(c/reference_pct)^exponent``.
    Exactly at a table point the tabulated values are returned (η0 = η_s + η_p to within
    one floating-point rounding).

    Examples
    --------
    >>> f = naalg(1.0)
    >>> f.zero_shear_viscosity_pa_s, f.density_kg_m3
    (0.02, 1001.05)
    >>> naalg(0.5).zero_shear_viscosity_pa_s > naalg(0.25).zero_shear_viscosity_pa_s
    True
    """
    t = _default_table() if table is None else table
    c = float(concentration_pct)
    cmax = t.max_concentration_pct
    if not (math.isfinite(c) and 0.0 <= c <= cmax):
        raise ValueError(
            f"NaAlg concentration {concentration_pct} % w/v is outside the table "
            f"(0 to {cmax:g} % w/v)"
        )
    eta_s = t.solvent_viscosity_pa_s
    hit = np.flatnonzero(t.concentration_pct == c)
    if hit.size:
        i = int(hit[0])
        rho = float(t.density_kg_m3[i])
        sigma = float(t.surface_tension_n_m[i])
        eta0 = float(t.zero_shear_viscosity_pa_s[i])
    else:
        cs = np.concatenate(([0.0], t.concentration_pct))
        rho = float(np.interp(c, cs, np.concatenate(([t.solvent_density_kg_m3], t.density_kg_m3))))
        sigma = float(
            np.interp(
                c, cs, np.concatenate(([t.solvent_surface_tension_n_m], t.surface_tension_n_m))
            )
        )
        eta0 = eta_s * (1.0 + _interp_specific_viscosity(t, c))
    if relaxation_time_s is not None:
        lam = float(relaxation_time_s)
    elif c == 0.0:
        lam = 0.0
    else:
        lam = t.relaxation_time_s(c, model)
    if polymer_share is None:
        known = model == "lagrangian" or model in t.model_laws
        share = t.law(model).polymer_share if known else 1.0
    else:
        share = float(polymer_share)
        check_in_range("polymer_share", share, 0.0, 1.0, low_closed=False)
    eta_s, eta_p = split_viscosity(eta0, eta_s, share)
    return Fluid(
        name=f"NaAlg {c:g} % w/v",
        density_kg_m3=rho,
        surface_tension_n_m=sigma,
        solvent_viscosity_pa_s=eta_s,
        polymer_viscosity_pa_s=eta_p,
        relaxation_time_s=lam,
        extensibility_l2=t.extensibility_l2,
        concentration_pct=c,
    )


def fluid_table_rows(table: NaAlgTable | None = None) -> list[dict[str, Any]]:
    """Rows of the NaAlg property table for a report (one per table point).

    Parameters
    ----------
    table : NaAlgTable, optional
        Default: the package table.

    Returns
    -------
    list of dict
        Keys ``concentration_pct``, ``density_kg_m3``, ``surface_tension_n_m``,
        ``zero_shear_viscosity_pa_s``, ``polymer_viscosity_pa_s``, ``relaxation_time_s``,
        ``extensibility_l2``, ``relaxation_status``, ``density_source``,
        ``surface_tension_source``, ``viscosity_source``, ``relaxation_source`` and
        ``extensibility_source``.

    Examples
    --------
    >>> rows = fluid_table_rows()
    >>> len(rows), rows[3]["concentration_pct"], rows[3]["zero_shear_viscosity_pa_s"]
    (6, 1.0, 0.02)
    """
    t = _default_table() if table is None else table
    rel_src = (
        f"{t.relaxation_status}: λ = {t.lambda_ref_s:g} s · (c/{t.reference_pct:g} %)"
        f"^{t.exponent:g}; {t.relaxation_note}"
    )
    rows = []
    for i, c in enumerate(t.concentration_pct):
        f = naalg(float(c), table=t)
        src = t.sources[i] if i < len(t.sources) else {}
        rows.append(
            {
                "concentration_pct": float(c),
                "density_kg_m3": f.density_kg_m3,
                "surface_tension_n_m": f.surface_tension_n_m,
                "zero_shear_viscosity_pa_s": f.zero_shear_viscosity_pa_s,
                "polymer_viscosity_pa_s": f.polymer_viscosity_pa_s,
                "relaxation_time_s": f.relaxation_time_s,
                "extensibility_l2": f.extensibility_l2,
                "relaxation_status": t.relaxation_status,
                "density_source": src.get("density", ""),
                "surface_tension_source": src.get("surface_tension", ""),
                "viscosity_source": src.get("zero_shear_viscosity", ""),
                "relaxation_source": rel_src,
                "extensibility_source": t.global_sources.get("extensibility_l2", ""),
            }
        )
    return rows
