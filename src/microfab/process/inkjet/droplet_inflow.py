"""What feeds the jet of a drop-on-demand run: the acoustics' flow in the jet's units.

The dispenser's acoustics (:mod:`microfab.plants.printhead`) push liquid into the
one-dimensional jet models of :func:`.droplet.simulate_droplet`, scaled by the nozzle
radius and the capillary time (`Scales`). One way (the Lagrangian model, and the Eulerian
one with a pinned meniscus): the orifice flow over one fixed record (`FLOW_RECORD_S`), of
which the jet is fed the outflow beyond everything pushed out before (`jet_inflow`). Two
ways (the Eulerian model's retracting meniscus): the acoustics without their lumped
meniscus as the jet's upstream model (`coupled_upstream`), and the nozzle flow they
produced, read back from the run. Apart from the driver and its result (:mod:`.droplet`),
which re-exports these names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microfab.plants.printhead import NozzleFlow, Printhead, nozzle_flow
from microfab.plants.printhead_coupled import discrete_acoustics, drive_slopes
from microfab.process.inkjet.fluids_base import Fluid
from microfab.process.inkjet.jet_bodies import JetModel, JetRun
from microfab.process.inkjet.jet_euler_upstream import Upstream
from microfab.trajectory.waveform import Waveform

__all__ = [
    "COUPLED_DT_S",
    "FLOW_RECORD_S",
    "Scales",
    "coupled_upstream",
    "jet_inflow",
]

#: The orifice flow is computed over one fixed record (or the run, if longer) and cut to
#: the run. Its FFT convolution rounds differently for different record lengths (about
#: 1e-15 m/s), and the jet solver's step control turns such a difference into another
#: step sequence and, near a breakup threshold, another outcome: a 300 µs and a 400 µs
#: run of 1.5 % NaAlg parted after 51 µs. With one record, a run is the prefix of any
#: longer run of the same point (tested).
FLOW_RECORD_S = 5.001e-3


@dataclass(frozen=True)
class Scales:
    """Units of the dimensionless jet model: nozzle radius and capillary time."""

    length_m: float
    time_s: float

    @classmethod
    def of(cls, fluid: Fluid, radius_m: float) -> Scales:
        """Capillary scales ``R`` and ``sqrt(rho R^3 / sigma)``."""
        t_c = math.sqrt(fluid.density_kg_m3 * radius_m**3 / fluid.surface_tension_n_m)
        return cls(length_m=radius_m, time_s=t_c)

    @property
    def velocity_m_s(self) -> float:
        """Velocity unit ``R / t_c``."""
        return self.length_m / self.time_s

    def model(self, fluid: Fluid) -> JetModel:
        """Dimensionless fluid parameters (Ohnesorge numbers, Deborah number, L²)."""
        visc = math.sqrt(fluid.density_kg_m3 * fluid.surface_tension_n_m * self.length_m)
        polymer = not fluid.is_newtonian
        # a fluid without relaxation time carries its polymer viscosity as plain viscosity
        solvent = fluid.solvent_viscosity_pa_s if polymer else fluid.zero_shear_viscosity_pa_s
        return JetModel(
            ohnesorge=solvent / visc,
            polymer_ohnesorge=fluid.polymer_viscosity_pa_s / visc if polymer else 0.0,
            deborah=fluid.relaxation_time_s / self.time_s if polymer else 0.0,
            extensibility_l2=fluid.extensibility_l2,
        )


@dataclass(frozen=True)
class _ScaledInflow:
    flow: NozzleFlow
    scales: Scales

    def velocity(self, t: float) -> float:
        return self.flow.at(t * self.scales.time_s)[0] / self.scales.velocity_m_s

    def displacement(self, t: float) -> float:
        return self.flow.at(t * self.scales.time_s)[1] / self.scales.length_m


def _one_way_flow(
    printhead: Printhead, fluid: Fluid, waveform: Waveform, duration_s: float
) -> NozzleFlow:
    """The acoustics' orifice flow with their own lumped meniscus, cut to the run.

    Computed over `FLOW_RECORD_S` (or the run, if longer) so that a run is the prefix of
    any longer run of the same point.
    """
    flow = nozzle_flow(
        printhead,
        waveform,
        density_kg_m3=fluid.density_kg_m3,
        viscosity_pa_s=fluid.zero_shear_viscosity_pa_s,
        surface_tension_n_m=fluid.surface_tension_n_m,
        duration_s=max(duration_s + 1e-6, FLOW_RECORD_S),
    )
    keep = int(np.searchsorted(flow.t_s, duration_s + 1e-6, side="right"))
    return NozzleFlow(
        t_s=flow.t_s[:keep],
        velocity_m_s=flow.velocity_m_s[:keep],
        displacement_m=flow.displacement_m[:keep],
        nozzle_radius_m=flow.nozzle_radius_m,
    )


#: Step of the coupled acoustics, s: the step of the one-way orifice flow (50 ns, which hits
#: every corner of the seed's waveform).
COUPLED_DT_S = 50e-9


def coupled_upstream(
    printhead: Printhead,
    fluid: Fluid,
    waveform: Waveform,
    *,
    duration_s: float,
    dt_s: float = COUPLED_DT_S,
) -> Upstream:
    """The dispenser's acoustics as the Eulerian jet's upstream model (dimensionless).

    The acoustics of :mod:`microfab.plants.printhead` without their lumped meniscus
    (:func:`microfab.plants.printhead_coupled.discrete_acoustics`), scaled to the jet's
    units (:class:`Scales`): the meniscus pressure in ``sigma / R`` goes in, the mean
    nozzle velocity in ``R / t_c`` comes out, at a step of ``dt_s``. The viscosity of the
    channel and nozzle friction is the zero-shear one (quasi-steady Poiseuille, as in the
    one-way model).

    Parameters
    ----------
    printhead : Printhead
        Dispenser model.
    fluid : Fluid
        The ink.
    waveform : Waveform
        Drive voltage.
    duration_s : float
        Simulated time from the start of the pulse, s (the drive's slopes are tabulated
        that far; after it the drive is held).
    dt_s : float, optional
        Step of the acoustics, s.

    Returns
    -------
    Upstream
    """
    sc = Scales.of(fluid, printhead.nozzle_radius_m)
    ac = discrete_acoustics(
        printhead,
        density_kg_m3=fluid.density_kg_m3,
        viscosity_pa_s=fluid.zero_shear_viscosity_pa_s,
        dt_s=dt_s,
    )
    area = math.pi * printhead.nozzle_radius_m**2
    pressure_unit = fluid.surface_tension_n_m / printhead.nozzle_radius_m  # Pa
    return Upstream(
        phi=ac.phi,
        g_drive=ac.gamma_drive,
        g_pressure=ac.gamma_pressure * pressure_unit,
        c_row=ac.flow_row / (area * sc.velocity_m_s),
        slopes=drive_slopes(waveform, duration_s=duration_s + 2 * dt_s, dt_s=dt_s),
        dt=dt_s / sc.time_s,
    )


def _coupled_flow(run: JetRun, sc: Scales, radius_m: float) -> NozzleFlow:
    """The nozzle velocity the coupled acoustics produced, as a `NozzleFlow` (SI)."""
    assert run.upstream_velocity is not None
    v = np.asarray(run.upstream_velocity) * sc.velocity_m_s
    dt = run.upstream_dt * sc.time_s
    t = np.arange(v.size) * dt
    disp = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)))
    return NozzleFlow(t_s=t, velocity_m_s=v, displacement_m=disp, nozzle_radius_m=radius_m)


def jet_inflow(flow: NozzleFlow) -> NozzleFlow:
    """The part of the orifice flow that feeds the jet outside the nozzle.

    While the liquid column is pushed out, it all goes into the jet. When the acoustics
    draw liquid back, the model lets the meniscus inside the bore take the retraction:
    the jet's root stays at the rim with zero velocity, and later outflow first refills
    the bore before it pushes the jet again. The jet's inflow displacement is therefore
    the running maximum of the orifice displacement. This is an ASSUMPTION: a pinned
    rim that imposes the suction on the 1D jet empties the root cell within a few µs and
    pinches every fluid at the rim at the same moment, whatever its viscoelasticity.

    Parameters
    ----------
    flow : NozzleFlow
        Orifice flow from :func:`microfab.plants.printhead.nozzle_flow`.

    Returns
    -------
    NozzleFlow
        Same time grid; velocity zero while the orifice displacement is below its
        running maximum, displacement integrated from that velocity.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(5) * 1e-6
    >>> flow = NozzleFlow(t_s=t, velocity_m_s=np.array([0.0, 2.0, -2.0, 2.0, 2.0]),
    ...                   displacement_m=np.array([0.0, 1.0, 1.0, 1.0, 3.0]) * 1e-6,
    ...                   nozzle_radius_m=60e-6)
    >>> jet_inflow(flow).velocity_m_s.tolist()
    [0.0, 2.0, 0.0, 2.0, 2.0]
    """
    d = flow.displacement_m
    high = np.maximum.accumulate(d)
    at_high = d >= high - 1e-9 * max(float(np.abs(d).max()), flow.nozzle_radius_m)
    v = np.where(at_high & (flow.velocity_m_s > 0.0), flow.velocity_m_s, 0.0)
    disp = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * flow.dt_s)))
    return NozzleFlow(
        t_s=flow.t_s, velocity_m_s=v, displacement_m=disp, nozzle_radius_m=flow.nozzle_radius_m
    )
