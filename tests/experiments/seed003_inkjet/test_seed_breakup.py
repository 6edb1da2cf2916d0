"""Seed 003 part 1 at 50 V: breakup times, modes and the concentration trend (Fig. 2, 4).

Each jet model has its own relaxation law, fitted to the two quoted times with that
model (``microfab droplet calibrate --model M``), so the times check that the stored
calibration still reproduces them with the current model; the modes and the other four
concentrations are predictions. The models run single-threaded
(`microfab.core.threads`), so these numbers are the same on every machine with the same
BLAS kernels; the Lagrangian 1 % jet is chaotic in the last bit and ends another way with
OpenBLAS's Haswell or SandyBridge kernels than with SkylakeX, so its mode is not tested.
"""

from __future__ import annotations

import itertools

import pytest

from microfab.experiments.seed003_inkjet.paper import SEED_BREAKUP, SEED_CONCENTRATIONS_PCT
from microfab.machines.printhead.calibration import simulated_breakup
from microfab.process.inkjet.fluids import load_table

Runs = dict[float, tuple[float | None, str | None]]


def _breakup(c: float, model: str) -> tuple[float | None, str | None]:
    # the calibration's own model run, with the stored law's relaxation time
    return simulated_breakup(c, load_table().relaxation_time_s(c, model), model)


@pytest.fixture(scope="module")
def lagrangian() -> Runs:
    return {c: _breakup(c, "lagrangian") for c in SEED_BREAKUP}


@pytest.fixture(scope="module")
def eulerian() -> Runs:
    return {c: _breakup(c, "eulerian") for c in SEED_CONCENTRATIONS_PCT}


@pytest.mark.parametrize("model", ["lagrangian", "eulerian"])
def test_the_relaxation_law_is_calibrated(model: str) -> None:
    table = load_table()
    law = table.law(model)
    assert law.status == "calibrated"
    lo, hi = table.lambda_ref_bounds_s
    assert lo <= law.lambda_ref_s <= hi
    lo, hi = table.exponent_bounds
    assert lo <= law.exponent <= hi


@pytest.mark.parametrize(
    "c",
    [
        0.15,
        pytest.param(
            1.0,
            marks=pytest.mark.xfail(
                raises=AssertionError,
                strict=True,
                reason="known gap: the Lagrangian 1 % breakup time is not continuous in λ (the "
                "thread holds or snaps), and the calibration's λ gives 338 µs with OpenBLAS's "
                "SkylakeX kernels, 122 µs with Haswell or SandyBridge (chaotic), not 230 µs",
            ),
        ),
    ],
)
def test_lagrangian_breakup_time_within_20_percent_of_the_seed(
    lagrangian: Runs, c: float, scaled
) -> None:
    t = scaled(lagrangian[c][0])
    assert t is not None
    assert t == pytest.approx(SEED_BREAKUP[c][0], rel=0.20)


@pytest.mark.parametrize("c", [0.15, 1.0])
def test_eulerian_breakup_time_within_20_percent_of_the_seed(
    eulerian: Runs, c: float, scaled
) -> None:
    t = scaled(eulerian[c][0])
    assert t is not None
    assert t == pytest.approx(SEED_BREAKUP[c][0], rel=0.20)


def test_eulerian_one_percent_pinches_at_the_nozzle_exit(eulerian: Runs) -> None:
    assert eulerian[1.0][1] == "exit"


# No test of the Lagrangian 1 % jet's mode: it is chaotic in the last bit of the banded
# solve. With OpenBLAS's SkylakeX kernels it first breaks behind the head (338 µs), with
# Haswell and SandyBridge it exit-pinches at 122 µs (the seed: at the exit). Its time
# misses the seed's 230 µs either way (the strict expected failure above).


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap: the Lagrangian model pinches 0.15 % NaAlg at the nozzle exit (98 µs), "
    "not behind the head as the seed observed",
)
def test_lagrangian_low_concentration_pinches_behind_the_head(lagrangian: Runs) -> None:
    assert lagrangian[0.15][1] == "front"


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap: with the meniscus retracting into the bore the Eulerian 0.15 % jet "
    "breaks at 83.4 µs 61 µm inside the bore (the law before the core's: 88 µs, 90 µm), where "
    "the retracted meniscus has "
    "pulled its root into a thread: an exit pinch, not the seed's front pinch",
)
def test_eulerian_low_concentration_pinches_behind_the_head(eulerian: Runs) -> None:
    assert eulerian[0.15][1] == "front"


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap: with the calibrated law the Lagrangian times rise from 0.15 % to 1 % "
    "(98, 100, 105, 338 µs), but the 1.5 % and 2 % jets do not break in 400 µs",
)
def test_lagrangian_breakup_time_rises_over_the_six_concentrations(lagrangian: Runs) -> None:
    times = [
        lagrangian[c][0] if c in lagrangian else _breakup(c, "lagrangian")[0]
        for c in SEED_CONCENTRATIONS_PCT
    ]
    assert all(t is not None for t in times), times
    assert all(a < b for a, b in itertools.pairwise(times)), times


