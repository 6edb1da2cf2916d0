"""The seed's dispenser: the printhead plant calibrated with the seed's drive and water.

The acoustic model (:mod:`microfab.plants.printhead`) has one free scale, the volume the
PZT displaces per volt. It is set here so that the bipolar 50 V waveform of seed 003
part 1 (``../shared/seeds/003_4915b267b12a78d4.txt``, Table 1; 50 V is the voltage of its
Fig. 2) gives a reference peak orifice velocity with a water-like liquid. The plant knows
nothing about waveforms, so this calibration, which needs the seed's waveform
(:mod:`microfab.trajectory.waveform`), lives in the process layer.

`default_printhead` builds a new calibrated head at each call (about 25 ms): the machine,
:mod:`microfab.machines.printhead`, builds it once per configuration
(`microfab.machines.printhead.twin`) and hands it to every run it plays.
"""

from __future__ import annotations

from microfab.plants.printhead import Printhead, calibrate_gain
from microfab.trajectory.waveform import seed003_waveform

__all__ = [
    "REFERENCE_DENSITY_KG_M3",
    "REFERENCE_PEAK_VELOCITY_M_S",
    "REFERENCE_SURFACE_TENSION_N_M",
    "REFERENCE_VISCOSITY_PA_S",
    "REFERENCE_VOLTAGE_V",
    "default_printhead",
]

#: Peak mean orifice velocity of the reference jetting condition, m/s. Assumption: MicroFab
#: dispensers at about 50 V give jet-head speeds of a few m/s. With 6 m/s at the orifice
#: the drop-on-demand model (:mod:`.droplet`) moves the head at about 4 m/s for the
#: water-like 0.15 % NaAlg; 8 m/s gave nearly 8 m/s, faster than "a few".
REFERENCE_PEAK_VELOCITY_M_S = 6.0
#: Density of the water-like reference liquid, kg/m³ (assumption: water at 20 °C).
REFERENCE_DENSITY_KG_M3 = 1000.0
#: Viscosity of the water-like reference liquid, Pa s (assumption: water at 20 °C).
REFERENCE_VISCOSITY_PA_S = 1.0e-3
#: Surface tension of the water-like reference liquid, N/m (assumption: water at 20 °C).
REFERENCE_SURFACE_TENSION_N_M = 0.072
#: Peak voltage of the reference drive, V: the voltage of Fig. 2 of the seed.
REFERENCE_VOLTAGE_V = 50.0  # seed 003 part 1, Table 1 and Fig. 2


def default_printhead() -> Printhead:
    """The default `Printhead`, calibrated with the seed's waveform and water.

    The gain is set so that the seed's 50 V bipolar waveform (seed 003 part 1, Table 1)
    gives `REFERENCE_PEAK_VELOCITY_M_S` with the water-like reference liquid
    (`REFERENCE_DENSITY_KG_M3`, `REFERENCE_VISCOSITY_PA_S`,
    `REFERENCE_SURFACE_TENSION_N_M`, all assumptions). Built anew at each call; the
    machine's `microfab.machines.printhead.twin` is the one built once and shared.

    Returns
    -------
    Printhead
        The calibrated dispenser model.

    Examples
    --------
    >>> head = default_printhead()
    >>> 1e-15 < head.gain_m3_per_v < 1e-12
    True
    """
    return calibrate_gain(
        Printhead(),
        seed003_waveform(REFERENCE_VOLTAGE_V),  # seed 003 part 1, Table 1 (50 V: Fig. 2)
        density_kg_m3=REFERENCE_DENSITY_KG_M3,
        viscosity_pa_s=REFERENCE_VISCOSITY_PA_S,
        surface_tension_n_m=REFERENCE_SURFACE_TENSION_N_M,
        target_peak_velocity_m_s=REFERENCE_PEAK_VELOCITY_M_S,
    )
