"""Published numbers of seed 004 (laser micromachining workstation, Golubovic et al.).

Every value cites its table, equation or section in ``../shared/seeds/004_e9b0ea07a8a259a3.txt``.
The seed gives no gains, sample time or speeds; the speeds the project uses for its
figures are in `PROJECT_CHOICES` and say so.

Seed errors noted here once (the code that uses the numbers repeats the relevant one):

* §III.A, eq. (15) cites "(15)" but means the derivative of (13); its right-hand side
  should be ``[0, v̇]``, not ``[0, v]``. ``[j̇]`` is the derivative ``J̇`` of eq. (14).
* §IV.C cites "[21]" for the autofocus set-up; the set-up is that of [23]. Refs. [16]
  and [17] are swapped (the cutting head is Haas LTI, the laser SPI).
* §IV.B: "200 nm" is a pulse width, so 200 ns; "8 mJ per pulse" contradicts 5 W at
  25 kHz, which gives 0.2 mJ.
"""

from __future__ import annotations

from microfab.machines.laser_stage.calibration import FIG3_PEAK_ERROR_M
from microfab.measure.contour import AXIS_BAND_M as FIG3_TYPICAL_ERROR_M
from microfab.trajectory.contour_laps import MAX_ACCELERATION_M_S2
from microfab.trajectory.force_check import CONTINUOUS_FORCE_N, PEAK_FORCE_N

__all__ = [
    "AVERAGE_POWER_W",
    "CONTINUOUS_FORCE_N",
    "DEPTH_OF_FOCUS_M",
    "FIG3_PEAK_ERROR_M",
    "FIG3_RADIUS_M",
    "FIG3_TYPICAL_ERROR_M",
    "FIG7_SIZE_M",
    "FIG7_SPEED_M_S",
    "MAX_ACCELERATION_M_S2",
    "MAX_VELOCITY_M_S",
    "PEAK_FORCE_N",
    "POSITION_RESOLUTION_M",
    "PROJECT_CHOICES",
    "PULSE_RATE_HZ",
    "PULSE_WIDTH_S",
    "SINGLE_STAGE_MASS_KG",
    "STATED_PULSE_ENERGY_J",
    "WAIST_DIAMETER_M",
    "WAVELENGTH_M",
    "pulse_energy_j",
]

# ---------------------------------------------------------------- Table I: the stage
# MAX_ACCELERATION_M_S2 (5 m/s²), PEAK_FORCE_N (12 N), CONTINUOUS_FORCE_N (3 N): seed 004
# Table I, from microfab.trajectory.contour_laps (the reference's checks).
MAX_VELOCITY_M_S = 0.1  # seed 004 Table I
POSITION_RESOLUTION_M = 10e-9  # seed 004 Table I (and §II.C: 10 nm encoder)
SINGLE_STAGE_MASS_KG = 0.6  # seed 004 Table I

# ---------------------------------------------------------------- §II.A: optics
WAVELENGTH_M = 1065e-9  # seed 004 §II.A: SPI G3 HS fibre laser, 1065 nm
WAIST_DIAMETER_M = 10.8e-6  # seed 004 §II.A: "final waist diameter ... 10.8 µm"
DEPTH_OF_FOCUS_M = 54e-6  # seed 004 §II.A: "depth of focus is approximately 54 µm"

# ---------------------------------------------------------------- §IV.A, Fig. 3
FIG3_RADIUS_M = 30e-6  # seed 004 §IV.A: circle reference of radius 30 µm
# FIG3_TYPICAL_ERROR_M (0.5 µm, seed 004 §IV.A: "errors are generally lower than 0.5 µm"):
# the band of microfab.measure.contour.AXIS_BAND_M; FIG3_PEAK_ERROR_M (0.8 µm, §IV.A:
# "reaching 0.8 µm at the peak points"): the fit target of
# microfab.machines.laser_stage.calibration.

# ---------------------------------------------------------------- §IV.D, Fig. 7
FIG7_SIZE_M = 100e-6  # seed 004 §IV.D: "circle with 100 µm" (radius or diameter unsaid)
FIG7_SPEED_M_S = 10e-3  # seed 004 §IV.D: reference tangential velocity 10 mm/s

# ---------------------------------------------------------------- §IV.B: marking
PULSE_RATE_HZ = 25e3  # seed 004 §IV.B: repetition rate 25 kHz
PULSE_WIDTH_S = 200e-9  # seed 004 §IV.B: "200 nm", read as 200 ns (see the module notes)
AVERAGE_POWER_W = 5.0  # seed 004 §IV.B: 25 % of the 20 W laser
STATED_PULSE_ENERGY_J = 8e-3  # seed 004 §IV.B, inconsistent: 5 W / 25 kHz = 0.2 mJ

#: Choices the project makes where the seed is silent (issue 15), not seed data.
PROJECT_CHOICES = {
    "fig3_speed_m_s": 1e-3,  # Fig. 3's speed is not given: 1 mm/s (also 0.1-10 mm/s)
    "fig7_radius_m": 100e-6,  # "100 µm" read as the radius (50 µm also run)
    "fig7_gain_min": 2.0,  # after lap 1 the correction cuts the max contour error >= 2x
    "fig7_low_speed_m_s": 1e-3,  # at <= 1 mm/s the correction changes it by < 50 nm
    "fig7_low_speed_change_m": 50e-9,
    # issue 45, on the paper's model: the ratio without / with rises over 0.5-20 mm/s and
    # is <= 1.2 at 0.5 mm/s (the seed's "almost no significant contribution" at low speed)
    "fig7_ratio_low_max": 1.2,
    "fig7_ratio_speeds_mm_s": (0.5, 1.0, 2.0, 5.0, 10.0, 20.0),
    "fig3_fraction_below_typical": 0.95,  # "generally lower than 0.5 µm": >= 95 % of samples
    "fig3_peak_tolerance": 0.25,  # peak 0.8 µm ± 25 %
    "autofocus_start_m": 500e-6,  # autofocus starts 500 µm off focus (assumed)
    # Fig. 6 has no numbers: the project's autofocus targets (issues 15, 33, 45)
    "autofocus_ptp_max_m": 5e-6,  # continuous law's steady peak-to-peak of z <= 5 µm
    "autofocus_ratio_min": 5.0,  # ... and <= 1/5 of the discontinuous law's
}


def pulse_energy_j() -> float:
    """Energy per pulse implied by the seed's average power and rate, J (0.2 mJ)."""
    return AVERAGE_POWER_W / PULSE_RATE_HZ