def test_eulerian_breakup_time_rises_over_the_first_five_concentrations(eulerian: Runs) -> None:
    # 0.2, 0.25 and 1.5 % are predictions (the law was fitted at 0.15 and 1 %)
    times = [eulerian[c][0] for c in SEED_CONCENTRATIONS_PCT[:5]]
    assert all(t is not None for t in times), times
    assert all(a < b for a, b in itertools.pairwise(times)), times


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap: the Eulerian model with the core's law (issue 46) breaks 0.15-1.5 % at "
    "83.4, 86.1, 89.5, 238.5 and 287.3 µs, but the 2 % jet (assumed η0 65 mPa·s) does not "
    "break within 1 ms; it breaks after 1.5 % (306.6 µs) with η0 0.6x the assumed value, "
    "before it (246.5-276.6 µs) with 0.3-0.5x, and not at 0.7x or 0.8x",
)
def test_eulerian_breakup_time_rises_over_the_six_concentrations(eulerian: Runs) -> None:
    times = [eulerian[c][0] for c in SEED_CONCENTRATIONS_PCT]
    assert all(t is not None for t in times), times
    assert all(a < b for a, b in itertools.pairwise(times)), times


def test_eulerian_two_percent_needs_a_lower_viscosity_to_break_after_one_and_a_half(
    eulerian: Runs,
) -> None:
    # what would have to change for the six to rise (the closing note of issue 19)
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point
    from microfab.machines.printhead.sensitivity import SensitivityPoint, perturbed_fluid

    def at(factor: float) -> float | None:
        fluid = perturbed_fluid(SensitivityPoint(2.0, "zero_shear_viscosity", factor), "eulerian")
        res = run_point(SweepPoint(2.0, 50.0), DropletSettings(model="eulerian"), fluid=fluid)
        return res.breakup_time_s

    t_low, t_high = at(0.6), at(0.8)
    t15 = eulerian[1.5][0]
    assert t_low is not None and t15 is not None and t_low > t15
    assert t_high is None


def _within_1_ms(c: float) -> float | None:
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point

    res = run_point(SweepPoint(c, 50.0), DropletSettings(model="eulerian", duration_s=1e-3))
    return res.breakup_time_s


def test_eulerian_one_and_a_half_percent_breaks_within_1_ms_after_one(eulerian: Runs) -> None:
    # the acceptance: 1.5 % and 2 % break within 1 ms and later than 1 % (predicted)
    t15, t1 = _within_1_ms(1.5), eulerian[1.0][0]
    assert t15 is not None and t1 is not None
    assert t1 < t15 < 1e-3


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap: the Eulerian 2 % jet (assumed η0 65 mPa·s) is drawn back into the bore "
    "and does not break within 1 ms (it does with η0 0.3-0.6x the assumed value)",
)
def test_eulerian_two_percent_breaks_within_1_ms_after_one_and_a_half() -> None:
    t2, t15 = _within_1_ms(2.0), _within_1_ms(1.5)
    assert t2 is not None and t15 is not None
    assert t15 < t2 < 1e-3


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="known gap (issue 46): with the core's law the Eulerian jets at 50 V pinch 61, 77, "
    "95, 44 and 34 µm inside the bore (0.15-1.5 %; 2 % does not break), where a camera at "
    "the nozzle plate cannot see them; in all 313 inks the calibration tried, a pinch lay "
    "30-107 µm inside (the meniscus retracting into the bore, a structural finding)",
)
def test_eulerian_breakups_lie_outside_the_orifice() -> None:
    from microfab.machines.printhead.calibration import RIM_SLACK_UM
    from microfab.machines.printhead.machine import DropletSettings, SweepPoint, run_point

    # the five that break within 400 µs (2 % does not within 1 ms: its own test above)
    settings = DropletSettings(model="eulerian", duration_s=400e-6, after_breakup_s=2e-6)
    depth = {}
    for c in SEED_CONCENTRATIONS_PCT[:5]:
        res = run_point(SweepPoint(c, 50.0), settings)
        assert res.breakup_z_m is not None, c
        depth[c] = res.breakup_z_m * 1e6
    # z from the orifice, inside < 0; one camera pixel of slack (calibration's RIM check)
    assert all(z >= -RIM_SLACK_UM for z in depth.values()), depth
