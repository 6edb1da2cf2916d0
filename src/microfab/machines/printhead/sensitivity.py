"""How much the seed's breakup times hang on the fluid values that stay assumed.

Seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``) gives no fluid properties,
and no published measurement of this alginate at its six concentrations could be found
(``data/naalg.toml``, header). Every property of :func:`microfab.process.inkjet.fluids.naalg`
is therefore assumed or calibrated. This study changes one at a time by a factor around
its table value and reruns the 50 V drop (`microfab.machines.printhead.run_point`, the
one path every droplet command takes), so that the breakup time and mode can be read against each
assumption:

* zero-shear viscosity η0 (×0.5, ×2: the grade is unknown; the polymer part takes the
  change, the water stays);
* relaxation time λ (×0.5, ×2: calibrated on two times, and the exponent is only bounded
  below, ``naalg.toml``);
* surface tension σ (×0.85, ×1.05: from 61 mN/m, a surface-active grade, to water);
* density ρ (×0.99, ×1.01: a partial specific volume between 0.5 and 0.7 mL/g);
* FENE-P extensibility L² (×0.5, ×1.5: 50 to 150, the estimate's range).

Each run is one point of the project's sweep runner (:func:`microfab.io.sweep.run_sweep`),
saved atomically as it finishes, so an interrupted study resumes. The study serves
``microfab droplet sensitivity``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microfab.io.sweep import SweepResult, run_sweep
from microfab.machines.printhead.machine import (
    FIG4_VOLTAGE_V,
    DropletSettings,
    SweepPoint,
    run_point,
)
from microfab.process.inkjet.droplet import DEFAULT_JET_MODEL

if TYPE_CHECKING:
    from microfab.process.inkjet.fluids import Fluid

__all__ = [
    "FACTORS",
    "RADIUS_FACTORS",
    "ScalingRow",
    "SensitivityPoint",
    "markdown",
    "nozzle_scaling",
    "perturbed_fluid",
    "sensitivity_points",
    "sensitivity_study",
    "sensitivity_table",
]

#: Property -> factors tried (module docstring for why these).
FACTORS: dict[str, tuple[float, ...]] = {
    "zero_shear_viscosity": (0.5, 2.0),
    "relaxation_time": (0.5, 2.0),
    "surface_tension": (0.85, 1.05),
    "density": (0.99, 1.01),
    "extensibility_l2": (0.5, 1.5),
}


@dataclass(frozen=True)
class SensitivityPoint:
    """One run: concentration (% w/v), the property changed and its factor (1: none)."""

    concentration_pct: float
    prop: str
    factor: float

    def __post_init__(self) -> None:
        if self.prop not in (*FACTORS, "none"):
            raise ValueError(f"unknown property {self.prop!r}; choose one of {[*FACTORS]}")
        if not self.factor > 0.0:
            raise ValueError(f"factor must be > 0, got {self.factor}")


def perturbed_fluid(point: SensitivityPoint, model: str = DEFAULT_JET_MODEL) -> Any:
    """The NaAlg fluid of ``point`` with its one property scaled.

    ``model`` picks the relaxation law calibrated for that jet model.

    Returns
    -------
    microfab.process.inkjet.fluids.Fluid
    """
    from microfab.process.inkjet.fluids import load_table, naalg, split_viscosity

    base = naalg(point.concentration_pct, model=model)
    f = point.factor
    if point.prop == "none":
        return base
    if point.prop == "zero_shear_viscosity":
        # η0 scaled, water's share kept and the rest split between the relaxing polymer and
        # its fast modes as the law's polymer share splits it (fluids: η_p = s_p (η0 - η_w))
        eta_w = load_table().solvent_viscosity_pa_s
        eta0 = f * base.zero_shear_viscosity_pa_s
        if eta0 < eta_w:
            raise ValueError(
                f"η0 × {f} of {base.name} is below the water's viscosity; use a larger factor"
            )
        # the share the fluid was made with; pure water (no polymer) gives it all to η_p
        gap = base.zero_shear_viscosity_pa_s - eta_w
        share = base.polymer_viscosity_pa_s / gap if gap > 0.0 else 1.0
        eta_s, eta_p = split_viscosity(eta0, eta_w, share)
        return base.with_(solvent_viscosity_pa_s=eta_s, polymer_viscosity_pa_s=eta_p)
    field = {
        "relaxation_time": "relaxation_time_s",
        "surface_tension": "surface_tension_n_m",
        "density": "density_kg_m3",
        "extensibility_l2": "extensibility_l2",
    }[point.prop]
    return base.with_(**{field: f * getattr(base, field)})


def sensitivity_points(
    concentrations_pct: Sequence[float] = (0.15, 1.0, 2.0),
    props: Sequence[str] = tuple(FACTORS),
) -> list[SensitivityPoint]:
    """The unperturbed run and each one-at-a-time change, per concentration."""
    out: list[SensitivityPoint] = []
    for c in concentrations_pct:
        if not c > 0.0:
            raise ValueError(
                f"concentration {c} % w/v has no polymer to perturb; give concentrations > 0"
            )
        out.append(SensitivityPoint(float(c), "none", 1.0))
        for p in props:
            if p not in FACTORS:
                raise ValueError(f"unknown property {p!r}; choose from {[*FACTORS]}")
            out.extend(SensitivityPoint(float(c), p, float(f)) for f in FACTORS[p])
    return out


def _simulate(point: SensitivityPoint, settings: DropletSettings) -> dict[str, Any]:
    res = run_point(SweepPoint(point.concentration_pct, FIG4_VOLTAGE_V), settings,
                    fluid=perturbed_fluid(point, settings.model))  # fmt: skip
    return res.to_dict()


def sensitivity_study(
    points: Sequence[SensitivityPoint],
    *,
    settings: DropletSettings | None = None,
    results_dir: str | Path | None = None,
    progress: Callable[[int, int, SensitivityPoint, bool], None] | None = None,
    workers: int = 1,
    raise_on_failure: bool = True,
) -> SweepResult[SensitivityPoint]:
    """Run every point (saved and resumed in ``results_dir``).

    Parameters
    ----------
    points : sequence of SensitivityPoint
        :func:`sensitivity_points`.
    settings : DropletSettings, optional
        Simulated time, step budget and jet model shared by every point.
    results_dir : str or Path, optional
        Folder of the saved points.
    progress : callable, optional
        ``progress(done, total, point, ok)``.
    workers : int, optional
        Local Dask worker processes (1: in this process).
    raise_on_failure : bool, optional
        Raise `microfab.io.sweep.SweepError` if a point failed (default), or
        return the failures in the result.

    Returns
    -------
    SweepResult
    """
    settings = settings or DropletSettings()
    return run_sweep(
        functools.partial(_simulate, settings=settings),
        points,
        results_dir=results_dir,
        settings={**settings.to_dict(), "study": "sensitivity"},
        workers=workers,
        progress=progress,
        raise_on_failure=raise_on_failure,
    )


def sensitivity_table(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Breakup time and mode of each change beside its concentration's unperturbed run.

    Returns
    -------
    list of dict
        ``concentration_pct, prop, factor, breakup_time_us, mode, outcome,
        change_us`` (time minus the unperturbed one, None where either did not break).
    """
    base = {r["concentration_pct"]: r for r in rows if r["prop"] == "none"}
    out = []
    for r in rows:
        t = r["breakup_time_s"]
        b = base.get(r["concentration_pct"], {}).get("breakup_time_s")
        out.append({
            "concentration_pct": r["concentration_pct"],
            "prop": r["prop"],
            "factor": r["factor"],
            "breakup_time_us": None if t is None else 1e6 * t,
            "mode": r["breakup_mode"],
            "outcome": r["outcome"],
            "change_us": None if t is None or b is None else 1e6 * (t - b),
        })  # fmt: skip
    return out


