from __future__ import annotations

import pytest

from microfab.plants.printhead import Printhead, nozzle_flow
from microfab.process.inkjet.dispenser import REFERENCE_PEAK_VELOCITY_M_S, default_printhead
from microfab.trajectory.waveform import seed003_waveform

WATER = {"density_kg_m3": 1000.0, "viscosity_pa_s": 1e-3, "surface_tension_n_m": 0.072}


def test_default_printhead_is_calibrated_and_cached() -> None:
    head = default_printhead()
    assert default_printhead() is head
    peak = nozzle_flow(head, seed003_waveform(50.0), **WATER).peak_velocity_m_s
    assert peak == pytest.approx(REFERENCE_PEAK_VELOCITY_M_S, rel=1e-9)
    # the class default is the same gain, rounded to three digits
    assert Printhead().gain_m3_per_v == pytest.approx(head.gain_m3_per_v, rel=5e-3)
