"""The XY stage twin's assumed magnitudes and the shipped twin's calibration."""

from __future__ import annotations

import re
import tomllib
from importlib import resources

import pytest

from microfab.machines import provenance
from microfab.machines.xy_stage import calibration_core
from microfab.machines.xy_stage.calibration import (
    CALIBRATION,
    FREE_FIELDS,
    REFERENCE,
    REFERENCE_SHARED,
    TARGET_SIGMA_M,
    assumed_changes,
    force_budget,
    scaled_changes,
)
from microfab.machines.xy_stage.identify import linear_checks
from microfab.plants.xy_stage_params import load_params


def _twin_file() -> dict:
    text = resources.files("microfab.data").joinpath("xy_stage_twin.toml").read_text()
    return tomllib.loads(text)


def _shipped_sigma_m() -> tuple[float, float]:
    """σ per axis that the data file's calibrated sources state.

    Either calibration's sources: the retired fit's ("... is 48.1 um, seed 48.0 um", on
    600 s) or the core's ("linear_sigma_x_um (47.93 µm for 48, ...)", on its data).
    """
    data = _twin_file()["axes"]
    out = []
    for ax in ("x", "y"):
        src = data[ax]["coulomb_n_source"]
        m = re.search(r"is ([0-9.]+) um, seed", src) or re.search(
            rf"linear_sigma_{ax}_um \(([0-9.e+-]+) µm", src
        )
        assert m is not None, src
        out.append(float(m.group(1)) * 1e-6)
    return out[0], out[1]


def test_the_shipped_twin_holds_one_xy_stage_calibration():
    data = _twin_file()["axes"]
    for ax in ("x", "y"):
        for key in FREE_FIELDS:
            src = data[ax][f"{key}_source"]
            assert src.startswith("calibrated") and "microfab calibrate xy-stage" in src, key
    # the retired fit's labels while the file holds its answer, the core's once rewritten
    held = [provenance.holds(c) for c in (CALIBRATION, calibration_core.CALIBRATION)]
    assert held.count(True) == 1, held


def test_shipped_twin_sigma_on_short_seeded_data_is_in_the_band():
    checks = linear_checks(60.0, seed=0, orders=())
    for got, full in zip(checks.sigma_m, _shipped_sigma_m(), strict=True):
        assert abs(got / full - 1) <= 0.15, (got, full)
    assert abs(checks.mu_m[0]) <= max(2e-6, checks.sigma_m[0] / 3)


def test_scaling_keeps_the_bristle_law():
    p = load_params().with_(**dict(scaled_changes((2.0, 3.0))))
    for i, s in enumerate((2.0, 3.0)):
        assert p.coulomb_n[i] == pytest.approx(s * REFERENCE["coulomb_n"][i])
        # the pre-sliding displacement F_c / sigma0 does not change
        assert p.coulomb_n[i] / p.bristle_stiffness_n_per_m[i] == pytest.approx(
            REFERENCE["coulomb_n"][i] / REFERENCE["bristle_stiffness_n_per_m"][i]
        )
    b = force_budget(p)
    assert b[0].coulomb_n == 40.0 and b[0].inertial_n == pytest.approx(150.0)


def test_assumed_changes_are_every_magnitude_the_core_frees():
    changes = dict(assumed_changes())
    assert changes["coulomb_n"] == REFERENCE["coulomb_n"]
    written = {k.key for k in calibration_core.TWIN_KEYS}
    assert written <= set(changes)  # the assumed twin resets whatever the core writes
    # a value of the file still assumed is the reference's
    for section, table in _twin_file().items():
        for key, value in REFERENCE_SHARED.items():
            src = table.get(f"{key}_source", "") if isinstance(table, dict) else ""
            if src.startswith("assumed"):
                assert table[key] == value, (section, key)


@pytest.fixture(scope="module")
def short_checks():
    return linear_checks(60.0, seed=0, orders=())


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="on the twin calibrated on the core the linear model's sigma of y is 41.7 µm on "
    "60 s (48.7 µm on 600 s; Table II 156.3): where it is met the networks' proxy is at "
    "least 52 µm (8.7x Table II's 6.0), so the joint fit gives it up "
    "(xy_stage.calibration_core's finding)",
)
def test_linear_sigma_of_y_matches_table_ii(short_checks):
    assert abs(short_checks.sigma_m[1] / TARGET_SIGMA_M[1] - 1) <= 0.15


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="on the calibrated twin the slowest identified time constant is 40.7 ms (60 s), "
    "outside the seed's 500 ms / 25 = 20 ms ± 50 %: a check held back that the core's fit "
    "did not meet (pinned by the y friction, the resonance and the y feedforward)",
)
def test_slowest_time_constant_near_20_ms(short_checks):
    from microfab.experiments.seed002_stage.paper import SLOW_TIME_CONSTANT_S

    assert abs(short_checks.slowest_time_constant_s / SLOW_TIME_CONSTANT_S - 1) <= 0.5
