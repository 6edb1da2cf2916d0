"""The stage friction law (LuGre + cogging + cable carrier) shared by the seed 002 and 004 twins."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.plants.friction import N_FRICTION, StageFriction, bristle_step, friction_force
from microfab.plants.lmw_stage import lmw_stage_twin
from microfab.plants.lmw_stage_params import _BLOCK as LMW_BLOCK
from microfab.plants.lmw_stage_params import _FRIC as LMW_FRIC
from microfab.plants.lmw_stage_params import _HEADER as LMW_HEADER
from microfab.plants.xy_stage import xy_stage_twin
from microfab.plants.xy_stage_params import _BLOCK as XY_BLOCK
from microfab.plants.xy_stage_params import _FRIC as XY_FRIC
from microfab.plants.xy_stage_params import _HEADER as XY_HEADER

# the seed 004 twin's x axis as assumed before issue 45's calibration (data/lmw_stage.toml)
X_AXIS = {
    "coulomb_n": 0.15,
    "static_n": 0.225,
    "stribeck_m_s": 1.0e-3,
    "bristle_stiffness_n_per_m": 1.5e5,
    "bristle_damping_n_s_per_m": 100.0,
    "viscous_n_s_per_m": 1.0,
    "cogging_n": 0.02,
    "cogging_pitch_m": 0.024,
    "cogging_phase_rad": 0.0,
    "cable_stiffness_n_per_m": 10.0,
    "cable_rest_m": 0.01,
}


def law(**changes) -> StageFriction:
    return StageFriction(axis="x", **{**X_AXIS, **changes})


def test_the_law_against_hand_computed_values():
    f = law()
    # at rest with the bristles deflected 1 µm, a quarter pitch out (sin = 1):
    # F = σ0 z + A + k (x - x_rest) = 0.15 + 0.02 + 10 (0.006 - 0.01) = 0.13 N, g = F_s
    F, zd, g = f.force(0.006, 0.0, 1e-6)
    assert F == pytest.approx(0.13, abs=1e-15)
    assert zd == 0.0
    assert g == pytest.approx(0.225, abs=1e-15)
    # at v = v_s with relaxed bristles, at the cable's rest where the ripple is sin(5π/6):
    # g = 0.15 + 0.075 / e, ż = v, F = σ1 v + σ2 v + 0.02 * 0.5 = 0.1 + 0.001 + 0.01 N
    F, zd, g = f.force(0.01, 1e-3, 0.0)
    assert g == pytest.approx(0.15 + 0.075 / math.e, rel=1e-15)
    assert zd == 1e-3
    assert F == pytest.approx(0.111, rel=1e-14)


def test_steady_sliding_gives_the_stribeck_curve():
    """At ż = 0 (z = g(v) / σ0 sign v) LuGre's force is g(v) sign v + σ2 v."""
    f = law(cogging=False, cable=False)
    for v in (-0.05, -1e-3, 2e-4, 1e-3, 0.1):
        g = 0.15 + 0.075 * math.exp(-((v / 1e-3) ** 2))
        F, zd, gg = f.force(0.0, v, math.copysign(g / 1.5e5, v))
        assert gg == pytest.approx(g, rel=1e-15)
        assert zd == pytest.approx(0.0, abs=1e-15 * abs(v))
        assert F == pytest.approx(math.copysign(g, v) + 1.0 * v, rel=1e-12)


def test_switches_and_the_link_ripple():
    assert law(friction=False, cogging=False, cable=False).force(0.3, 0.2, 1e-6) == (0.0, 0.0, 1.0)
    # the link ripple adds A_l sin(2π x / p_l + φ_l) to the cable's spring
    off = law(friction=False, cogging=False)
    on = law(friction=False, cogging=False, cable_link_force_n=3.0, cable_link_pitch_m=0.018,
             cable_link_phase_rad=0.3)  # fmt: skip
    x = 0.004
    ripple = 3.0 * math.sin(2 * math.pi * x / 0.018 + 0.3)
    assert on.force(x, 0.0, 0.0)[0] - off.force(x, 0.0, 0.0)[0] == pytest.approx(ripple, rel=1e-12)
    assert off.force(x, 0.0, 0.0)[0] == pytest.approx(10.0 * (x - 0.01), rel=1e-15)


