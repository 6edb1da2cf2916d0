from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.process.inkjet.dimensionless import (
    CATEGORIES,
    numbers,
    regime_map,
)
from microfab.process.inkjet.fluids import WATER, Fluid, naalg, newtonian

# ρ = 1000, σ = 0.05, R = 50 µm (L = D = 100 µm): sqrt(ρ σ D) = sqrt(5e-3).
SQRT_RSD = math.sqrt(1000.0 * 0.05 * 100e-6)


def _fluid_with_oh(oh: float) -> Fluid:
    return newtonian(f"Oh={oh}", 1000.0, 0.05, oh * SQRT_RSD)


def test_water_by_hand() -> None:
    d = numbers(WATER, nozzle_radius_m=60e-6, speed_m_s=5.0)
    # D = 120 µm; ρ = 997.05, σ = 0.07197, η = 0.89e-3 (computed separately).
    assert d.length_m == 120e-6 and d.radius_m == 60e-6
    assert d.ohnesorge == pytest.approx(0.009591028099203494, rel=1e-9)
    assert d.reynolds == pytest.approx(672.1685393258427, rel=1e-9)
    assert d.weber == pytest.approx(41.561067111296374, rel=1e-9)
    assert d.z_number == pytest.approx(1.0 / 0.009591028099203494, rel=1e-9)
    assert d.deborah == 0.0 and d.elastocapillary == 0.0
    assert d.capillary_time_s == pytest.approx(math.sqrt(997.05 * (60e-6) ** 3 / 0.07197))


@pytest.mark.parametrize("c", [0.0, 0.15, 0.7, 2.0])
@pytest.mark.parametrize("v", [0.3, 2.0, 9.0])
def test_oh_is_sqrt_we_over_re(c: float, v: float) -> None:
    d = numbers(naalg(c), speed_m_s=v)
    assert d.ohnesorge == pytest.approx(math.sqrt(d.weber) / d.reynolds, rel=1e-12)
    assert d.z_number == pytest.approx(1.0 / d.ohnesorge, rel=1e-12)


def test_length_convention() -> None:
    f = naalg(1.0)
    dia = numbers(f, nozzle_radius_m=60e-6, speed_m_s=3.0)
    rad = numbers(f, nozzle_radius_m=60e-6, speed_m_s=3.0, length_m=60e-6)
    assert rad.ohnesorge == pytest.approx(dia.ohnesorge * math.sqrt(2.0), rel=1e-12)
    assert rad.weber == pytest.approx(dia.weber / 2.0, rel=1e-12)
    # radius-based quantities do not depend on length_m
    assert rad.deborah == dia.deborah and rad.elastocapillary == dia.elastocapillary
    assert rad.capillary_time_s == dia.capillary_time_s


def test_deborah_and_elastocapillary_by_hand() -> None:
    f = Fluid(
        name="model",
        density_kg_m3=1000.0,
        surface_tension_n_m=0.05,
        solvent_viscosity_pa_s=1e-3,
        polymer_viscosity_pa_s=9e-3,
        relaxation_time_s=2e-4,
    )
    d = numbers(f, nozzle_radius_m=50e-6, speed_m_s=1.0)
    # t_c = sqrt(1000 · (50e-6)³ / 0.05) = 5e-5 s; t_v = 0.01 · 50e-6 / 0.05 = 1e-5 s
    assert d.capillary_time_s == pytest.approx(5e-5, rel=1e-12)
    assert d.viscous_time_s == pytest.approx(1e-5, rel=1e-12)
    assert d.deborah == pytest.approx(4.0, rel=1e-12)
    assert d.elastocapillary == pytest.approx(20.0, rel=1e-12)
    # Ec = De / Oh_R (radius-based Ohnesorge)
    oh_r = 0.01 / math.sqrt(1000.0 * 0.05 * 50e-6)
    assert d.elastocapillary == pytest.approx(d.deborah / oh_r, rel=1e-12)


@pytest.mark.parametrize(
    ("fluid", "speed", "expected"),
    [
        (_fluid_with_oh(0.5), 2.0, "printable"),  # Z = 2, We = 8, We^½Re^¼ ≈ 4.4
        (_fluid_with_oh(0.5), 1.0, "no ejection"),  # We = 2
        (_fluid_with_oh(2.0), 5.0, "too viscous"),  # Z = 0.5, We = 50
        (_fluid_with_oh(0.05), 3.0, "satellites"),  # Z = 20, We = 18, We^½Re^¼ ≈ 12.9
        (WATER, 5.0, "satellites"),  # Z ≈ 104, We ≈ 42
        (WATER, 30.0, "splashing"),  # We ≈ 1496, Re ≈ 4033 → ≈ 309
        (WATER, 0.0, "no ejection"),
    ],
)
def test_regime_categories(fluid: Fluid, speed: float, expected: str) -> None:
    d = numbers(fluid, nozzle_radius_m=50e-6 if fluid is not WATER else 60e-6, speed_m_s=speed)
    assert d.category == expected
    assert d.printable is (expected == "printable")
    assert d.window.startswith(expected)


def test_window_text_names_limit() -> None:
    d = numbers(_fluid_with_oh(2.0), nozzle_radius_m=50e-6, speed_m_s=5.0)
    assert "Z = 1/Oh = 0.5 < 1" in d.window and "Derby" in d.window
    d = numbers(_fluid_with_oh(0.5), nozzle_radius_m=50e-6, speed_m_s=2.0)
    assert "We = 8" in d.window


@pytest.mark.parametrize(
    "kwargs",
    [
        {"speed_m_s": -1.0},
        {"speed_m_s": float("nan")},
        {"speed_m_s": 1.0, "nozzle_radius_m": 0.0},
        {"speed_m_s": 1.0, "length_m": -1e-6},
    ],
)
def test_numbers_bad_input(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        numbers(WATER, **kwargs)


def test_regime_map_consistent_with_numbers() -> None:
    cs = [0.15, 0.5, 1.0, 2.0]
    vs = [0.5, 2.0, 5.0, 12.0, 30.0]
    m = regime_map(cs, vs)
    assert m.ohnesorge.shape == m.weber.shape == m.category.shape == (4, 5)
    d = numbers(naalg(1.0), speed_m_s=5.0)
    assert m.weber[2, 2] == pytest.approx(d.weber)
    assert m.deborah[2, 2] == pytest.approx(d.deborah)
    assert m.elastocapillary[2, 2] == pytest.approx(d.elastocapillary)
    assert CATEGORIES[m.category[2, 2]] == d.category
    # Oh, Z, De do not depend on speed
    assert np.allclose(m.ohnesorge, m.ohnesorge[:, :1])
    assert np.allclose(m.deborah, m.deborah[:, :1])
    assert np.array_equal(m.printable, m.category == CATEGORIES.index("printable"))
    assert m.length_m == pytest.approx(120e-6)
    # slowest column never ejects (We < 4 at 0.5 m/s through 120 µm)
    assert np.all(m.category[:, 0] == CATEGORIES.index("no ejection"))
