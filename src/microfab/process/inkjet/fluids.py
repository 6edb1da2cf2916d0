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

The `Fluid` record is in :mod:`.fluids_base` and the reading of the table in
:mod:`.fluids_table`; both are re-exported here.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from microfab.core.validate import check_in_range
from microfab.process.inkjet.fluids_base import WATER, Fluid, newtonian
from microfab.process.inkjet.fluids_table import _TABLE_FILE as _TABLE_FILE
from microfab.process.inkjet.fluids_table import (
    DEFAULT_JET_MODEL,
    NaAlgTable,
    RelaxationLaw,
    _default_table,
    load_table,
)
from microfab.process.inkjet.fluids_table import _bounds as _bounds
from microfab.process.inkjet.fluids_table import _frozen as _frozen
from microfab.process.inkjet.fluids_table import _parse_table as _parse_table

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