def test_bristle_step_is_the_exact_solution():
    """dz/dx = 1 - σ0 z / g for dx > 0: z = g/σ0 + (z0 - g/σ0) exp(-σ0 dx / g)."""
    f = law()
    g, s0 = 0.2, 1.5e5
    for z0, dx in ((0.0, 1e-6), (-1e-6, 3e-6), (5e-7, -2e-6)):
        zss = math.copysign(g / s0, dx)
        want = zss + (z0 - zss) * math.exp(-s0 * abs(dx) / g)
        assert f.bristle(z0, dx, g) == pytest.approx(want, rel=1e-15)
    assert f.bristle(3e-7, 0.0, g) == 3e-7
    # many small steps of the bristle ODE reach the same deflection
    z, n = -1e-6, 20000
    h = 3e-6 / n
    for _ in range(n):
        z += h * (1.0 - s0 * z / g)
    assert f.bristle(-1e-6, 3e-6, g) == pytest.approx(z, rel=1e-4)


def test_pack_and_kernels_read_the_same_block():
    f = law()
    p = np.array([7.0, 7.0, *f.pack()])
    assert len(f.pack()) == N_FRICTION
    assert friction_force(p, 2, 0.006, 2e-4, 3e-7) == f.force(0.006, 2e-4, 3e-7)
    assert bristle_step(p, 2, 3e-7, 1e-6, 0.2) == f.bristle(3e-7, 1e-6, 0.2)


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"static_n": 0.1}, r"static_n\[x\] = 0\.1 N is below coulomb_n\[x\] = 0\.15 N"),
        ({"coulomb_n": 0.0, "static_n": 0.0}, r"coulomb_n\[x\] = 0 N with friction on"),
        ({"stribeck_m_s": 0.0}, r"stribeck_m_s\[x\] must be positive"),
        ({"bristle_damping_n_s_per_m": -1.0}, r"bristle_damping_n_s_per_m\[x\] must be non-neg"),
        ({"cogging_phase_rad": float("nan")}, r"cogging_phase_rad\[x\]"),
        ({"cable_link_pitch_m": 0.0}, r"cable_link_pitch_m\[x\] must be positive"),
        ({"cable": 1}, "switch cable must be true or false"),
    ],
)
def test_bad_values_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        law(**changes)


def test_no_coulomb_force_is_allowed_with_friction_off():
    assert law(coulomb_n=0.0, static_n=0.0, friction=False).coulomb_n == 0.0


def test_per_axis_laws_from_pairs():
    pairs = {k: (v, 2 * v) for k, v in X_AXIS.items() if not k.startswith("cable")}
    x, y = StageFriction.per_axis(pairs, each=({"cable": False}, {"cable_rest_m": 0.5}))
    assert (x.axis, y.axis, x.cable, y.cable) == ("x", "y", False, True)
    assert (x.static_n, y.static_n, y.cable_rest_m) == (0.225, 0.45, 0.5)
    with pytest.raises(ValueError, match="coulomb_n needs one value per axis"):
        StageFriction.per_axis({**pairs, "coulomb_n": (0.1,)})
    with pytest.raises(ValueError, match=r"static_n\[y\] = 0\.2 N is below coulomb_n\[y\]"):
        StageFriction.per_axis({**pairs, "static_n": (0.225, 0.2)})


def test_both_twins_pack_their_laws_into_the_kernels():
    lmw = lmw_stage_twin()
    xy = xy_stage_twin()
    for a in range(2):
        b = LMW_HEADER + a * LMW_BLOCK + LMW_FRIC
        np.testing.assert_array_equal(
            lmw.params[b : b + N_FRICTION], lmw.config.friction_laws[a].pack()
        )
        b = XY_HEADER + a * XY_BLOCK + XY_FRIC
        np.testing.assert_array_equal(
            xy.params[b : b + N_FRICTION], xy.config.friction_laws[a].pack()
        )
    # the data file's x axis: three values calibrated by `microfab calibrate laser`
    calibrated = {
        "static_n": 0.36989,
        "stribeck_m_s": 1.0649e-4,
        "bristle_stiffness_n_per_m": 1.0448e7,
    }
    assert lmw.config.friction_laws[0] == law(**calibrated)
    # the cable carrier is on y only in the seed 002 twin, with its links' ripple
    x, y = xy.config.friction_laws
    assert not x.cable and y.cable and y.cable_link_force_n == xy.config.cable_link_force_n
    # the twin's stored disturbance at rest is the law's force, scaled
    s = lmw.state_at((0.004, -0.002))
    want = [lmw.config.disturbance_scale * lmw.config.friction_laws[a].force(p, 0.0, 0.0)[0]
            for a, p in enumerate((0.004, -0.002))]  # fmt: skip
    np.testing.assert_array_equal(lmw.disturbance(s), want)
