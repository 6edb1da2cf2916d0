"""The NaAlg ink on the calibration core: the problem, a tiny run, the twin file."""

from __future__ import annotations

import math
import shutil
from importlib import resources
from pathlib import Path

import pytest

from microfab.calibrate import calibrate
from microfab.machines.printhead import calibration as cal
from microfab.plants.sourced_toml import sources_of
from microfab.process.inkjet.fluids import load_table, naalg

#: A run too short for any breakup (0.15 % breaks near 88 µs): the same model, about 0.1 s
#: per parameter set, so a test's budget runs in a few seconds.
SHORT_S = 20e-6


def _packaged(tmp_path: Path) -> Path:
    path = tmp_path / "naalg.toml"
    with resources.as_file(resources.files("microfab.data") / "naalg.toml") as src:
        shutil.copy(src, path)
    return path


def test_problem_fits_the_two_times_and_holds_the_modes_back() -> None:
    prob = cal.problem()
    fit = {t.name: t for t in prob.targets if t.role == "fit"}
    assert set(fit) == {cal.T_LOW, cal.T_REF}
    assert (fit[cal.T_LOW].value, fit[cal.T_LOW].tolerance) == (95.0, pytest.approx(9.5))
    assert (fit[cal.T_REF].value, fit[cal.T_REF].tolerance) == (230.0, pytest.approx(23.0))
    checks = {t.name: t for t in prob.targets if t.role == "check"}
    assert set(checks) == {cal.FRONT, cal.EXIT, cal.RISE, cal.LAST, cal.LAST_AFTER, cal.RIM}
    # a mode check is met exactly when the pinch lies in the seed's third of the jet
    front, exit_ = checks[cal.FRONT], checks[cal.EXIT]
    assert front.residual(2 / 3 + 1e-9) == pytest.approx(-1.0) and front.residual(0.6) < -1
    assert exit_.residual(1 / 3 - 1e-9) == pytest.approx(1.0) and exit_.residual(0.4) > 1
    assert all(t.source.startswith("seed 003 part 1") for t in prob.targets)
    params = {p.name: p for p in prob.parameters}
    assert set(params) == {"lambda_ref_s", "exponent", "polymer_share"}
    assert params["exponent"].low > 0.0  # m = 0 needs a reason the seed does not give
    assert params["lambda_ref_s"].log
    assert (params["lambda_ref_s"].low, params["lambda_ref_s"].high) == (
        load_table().lambda_ref_bounds_s
    )
    assert all("assumed" in params[n].source for n in ("exponent", "polymer_share"))
    diag = cal.problem(mode_fit=True)
    assert {t.name for t in diag.targets if t.role == "fit"} == {
        cal.T_LOW,
        cal.T_REF,
        cal.FRONT,
        cal.EXIT,
    }
    # the model is picklable for the process pool, and the table's digest is its identity
    import pickle

    assert pickle.loads(pickle.dumps(prob.evaluate)).keywords == prob.evaluate.keywords
    assert prob.fingerprint() != cal.problem(model="lagrangian").fingerprint()


def test_polymer_share_moves_viscosity_to_the_solvent_and_keeps_eta0() -> None:
    full, half = naalg(1.0, polymer_share=1.0), naalg(1.0, polymer_share=0.5)
    assert half.zero_shear_viscosity_pa_s == pytest.approx(full.zero_shear_viscosity_pa_s)
    assert half.polymer_viscosity_pa_s == pytest.approx(0.5 * full.polymer_viscosity_pa_s)
    with pytest.raises(ValueError, match="polymer_share"):
        naalg(1.0, polymer_share=0.0)


@pytest.fixture(scope="module")
def tiny():
    """One tiny calibration on a run too short to break: every row comes back."""
    prob = cal.problem(duration_s=SHORT_S)
    return calibrate(prob, budget=13, seed=0, polish=False, conflict_budget=0)


def test_a_tiny_run_returns_every_row(tiny) -> None:
    assert [t.name for t in tiny.targets] == list(cal.problem().target_names)
    assert [p.name for p in tiny.parameters] == ["lambda_ref_s", "exponent", "polymer_share"]
    # nothing breaks within 20 µs: the times are NaN, counted as unmet, never as met
    row = {t.name: t for t in tiny.targets}
    assert math.isnan(row[cal.T_LOW].model) and not row[cal.T_LOW].met
    assert not tiny.converged


def test_write_twin_sources_name_the_command_and_targets(tiny, tmp_path: Path) -> None:
    path = _packaged(tmp_path)
    cal.write_twin(tiny, path, source=path, model="eulerian")
    law = load_table(path).law("eulerian")
    assert law.lambda_ref_s == pytest.approx(tiny.values["lambda_ref_s"], rel=1e-5)
    assert law.polymer_share == pytest.approx(tiny.values["polymer_share"], rel=1e-5)
    src = sources_of(path, "naalg.toml")
    for key in ("lambda_ref_s", "exponent", "polymer_share"):
        text = src[f"relaxation_eulerian.{key}"]
        assert text.startswith("calibrated: `microfab droplet calibrate --model eulerian`")
        assert cal.T_LOW in text and cal.T_REF in text
    # the Lagrangian law is untouched
    assert load_table(path).law("lagrangian") == load_table().law("lagrangian")


def test_a_table_that_cannot_take_the_law_is_refused_and_left(tmp_path: Path) -> None:
    path = _packaged(tmp_path)
    text = path.read_text(encoding="utf-8").replace("polymer_share_source", "polymer_share_note")
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match="polymer_share"):
        cal.problem(source=path)
    assert path.read_text(encoding="utf-8") == text
    with pytest.raises(ValueError, match="model must be one of"):
        cal.problem(model="smooth")