def markdown(table: Sequence[dict[str, Any]]) -> str:
    """The table as Markdown (one row per run)."""
    lines = [
        "| c (%) | property | factor | breakup (µs) | mode | change (µs) | outcome |",
        "|---:|---|---:|---:|---|---:|---|",
    ]
    for r in table:
        t = "–" if r["breakup_time_us"] is None else f"{r['breakup_time_us']:.1f}"
        d = "–" if r["change_us"] is None else f"{r['change_us']:+.1f}"
        lines.append(f"| {r['concentration_pct']:g} | {r['prop']} | {r['factor']:g} | {t} | "
                     f"{r['mode'] or '–'} | {d} | {r['outcome']} |")  # fmt: skip
    return "\n".join(lines) + "\n"


#: Nozzle radii of the scaling check, relative to the seed's 60 µm (issue 46: ×0.7 / 1 / 1.4).
RADIUS_FACTORS = (0.7, 1.0, 1.4)


@dataclass(frozen=True)
class ScalingRow:
    """One nozzle radius of `nozzle_scaling`.

    Attributes
    ----------
    radius_m : float
        Orifice radius R, m.
    ohnesorge : float
        ``Oh = η / sqrt(ρ σ R)`` of the liquid at that radius.
    capillary_time_s : float
        ``sqrt(ρ R³ / σ)``, s.
    breakup_time_s : float or None
        First breakup, s (None: none within the run).
    breakup_z_m : float or None
        Its position from the orifice, m (< 0: inside the bore).
    """

    radius_m: float
    ohnesorge: float
    capillary_time_s: float
    breakup_time_s: float | None
    breakup_z_m: float | None

    @property
    def scaled_time(self) -> float:
        """``t_b / sqrt(ρ R³ / σ)`` (NaN without a breakup)."""
        if self.breakup_time_s is None:
            return math.nan
        return self.breakup_time_s / self.capillary_time_s


