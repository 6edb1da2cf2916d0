from __future__ import annotations

import math
import re
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from microfab.process.inkjet.fluids import (
    DEFAULT_JET_MODEL,
    SEED_CONCENTRATIONS_PCT,
    WATER,
    Fluid,
    fluid_table_rows,
    load_table,
    naalg,
    newtonian,
)

ETA_S = 0.89e-3  # water, 25 °C (brief / handbook)


def _raw() -> dict:
    text = resources.files("microfab.data").joinpath("naalg.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


# ---------------------------------------------------------------- Fluid


def test_fluid_derived_properties() -> None:
    f = Fluid(
        name="ink",
        density_kg_m3=1000.0,
        surface_tension_n_m=0.05,
        solvent_viscosity_pa_s=1e-3,
        polymer_viscosity_pa_s=9e-3,
        relaxation_time_s=2e-4,
        extensibility_l2=400.0,
    )
    assert f.zero_shear_viscosity_pa_s == pytest.approx(1e-2)
    assert f.polymer_modulus_pa == pytest.approx(45.0)  # 9e-3 / 2e-4
    assert not f.is_newtonian
    g = f.with_(relaxation_time_s=0.0)
    assert g.is_newtonian and g.polymer_modulus_pa == 0.0
    assert g.extensibility_l2 == 400.0 and f.relaxation_time_s == 2e-4  # original untouched
    assert math.isinf(f.with_(extensibility_l2=math.inf).extensibility_l2)


def test_newtonian_and_water() -> None:
    f = newtonian("oil", 900.0, 0.03, 0.05)
    assert f.is_newtonian and f.polymer_viscosity_pa_s == 0.0 and f.relaxation_time_s == 0.0
    assert f.zero_shear_viscosity_pa_s == 0.05
    assert WATER.density_kg_m3 == 997.05
    assert WATER.surface_tension_n_m == 0.07197
    assert WATER.zero_shear_viscosity_pa_s == ETA_S
    assert WATER.is_newtonian


@pytest.mark.parametrize(
    ("field", "value", "pattern"),
    [
        ("density_kg_m3", -1.0, r"density .*-1\.0 kg/m³"),
        ("surface_tension_n_m", float("nan"), r"surface tension .*nan N/m"),
        ("solvent_viscosity_pa_s", 0.0, r"solvent viscosity .*0\.0 Pa·s"),
        ("polymer_viscosity_pa_s", -1e-3, r"polymer viscosity .*Pa·s"),
        ("relaxation_time_s", -1e-5, r"relaxation time .* s"),
        ("relaxation_time_s", math.inf, r"relaxation time .*inf s"),
        ("extensibility_l2", 2.0, r"L² .*2\.0"),
        ("extensibility_l2", float("nan"), r"L²"),
        ("concentration_pct", -0.5, r"concentration .*% w/v"),
    ],
)
def test_fluid_validation(field: str, value: float, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern):
        WATER.with_(**{field: value})


def test_fluid_is_frozen() -> None:
    with pytest.raises(AttributeError):
        WATER.density_kg_m3 = 1.0  # type: ignore[misc]


# ---------------------------------------------------------------- table


def test_table_matches_toml_and_seed() -> None:
    raw = _raw()
    t = load_table()
    conc = [r["concentration_pct"] for r in raw["solution"]]
    assert tuple(conc) == SEED_CONCENTRATIONS_PCT == (0.15, 0.20, 0.25, 1.0, 1.5, 2.0)
    assert raw["solvent_viscosity_pa_s"] == ETA_S
    assert t.solvent_viscosity_pa_s == ETA_S
    for r in raw["solution"]:
        for key in ("density", "surface_tension", "zero_shear_viscosity"):
            assert r[f"{key}_source"].strip(), (r["concentration_pct"], key)
    rel = raw["relaxation"]
    assert rel["reference_pct"] == 1.0
    assert rel["status"] in {"uncalibrated", "calibrated"}
    assert rel["bounds"]["lambda_ref_s"] == [1.0e-6, 5.0e-3]
    assert rel["bounds"]["exponent"] == [0.3, 4.0]  # semi-dilute (its note)
    lo, hi = t.lambda_ref_bounds_s
    assert lo <= t.lambda_ref_s <= hi
    lo, hi = t.exponent_bounds
    assert lo <= t.exponent <= hi
    assert 3.0 < t.extensibility_l2 < math.inf
    with pytest.raises(ValueError):
        t.concentration_pct[0] = 9.0  # read-only arrays


def test_table_points_returned_exactly() -> None:
    for r in _raw()["solution"]:
        f = naalg(r["concentration_pct"])
        assert f.concentration_pct == r["concentration_pct"]
        assert f.density_kg_m3 == r["density_kg_m3"]
        assert f.surface_tension_n_m == r["surface_tension_n_m"]
        # η0 = η_s + η_p: equal up to one floating-point rounding.
        assert f.zero_shear_viscosity_pa_s == pytest.approx(
            r["zero_shear_viscosity_pa_s"], rel=1e-15
        )
        # the default model's law splits η0 - η_w by its polymer share (fluids module doc)
        share = load_table().law(DEFAULT_JET_MODEL).polymer_share
        excess = r["zero_shear_viscosity_pa_s"] - ETA_S
        assert f.solvent_viscosity_pa_s == pytest.approx(ETA_S + (1 - share) * excess, rel=1e-14)
        assert f.polymer_viscosity_pa_s == pytest.approx(share * excess, rel=1e-14)


def test_one_percent_literal_values() -> None:
    f = naalg(1.0)
    assert (f.density_kg_m3, f.surface_tension_n_m, f.zero_shear_viscosity_pa_s) == (
        1001.05,
        0.0695,
        0.02,
    )
    assert f.name == "NaAlg 1 % w/v"


def test_interpolation_laws_by_hand() -> None:
    # Power law of η_sp between 1 % (η0 = 20 mPa·s) and 1.5 % (38 mPa·s): at the geometric
    # mean concentration η_sp is the geometric mean of the end values.
    sp1, sp2 = 0.020 / ETA_S - 1.0, 0.038 / ETA_S - 1.0
    c = math.sqrt(1.0 * 1.5)
    assert naalg(c).zero_shear_viscosity_pa_s == pytest.approx(ETA_S * (1 + math.sqrt(sp1 * sp2)))
    # Dilute limit below 0.15 % (η0 = 2 mPa·s): η_sp ∝ c.
    sp015 = 2.0e-3 / ETA_S - 1.0
    assert naalg(0.075).zero_shear_viscosity_pa_s == pytest.approx(ETA_S * (1 + sp015 / 2))
    # Density and surface tension linear in c: between 0.25 % and 1 %.
    assert naalg(0.6).density_kg_m3 == pytest.approx(998.05 + (1001.05 - 998.05) * 0.35 / 0.75)
    assert naalg(0.6).surface_tension_n_m == pytest.approx(0.0714 + (0.0695 - 0.0714) * 0.35 / 0.75)
    # ... and linear to water below the first point.
    assert naalg(0.05).density_kg_m3 == pytest.approx(997.05 + (997.65 - 997.05) / 3)
    assert naalg(0.05).surface_tension_n_m == pytest.approx(0.07197 + (0.0716 - 0.07197) / 3)
    # η_p = s_p (η0 - η_w), s_p the default model's polymer share.
    f = naalg(0.7)
    share = load_table().law(DEFAULT_JET_MODEL).polymer_share
    assert f.polymer_viscosity_pa_s == pytest.approx(share * (f.zero_shear_viscosity_pa_s - ETA_S))
    assert naalg(0.7, polymer_share=1.0).polymer_viscosity_pa_s == pytest.approx(
        f.zero_shear_viscosity_pa_s - ETA_S
    )


def test_relaxation_law() -> None:
    t = load_table()
    for c in (0.15, 0.4, 1.0, 2.0):
        expect = t.lambda_ref_s * (c / t.reference_pct) ** t.exponent
        # the table's top-level law ([relaxation]) is the Lagrangian model's
        assert naalg(c, model="lagrangian").relaxation_time_s == pytest.approx(expect, rel=1e-12)
        assert t.relaxation_time_s(c, "lagrangian") == pytest.approx(expect, rel=1e-12)
    assert naalg(1.0, model="lagrangian").relaxation_time_s == t.lambda_ref_s
    # without a model the default jet model's law
    law = t.law(DEFAULT_JET_MODEL)
    assert naalg(1.0).relaxation_time_s == law.lambda_ref_s
    assert naalg(1.0, relaxation_time_s=5e-4).relaxation_time_s == 5e-4
    assert naalg(1.0).extensibility_l2 == t.extensibility_l2


def test_monotone_in_concentration() -> None:
    cs = np.linspace(0.0, 2.0, 401)
    fl = [naalg(float(c)) for c in cs]
    eta = np.array([f.zero_shear_viscosity_pa_s for f in fl])
    lam = np.array([f.relaxation_time_s for f in fl])
    rho = np.array([f.density_kg_m3 for f in fl])
    assert np.all(np.diff(eta) > 0.0)
    assert np.all(np.diff(lam) >= 0.0)  # exponent may be 0 after calibration
    assert np.all(np.diff(rho) > 0.0)


@pytest.mark.parametrize("c", SEED_CONCENTRATIONS_PCT)
def test_continuous_at_table_points(c: float) -> None:
    at = naalg(c)
    eps = 1e-9
    for side in (c - eps, c + eps):
        if side > 2.0:
            continue
        f = naalg(side)
        for name in ("zero_shear_viscosity_pa_s", "density_kg_m3", "surface_tension_n_m"):
            assert getattr(f, name) == pytest.approx(getattr(at, name), rel=1e-6), (side, name)
        assert f.relaxation_time_s == pytest.approx(at.relaxation_time_s, rel=1e-6)


def test_zero_concentration_is_water() -> None:
    f = naalg(0.0)
    assert f.density_kg_m3 == WATER.density_kg_m3
    assert f.surface_tension_n_m == WATER.surface_tension_n_m
    assert f.zero_shear_viscosity_pa_s == WATER.zero_shear_viscosity_pa_s
    assert f.is_newtonian and f.polymer_viscosity_pa_s == 0.0
    g = naalg(1e-9)
    assert g.zero_shear_viscosity_pa_s == pytest.approx(ETA_S, rel=1e-6)
    assert g.density_kg_m3 == pytest.approx(997.05, rel=1e-9)


@pytest.mark.parametrize("c", [-0.1, 2.0001, 5.0, float("nan"), float("inf")])
def test_bad_concentration(c: float) -> None:
    with pytest.raises(ValueError, match=r"outside the table \(0 to 2 % w/v\)"):
        naalg(c)


def test_bad_concentration_message() -> None:
    with pytest.raises(ValueError) as err:
        naalg(-0.1)
    assert str(err.value) == "NaAlg concentration -0.1 % w/v is outside the table (0 to 2 % w/v)"


# ---------------------------------------------------------------- load_table / rows


def _toml_text() -> str:
    return resources.files("microfab.data").joinpath("naalg.toml").read_text(encoding="utf-8")


def test_load_table_from_path(tmp_path: Path) -> None:
    # first occurrences are the [relaxation] entries (the bounds table follows it)
    text = re.sub(
        r"^lambda_ref_s = .*$", "lambda_ref_s = 3.0e-4", _toml_text(), count=1, flags=re.M
    )
    text = re.sub(r"^exponent = .*$", "exponent = 2.0", text, count=1, flags=re.M)
    text = re.sub(r'^status = ".*"$', 'status = "calibrated"', text, count=1, flags=re.M)
    p = tmp_path / "cal.toml"
    p.write_text(text, encoding="utf-8")
    t = load_table(p)
    assert (t.relaxation_status, t.lambda_ref_s, t.exponent) == ("calibrated", 3.0e-4, 2.0)
    assert naalg(1.0, table=t, model="lagrangian").relaxation_time_s == 3.0e-4
    assert naalg(0.5, table=t, model="lagrangian").relaxation_time_s == pytest.approx(3.0e-4 * 0.25)
    assert t.exponent_bounds == (0.3, 4.0)


@pytest.mark.parametrize(
    ("old", "new"),
    [
        ("zero_shear_viscosity_pa_s = 2.0e-3", "zero_shear_viscosity_pa_s = 0.5e-3"),
        ("concentration_pct = 0.20", "concentration_pct = 0.15"),
        ("[relaxation]", "[relaxation_missing]"),
        ("extensibility_l2 = 100.0", "extensibility_l2 = 1.0"),
        ("density_kg_m3 = 997.65", "density_kg_m3 = -997.65"),
    ],
)
def test_load_table_rejects_bad_files(tmp_path: Path, old: str, new: str) -> None:
    text = _toml_text()
    assert old in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(ValueError):
        load_table(p)


def test_the_back_pressure_is_read_with_its_source_and_is_zero_without_a_jetting_table(
    tmp_path: Path,
) -> None:
    t = load_table()
    assert t.back_pressure_pa == _raw()["jetting"]["back_pressure_pa"]
    assert "pneumatic controller" in t.back_pressure_source
    assert t.back_pressure_source.startswith("assumed")
    text = _toml_text()
    p = tmp_path / "no_jetting.toml"
    p.write_text(text[: text.index("[jetting]")], encoding="utf-8")
    assert load_table(p).back_pressure_pa == 0.0
    p.write_text(text.replace("back_pressure_pa = 0.0", "back_pressure_pa = -450.5"), "utf-8")
    assert load_table(p).back_pressure_pa == -450.5
    p.write_text(text.replace("back_pressure_pa = 0.0", "back_pressure_pa = nan"), "utf-8")
    with pytest.raises(ValueError, match="back_pressure_pa"):
        load_table(p)


def test_load_table_rejects_invalid_toml(tmp_path: Path) -> None:
    p = tmp_path / "broken.toml"
    p.write_text("solution = [", encoding="utf-8")
    with pytest.raises(ValueError, match="not valid TOML"):
        load_table(p)


def test_fluid_table_rows() -> None:
    rows = fluid_table_rows()
    assert [r["concentration_pct"] for r in rows] == list(SEED_CONCENTRATIONS_PCT)
    raw = _raw()["solution"]
    for r, src in zip(rows, raw, strict=True):
        assert r["density_kg_m3"] == src["density_kg_m3"]
        assert r["viscosity_source"] == src["zero_shear_viscosity_source"]
        assert r["relaxation_status"] in r["relaxation_source"]
        for key in (
            "surface_tension_n_m",
            "zero_shear_viscosity_pa_s",
            "relaxation_time_s",
            "extensibility_l2",
            "density_source",
            "surface_tension_source",
            "extensibility_source",
        ):
            assert key in r
