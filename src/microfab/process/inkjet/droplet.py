"""From drive voltage to droplet: waveform → printhead acoustics → slender-jet breakup.

The pipeline of seed 003 part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``): the
waveform (:mod:`microfab.trajectory.waveform`) drives the dispenser's acoustic model
(:mod:`microfab.plants.printhead`, calibrated in :mod:`.dispenser`), whose orifice
velocity pushes liquid into the one-dimensional jet model (:mod:`.jet`), scaled by the
nozzle radius and the capillary time. The jet is followed through its first breakup
(time, position, mode) and for a while after it, long enough to count satellites.

With the Lagrangian model, and the Eulerian one with its meniscus held at the rim, the
coupling is one way: the jet outside does not load the acoustics, and the jet is fed only
by outflow beyond everything pushed out before (:func:`jet_inflow`); the retraction of
the meniscus into the bore is left to the acoustic model. With the Eulerian model's
default, the retracting meniscus, it is two way: the meniscus moves into the bore and
the acoustics feel the jet (:func:`coupled_upstream`).

The capillary scales and what feeds the jet (the one-way inflow, the coupled upstream
model) are in :mod:`.droplet_inflow`, re-exported here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from microfab.core.validate import check_positive
from microfab.plants.printhead import NozzleFlow, Printhead
from microfab.process.inkjet.breakup import BreakupMode
from microfab.process.inkjet.dimensionless import Dimensionless, numbers
from microfab.process.inkjet.dispenser import default_printhead
from microfab.process.inkjet.droplet_inflow import COUPLED_DT_S as COUPLED_DT_S
from microfab.process.inkjet.droplet_inflow import (
    FLOW_RECORD_S,
    Scales,
    _coupled_flow,
    _one_way_flow,
    _ScaledInflow,
    coupled_upstream,
    jet_inflow,
)
from microfab.process.inkjet.fluids import DEFAULT_JET_MODEL as _DEFAULT_MODEL
from microfab.process.inkjet.fluids import Fluid
from microfab.process.inkjet.head_tail import HeadTail, Thinning, head_and_tail, thinning_rate
from microfab.process.inkjet.jet import Body, JetRun, Numerics, run_jet
from microfab.process.inkjet.jet_euler import (
    MENISCUS_KINDS,
    EulerNumerics,
    MeniscusKind,
    run_jet_euler,
)
from microfab.process.inkjet.jet_euler_meniscus import static_meniscus
from microfab.process.inkjet.silhouette import Silhouette
from microfab.trajectory.waveform import Waveform, seed003_waveform

__all__ = [
    "BREAKUP_RADIUS_M",
    "DEFAULT_JET_MODEL",
    "DOD_NUMERICS",
    "EULER_DOD_NUMERICS",
    "FLOW_RECORD_S",
    "JET_MODELS",
    "DropletResult",
    "JetModelKind",
    "Scales",
    "coupled_upstream",
    "jet_inflow",
    "simulate_droplet",
]

#: A neck counts as broken below this radius: half a pixel of the 2 µm/pixel camera
#: assumed in :mod:`microfab.measure.shadowgraph` (assumption; the seed measured breakup "from the
#: captured pictures", so a gap is what the camera can resolve).
BREAKUP_RADIUS_M = 1.0e-6


#: Solver settings for drop-on-demand runs: coarser cells than the verification defaults
#: (a cell per 0.8 local radii), a tighter time tolerance and a grid cap. The 1 % NaAlg
#: breakup time at 50 V is 233.5, 233.0 and 224.4 µs at rtol 1e-3, 5e-4 and 2e-3, and a
#: spurious 115 µs at 5e-3; 1e-3 is converged to 0.2 % and no slower than 2e-3.
DOD_NUMERICS = Numerics(resolution=0.8, rtol=1e-3, max_nodes=4000)

#: The two jet models of :func:`simulate_droplet`.
JetModelKind = Literal["lagrangian", "eulerian"]
JET_MODELS: tuple[JetModelKind, ...] = ("lagrangian", "eulerian")
#: The jet model every command runs unless asked for another (one place for the default,
#: kept in :mod:`.fluids` so that the table's default law follows it).
DEFAULT_JET_MODEL: JetModelKind = _DEFAULT_MODEL  # type: ignore[assignment]


#: Settings of the Eulerian model for drop-on-demand runs: its documented defaults (25
#: cells per nozzle radius over 30 radii; the 0.15 % and 1 % NaAlg breakups move by 2.7 and
#: 1.6 µs on a grid twice as fine).
EULER_DOD_NUMERICS = EulerNumerics()


@dataclass(frozen=True, kw_only=True)
class DropletResult:
    """What a drop-on-demand simulation predicts.

    Attributes
    ----------
    fluid, waveform, printhead : Fluid, Waveform, Printhead
        Inputs.
    flow : NozzleFlow
        Orifice velocity from the acoustic model.
    breakup_time_s : float or None
        First pinch-off, from the start of the drive pulse (None: no breakup).
    breakup_mode : {"front", "exit", "middle"} or None
        Where the first pinch-off happened (:func:`.breakup.classify_pinch`).
    breakup_z_m : float or None
        Its distance from the nozzle exit.
    jet_length_m : float or None
        Nozzle exit to head tip at the first breakup.
    satellites : int
        Detached bodies other than the head drop at the end of the run.
    head_speed_m_s : float
        Mean speed of the leading tip from the first breakup (or its last 30 µs before) to
        the end of the run.
    drop_volume_m3 : float
        Volume of the leading body at the end.
    outcome : str
        "breakup", "no breakup within the simulated time" (a jet still out at the end),
        "drawn back without breakup" (a jet longer than the nozzle radius came out and was
        drawn back), "no ejection" or "solver stopped early (reason), no breakup before"
        (step or grid limit, collapsed step).
    silhouettes : tuple of Silhouette
        Snapshots for images and figures.
    scales : Scales
        Units of the dimensionless run.
    run : JetRun
        The dimensionless solver output (history, events, statistics).
    numbers : Dimensionless
        Oh, We, Re, De, Ec, Z at the head speed (or the peak orifice speed if none).
    head_tail : HeadTail or None
        Head and tail in the last stored silhouette before the first breakup (the frame a
        camera would show last before it; :mod:`.head_tail`); None without breakup.
    thinning : Thinning or None
        Ligament thinning over the 40 µs of silhouettes before the first breakup.
    model : {"lagrangian", "eulerian"}
        The jet model that ran.
    meniscus : {"pinned", "retracting"}
        How the meniscus behaved: held at the rim with the acoustics' own lumped meniscus
        (the Lagrangian model, and the Eulerian one when asked), or retracting into the
        bore with the acoustics coupled both ways (the Eulerian default).
    """

    fluid: Fluid
    waveform: Waveform
    printhead: Printhead
    flow: NozzleFlow
    breakup_time_s: float | None
    breakup_mode: BreakupMode | None
    breakup_z_m: float | None
    jet_length_m: float | None
    satellites: int
    head_speed_m_s: float
    drop_volume_m3: float
    outcome: str
    silhouettes: tuple[Silhouette, ...]
    scales: Scales
    run: JetRun = field(repr=False)
    numbers: Dimensionless
    head_tail: HeadTail | None = None
    thinning: Thinning | None = None
    model: JetModelKind = DEFAULT_JET_MODEL
    meniscus: MeniscusKind = "pinned"

    @property
    def meniscus_trace(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Times (s) and meniscus centre positions (m, < 0 in the bore) per step, or None.

        None when the meniscus was held at the rim (the Lagrangian model, or
        ``meniscus="pinned"``).
        """
        z = self.run.meniscus_z
        if z is None:
            return None
        return self.run.t * self.scales.time_s, z * self.scales.length_m

    @property
    def meniscus_depth_m(self) -> float:
        """Deepest retraction of the meniscus centre into the bore over the run, m (>= 0)."""
        z = self.run.meniscus_z
        return 0.0 if z is None or z.size == 0 else float(-min(0.0, z.min())) * self.scales.length_m

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary; keys carry their units."""
        return {
            "jet_model": self.model,
            "meniscus": self.meniscus,
            "meniscus_max_depth_m": self.meniscus_depth_m,
            "breakup_time_s": self.breakup_time_s,
            "breakup_mode": self.breakup_mode,
            "breakup_z_m": self.breakup_z_m,
            "satellites": self.satellites,
            "head_speed_m_s": self.head_speed_m_s,
            "drop_volume_m3": self.drop_volume_m3,
            "drop_diameter_m": (6.0 * self.drop_volume_m3 / math.pi) ** (1.0 / 3.0),
            "jet_length_at_breakup_m": self.jet_length_m,
            "head_radius_m": None if self.head_tail is None else self.head_tail.head_radius_m,
            "tail_length_at_breakup_m": (
                None if self.head_tail is None else self.head_tail.tail_length_m
            ),
            "distinct_head": None if self.head_tail is None else self.head_tail.distinct_head,
            "ligament_thinning_m_s": None if self.thinning is None else self.thinning.speed_m_s,
            "ligament_thinning_rate_per_s": (
                None if self.thinning is None else self.thinning.rate_per_s
            ),
            "outcome": self.outcome,
            "fluid": self.fluid.name,
            "concentration_pct": self.fluid.concentration_pct,
            "voltage_v": self.waveform.amplitude_v,
            "waveform": self.waveform.kind,
            "peak_orifice_velocity_m_s": self.flow.peak_velocity_m_s,
            "ohnesorge": self.numbers.ohnesorge,
            "weber": self.numbers.weber,
            "reynolds": self.numbers.reynolds,
            "deborah": self.numbers.deborah,
            "elastocapillary": self.numbers.elastocapillary,
            "z_number": self.numbers.z_number,
            "solver_steps": self.run.steps,
            "solver_rejected_steps": self.run.rejected,
            "solver_stop_reason": self.run.stop_reason,
        }


def simulate_droplet(
    fluid: Fluid,
    waveform: Waveform | None = None,
    *,
    printhead: Printhead | None = None,
    duration_s: float = 400e-6,
    after_breakup_s: float = 60e-6,
    frame_interval_s: float = 10e-6,
    breakup_radius_m: float = BREAKUP_RADIUS_M,
    numerics: Numerics | EulerNumerics | None = None,
    model: JetModelKind = DEFAULT_JET_MODEL,
    progress: Callable[[float], None] | None = None,
    meniscus: MeniscusKind | None = None,
    back_pressure_pa: float = 0.0,
) -> DropletResult:
    """Simulate one drop-on-demand ejection.

    Parameters
    ----------
    fluid : Fluid
        The ink (e.g. :func:`.fluids.naalg`).
    waveform : Waveform, optional
        Drive voltage (default: the seed's 50 V bipolar waveform).
    printhead : Printhead, optional
        Dispenser model (default: :func:`.dispenser.default_printhead`).
    duration_s : float, optional
        Longest simulated time from the start of the pulse.
    after_breakup_s : float, optional
        How long the bodies are followed after the first breakup (satellites).
    frame_interval_s : float, optional
        Spacing of the stored silhouettes, s. The Eulerian model lands its steps on them,
        which does not move its breakup (0.15 % NaAlg at 50 V: within 4 ns and 0.06 µm
        over 1 to 10 µs frames or none, measured).
    breakup_radius_m : float, optional
        Neck radius that counts as broken.
    numerics : Numerics or EulerNumerics, optional
        Solver settings of the chosen model (``h_break`` is set from ``breakup_radius_m``);
        default `DOD_NUMERICS` or `EULER_DOD_NUMERICS`.
    model : {"lagrangian", "eulerian"}, optional
        The jet model: the Lagrangian slender-jet solver (:mod:`.jet`, moving nodes,
        adaptive regridding, bodies split at each pinch) or the regularised Eulerian one
        (:mod:`.jet_euler`, fixed grid, TVD mass flux, a thin film through pinch-offs).
    progress : callable, optional
        Called with the simulated time in s as the run advances.
    meniscus : {"pinned", "retracting"}, optional
        Eulerian model only (default "retracting"): the meniscus retracts into the bore
        and the acoustics feel the jet (:func:`coupled_upstream`,
        :mod:`.jet_euler_meniscus`), or it is held at the rim and fed the part of the
        acoustic flow that leaves the nozzle (:func:`jet_inflow`), as in the Lagrangian
        model.
    back_pressure_pa : float, optional
        Static pressure of the liquid in the bore over ambient, Pa (default 0): the back
        pressure the seed's pneumatic controller sets on the reservoir "to obtain an ideal
        meniscus" (seed 003 part 1, "Method"; it gives no value). The meniscus starts at
        rest where its Laplace pressure balances it
        (:func:`.jet_euler_meniscus.static_meniscus`) and the coupled acoustics feel it
        throughout. Eulerian model with the retracting meniscus only; its magnitude must
        stay below the bore's Laplace pressure ``2 sigma / R``.

    Returns
    -------
    DropletResult

    Raises
    ------
    ValueError
        For non-positive durations, a breakup radius not below the nozzle radius, or a
        back pressure the meniscus cannot hold or the chosen model cannot take.

    Examples
    --------
    >>> from microfab.process.inkjet.fluids import naalg
    >>> res = simulate_droplet(naalg(0.15))  # doctest: +SKIP
    >>> res.breakup_mode  # doctest: +SKIP
    'front'
    """
    waveform = waveform or seed003_waveform(50.0)
    printhead = printhead or default_printhead()
    for name, value in (
        ("duration_s", duration_s),
        ("after_breakup_s", after_breakup_s),
        ("frame_interval_s", frame_interval_s),
    ):
        check_positive(name, value, "s")
    radius = printhead.nozzle_radius_m
    if not 0.0 < breakup_radius_m < radius:
        raise ValueError(
            f"breakup radius {breakup_radius_m} m must lie between 0 and the nozzle radius "
            f"{radius} m"
        )
    if model not in JET_MODELS:
        raise ValueError(f"model must be one of {', '.join(JET_MODELS)}, got {model!r}")
    if meniscus is not None and meniscus not in MENISCUS_KINDS:
        raise ValueError(f"meniscus must be one of {', '.join(MENISCUS_KINDS)}, got {meniscus!r}")
    if meniscus == "retracting" and model != "eulerian":
        raise ValueError("only the Eulerian jet model has a retracting meniscus (model='eulerian')")
    menisc: MeniscusKind = meniscus or ("retracting" if model == "eulerian" else "pinned")
    laplace_pa = 2.0 * fluid.surface_tension_n_m / radius
    if not (math.isfinite(back_pressure_pa) and abs(back_pressure_pa) < laplace_pa):
        raise ValueError(
            f"back pressure {back_pressure_pa} Pa must lie within ± the bore's Laplace pressure "
            f"2 sigma / R = {laplace_pa:.6g} Pa, or no meniscus holds the liquid"
        )
    if back_pressure_pa != 0.0 and menisc != "retracting":
        raise ValueError(
            "a back pressure needs the Eulerian model with its retracting meniscus (the "
            "acoustics coupled both ways)"
        )
    sc = Scales.of(fluid, radius)
    frames = np.arange(0.0, duration_s + 0.5 * frame_interval_s, frame_interval_s)
    common: dict[str, Any] = {
        "t_end": duration_s / sc.time_s,
        "on_pinch": "split",
        "snapshot_times": frames / sc.time_s,
        "after_first_pinch": after_breakup_s / sc.time_s,
        "progress": None if progress is None else (lambda t: progress(t * sc.time_s)),
    }
    if model == "lagrangian":
        if numerics is not None and not isinstance(numerics, Numerics):
            raise TypeError("the Lagrangian model takes jet.Numerics settings")
        nu = dataclasses.replace(numerics or DOD_NUMERICS, h_break=breakup_radius_m / radius)
        flow = _one_way_flow(printhead, fluid, waveform, duration_s)
        inflow = _ScaledInflow(jet_inflow(flow), sc)
        run = run_jet([], sc.model(fluid), nu, land_on_snapshots=False, inflow=inflow, **common)
    else:
        if numerics is not None and not isinstance(numerics, EulerNumerics):
            raise TypeError("the Eulerian model takes jet_euler.EulerNumerics settings")
        base = numerics or EULER_DOD_NUMERICS
        nu_e = dataclasses.replace(base, h_break=breakup_radius_m / radius)
        if menisc == "retracting":
            up = coupled_upstream(printhead, fluid, waveform, duration_s=duration_s)
            p_b = back_pressure_pa * radius / fluid.surface_tension_n_m  # in sigma / R
            run = run_jet_euler(
                sc.model(fluid),
                nu_e,
                upstream=up,
                meniscus=menisc,
                back_pressure=p_b,
                meniscus_z0=static_meniscus(p_b),
                **common,
            )
            flow = _coupled_flow(run, sc, radius)
        else:
            flow = _one_way_flow(printhead, fluid, waveform, duration_s)
            inflow = _ScaledInflow(jet_inflow(flow), sc)
            run = run_jet_euler(sc.model(fluid), nu_e, inflow=inflow, **common)
    return _summarise(fluid, waveform, printhead, flow, sc, run, model, menisc)


def _silhouette(t: float, bodies: Sequence[Body], sc: Scales) -> Silhouette:
    out = []
    for b in bodies:
        z, r = b.profile()
        out.append((z * sc.length_m, r * sc.length_m))
    return Silhouette(time_s=t * sc.time_s, bodies=tuple(out), nozzle_radius_m=sc.length_m)


def _summarise(
    fluid: Fluid,
    waveform: Waveform,
    printhead: Printhead,
    flow: NozzleFlow,
    sc: Scales,
    run: JetRun,
    model: JetModelKind = DEFAULT_JET_MODEL,
    meniscus: MeniscusKind = "pinned",
) -> DropletResult:
    t_s = run.t * sc.time_s
    tip_z = run.tip_z * sc.length_m
    first = run.events[0] if run.events else None
    bodies = run.bodies
    lead = max(bodies, key=lambda b: b.z[-1]) if bodies else None
    if first is not None:
        t_b = first.t * sc.time_s
        window = t_s >= t_b - 30e-6
        outcome = "breakup"
    else:
        window = t_s >= t_s[-1] - 30e-6
        out = bool(bodies) and lead is not None and lead.z[-1] > 1.0
        ejected = tip_z.size > 0 and float(np.max(tip_z)) > sc.length_m
        if out:
            outcome = "no breakup within the simulated time"
        elif ejected:
            outcome = "drawn back without breakup"
        else:
            outcome = "no ejection"
        if run.stop_reason != "end time reached":
            outcome = f"solver stopped early ({run.stop_reason}), no breakup before"
    moving = window & (tip_z > 0.0)
    if np.count_nonzero(moving) >= 2 and np.ptp(t_s[moving]) > 0:
        head_speed = float(np.polyfit(t_s[moving], tip_z[moving], 1)[0])
    else:
        head_speed = 0.0
    satellites = 0
    drop_volume = 0.0
    if lead is not None:
        drop_volume = math.pi * lead.volume * sc.length_m**3
        tiny = (BREAKUP_RADIUS_M / sc.length_m) ** 3
        # detached bodies out of the nozzle (one still in the bore is not seen, nor ejected)
        satellites = sum(
            1
            for b in bodies
            if b is not lead and b.left == "tip" and b.volume > tiny and b.z[-1] > 0.0
        )
    speed_for_numbers = head_speed if head_speed > 0 else flow.peak_velocity_m_s
    silhouettes = tuple(_silhouette(t, b, sc) for t, b in run.snapshots)
    head_tail = thinning = None
    if first is not None:
        t_b = first.t * sc.time_s
        before = [s for s in silhouettes if s.time_s < t_b and s.bodies]
        head_tail = head_and_tail(before[-1]) if before else None
        thinning = thinning_rate(silhouettes, t_b)
    return DropletResult(
        fluid=fluid,
        waveform=waveform,
        printhead=printhead,
        flow=flow,
        breakup_time_s=None if first is None else first.t * sc.time_s,
        breakup_mode=None if first is None else first.mode,
        breakup_z_m=None if first is None else first.z * sc.length_m,
        jet_length_m=None if first is None else (first.z_tip - first.z_tail) * sc.length_m,
        satellites=satellites,
        head_speed_m_s=head_speed,
        drop_volume_m3=drop_volume,
        outcome=outcome,
        silhouettes=silhouettes,
        scales=sc,
        run=run,
        numbers=numbers(
            fluid, nozzle_radius_m=printhead.nozzle_radius_m, speed_m_s=speed_for_numbers
        ),
        head_tail=head_tail,
        thinning=thinning,
        model=model,
        meniscus=meniscus,
    )