def nozzle_scaling(
    fluid: Fluid,
    *,
    factors: Sequence[float] = RADIUS_FACTORS,
    voltage_v: float = FIG4_VOLTAGE_V,
    settings: DropletSettings | None = None,
) -> list[ScalingRow]:
    """First breakup of ``fluid`` as the printhead's orifice radius is scaled.

    The known scaling of capillary breakup (Rayleigh; Eggers & Villermaux, Rep. Prog. Phys.
    71 (2008) 036601, §2): for a liquid of Oh < 0.1 the breakup time follows the inertial
    capillary time ``sqrt(ρ R³ / σ)``, so it rises with R. The same head (`machine.twin`,
    only ``nozzle_radius_m`` changed) is driven with the seed's bipolar waveform.

    Parameters
    ----------
    fluid : Fluid
        The liquid (e.g. `microfab.process.inkjet.fluids.WATER`).
    factors : sequence of float
        Radii relative to the twin's.
    voltage_v : float
        Drive amplitude, V.
    settings : DropletSettings, optional
        Simulated time and jet model (default: 400 µs, the default model).

    Returns
    -------
    list of ScalingRow
        One per factor, in order.
    """
    from microfab.machines.printhead.machine import twin
    from microfab.process.inkjet.droplet import simulate_droplet
    from microfab.trajectory.waveform import seed003_waveform

    s = settings or DropletSettings(after_breakup_s=2e-6)
    head = twin()
    rows = []
    for k in factors:
        ph = dataclasses.replace(head, nozzle_radius_m=head.nozzle_radius_m * float(k))
        r = simulate_droplet(
            fluid,
            seed003_waveform(voltage_v),
            printhead=ph,
            duration_s=s.duration_s,
            after_breakup_s=s.after_breakup_s,
            model=s.model,  # type: ignore[arg-type]
        )
        rad = ph.nozzle_radius_m
        rho, sig = fluid.density_kg_m3, fluid.surface_tension_n_m
        rows.append(
            ScalingRow(
                radius_m=rad,
                ohnesorge=fluid.zero_shear_viscosity_pa_s / math.sqrt(rho * sig * rad),
                capillary_time_s=math.sqrt(rho * rad**3 / sig),
                breakup_time_s=r.breakup_time_s,
                breakup_z_m=r.breakup_z_m,
            )
        )
    return rows
