from __future__ import annotations

import shutil
from importlib import resources
from pathlib import Path

import pytest

from microfab.machines.printhead.calibration import (
    SEED_BREAKUP,
    calibrate_relaxation,
    write_relaxation,
)
from microfab.process.inkjet.fluids import load_table


def _stand_in(lam_true: float, m_true: float):
    """A breakup-time law with a known answer: t = 100 µs · (1 + λ / λ(c)_true)."""

    def breakup(c: float, lam: float) -> tuple[float, str]:
        lam_c = lam_true * c**m_true
        target = SEED_BREAKUP[c][0] if c in SEED_BREAKUP else 100e-6
        return target * (0.5 + 0.5 * lam / lam_c), "exit"

    return breakup


def test_calibration_recovers_a_known_law() -> None:
    fit = calibrate_relaxation(breakup=_stand_in(20e-6, 1.7), rtol=1e-3)
    assert fit.lambda_ref_s == pytest.approx(20e-6, rel=1e-2)
    assert fit.exponent == pytest.approx(1.7, abs=1e-2)
    assert fit.at_bound == ()
    assert fit.model_breakup[1.0][0] == pytest.approx(230e-6, rel=1e-2)
    assert fit.model_breakup[0.15][0] == pytest.approx(95e-6, rel=1e-2)


def test_calibration_reports_an_unreachable_target_at_a_bound() -> None:
    # the 0.15 % time never falls below 120 µs: the exponent runs to its upper bound
    def breakup(c: float, lam: float) -> tuple[float, str]:
        return (120e-6 + lam, "exit") if c < 1 else (100e-6 + 10.0 * lam, "exit")

    fit = calibrate_relaxation(breakup=breakup)
    assert fit.lambda_ref_s == pytest.approx(13e-6, rel=0.02)
    assert fit.at_bound == ("exponent",)
    assert fit.exponent == pytest.approx(load_table().exponent_bounds[1])


def test_calibration_takes_the_first_crossing_of_a_non_monotone_response() -> None:
    # rises to 250 µs at 10 µs, then falls: the scan must stop on the rising branch
    def breakup(c: float, lam: float) -> tuple[float | None, str | None]:
        if c < 1:
            return 95e-6, "front"
        return (150e-6 + 10.0 * lam, "exit") if lam <= 10e-6 else (100e-6, "exit")

    fit = calibrate_relaxation(breakup=breakup)
    assert fit.lambda_ref_s == pytest.approx(8e-6, rel=0.02)


def test_calibration_rejects_bad_settings() -> None:
    with pytest.raises(ValueError, match="scan_factor"):
        calibrate_relaxation(breakup=_stand_in(1e-5, 1.0), scan_factor=1.0)
    with pytest.raises(ValueError, match="rtol"):
        calibrate_relaxation(breakup=_stand_in(1e-5, 1.0), rtol=0.0)


def test_write_relaxation_round_trip(tmp_path: Path) -> None:
    src = resources.files("microfab.data").joinpath("naalg.toml")
    path = tmp_path / "naalg.toml"
    with resources.as_file(src) as f:
        shutil.copy(f, path)
    before = load_table(path)
    fit = calibrate_relaxation(breakup=_stand_in(20e-6, 1.7), rtol=1e-3)
    write_relaxation(fit, path, command="test", model="lagrangian")
    after = load_table(path)
    assert after.relaxation_status == "calibrated"
    assert after.lambda_ref_s == pytest.approx(fit.lambda_ref_s, rel=1e-3)
    assert after.exponent == pytest.approx(fit.exponent, abs=1e-3)
    assert after.exponent_bounds == before.exponent_bounds
    assert list(after.zero_shear_viscosity_pa_s) == list(before.zero_shear_viscosity_pa_s)
    assert "`test`" in after.relaxation_note


def test_write_relaxation_refuses_a_file_without_the_table(tmp_path: Path) -> None:
    path = tmp_path / "x.toml"
    path.write_text("a = 1\n")
    fit = calibrate_relaxation(breakup=_stand_in(20e-6, 1.7))
    with pytest.raises(ValueError, match="relaxation"):
        write_relaxation(fit, path, command="test")
    assert path.read_text() == "a = 1\n"


def test_each_jet_model_keeps_its_own_law(tmp_path: Path) -> None:
    src = resources.files("microfab.data").joinpath("naalg.toml")
    path = tmp_path / "naalg.toml"
    with resources.as_file(src) as f:
        shutil.copy(f, path)
    text = path.read_text()
    # without an Eulerian law the table says how to get one
    stripped = text[: text.index("[relaxation_eulerian]")]
    path.write_text(stripped)
    with pytest.raises(ValueError, match="--model eulerian --write"):
        load_table(path).law("eulerian")
    before = load_table(path)
    fit = calibrate_relaxation(breakup=_stand_in(20e-6, 1.7), rtol=1e-3)
    write_relaxation(fit, path, command="test", model="eulerian")  # appended
    fit2 = calibrate_relaxation(breakup=_stand_in(30e-6, 0.9), rtol=1e-3)
    write_relaxation(fit2, path, command="test2", model="eulerian")  # replaced in place
    after = load_table(path)
    law = after.law("eulerian")
    assert law.lambda_ref_s == pytest.approx(30e-6, rel=1e-2)
    assert law.exponent == pytest.approx(0.9, abs=1e-2)
    assert "`test2`" in law.note and "eulerian jet model" in law.note
    assert path.read_text().count("[relaxation_eulerian]") == 1
    assert after.lambda_ref_s == before.lambda_ref_s  # the Lagrangian law is untouched
    assert after.relaxation_time_s(1.0, "eulerian") == pytest.approx(law.lambda_ref_s)
    with pytest.raises(ValueError, match="lower-case"):
        write_relaxation(fit, path, command="x", model="Euler 2")
