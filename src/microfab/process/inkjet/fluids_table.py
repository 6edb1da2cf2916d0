"""The NaAlg property table of ``microfab/data/naalg.toml``: reading and validation.

The seed gives no fluid properties (seed 003 part 1), so they live in
``microfab/data/naalg.toml`` with a ``*_source`` string for every value. This module reads
that file (`load_table`; the package table once, `_default_table`) and checks it into a
`NaAlgTable`: the table points, the solvent, FENE-P ``L²`` and the relaxation laws
``λ(c) = lambda_ref_s · (c/reference_pct)^exponent`` per jet model (`RelaxationLaw`;
`DEFAULT_JET_MODEL` picks the default one). The interpolation between the table points is
in :mod:`.fluids` (`naalg`), which re-exports these names.
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
from microfab.process.inkjet.fluids_base import newtonian

__all__ = [
    "DEFAULT_JET_MODEL",
    "NaAlgTable",
    "RelaxationLaw",
    "load_table",
]

_TABLE_FILE = "naalg.toml"

#: The jet model every command runs unless asked for another, and whose calibrated
#: relaxation law the table gives by default (re-exported by :mod:`.droplet`). The
#: Eulerian model (meniscus in the bore) is closer to the seed and faster.
DEFAULT_JET_MODEL = "eulerian"


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
