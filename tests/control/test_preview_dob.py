"""Preview + DOB (seed 004 eqs. 3-4): DOB estimate of a force step, acceleration
feedforward, mass mismatch, linear model == kernel == Python, refusals."""

from __future__ import annotations

import numpy as np
import pytest

import control
from microfab.control.base import Loop
from microfab.control.preview_dob import (
    PreviewDOB,
    PreviewDOBConfig,
    nominal_closed_loop_poles,
)
from microfab.control.velocity import VelocityEstimator
from microfab.plants.base import LTIPlant
from microfab.plants.friction import StageFriction
from microfab.plants.lti import DiscreteLTI, block_diag, discretize
from microfab.sim.loop import LoopState, reference_array, simulate, simulate_python

DT = 1e-4  # assumed 10 kHz (the seed 004 twin's contract)
MASS = (1.2, 0.6)  # kg: x carries y; seed 004 Table I single stage 0.6 kg
KF = (10.0, 8.0)  # N/A, assumed for the stand-in (the seed gives none)
AMP_LAG = 20e-6  # s, assumed current amplifier lag of the stand-in


def axis_plant(m: float, k: float, lag: float) -> DiscreteLTI:
    """Stand-in axis: ``m ẍ = k i_a − F_l``, ``τ i̇_a = i − i_a``, ``F_l`` a constant state.

    States ``(x, v, i_a, F_l)``, input ``i`` (A), output ``x`` (m); ZOH at DT.
    """
    A = [[0, 1, 0, 0], [0, 0, k / m, -1 / m], [0, 0, -1 / lag, 0], [0, 0, 0, 0]]
    B = [[0], [0], [1 / lag], [0]]
    return discretize(control.ss(A, B, [[1, 0, 0, 0]], [[0]]), DT, "zoh")


def stage(scale: float = 1.0, lag: float = AMP_LAG) -> LTIPlant:
    return LTIPlant(
        block_diag(*(axis_plant(scale * m, k, lag) for m, k in zip(MASS, KF, strict=True)))
    )


def config(**kw) -> PreviewDOBConfig:
    return PreviewDOBConfig(mass_kg=MASS, force_constant_n_per_a=KF, **kw)


def circle(laps: float, radius: float = 100e-6, speed: float = 10e-3) -> tuple:
    """Circle at constant speed, shifted to start at the origin (where the stage rests)."""
    w = speed / radius
    n = round(laps * 2 * np.pi / w / DT)
    t = np.arange(n) * DT
    pos = radius * np.column_stack([np.cos(w * t) - 1.0, np.sin(w * t)])
    vel = radius * w * np.column_stack([-np.sin(w * t), np.cos(w * t)])
    acc = -(w**2) * radius * np.column_stack([np.cos(w * t), np.sin(w * t)])
    return pos, vel, acc


def max_error_after_first_lap(plant, ctrl, laps: int = 3) -> float:
    pos, vel, acc = circle(laps)
    res = simulate(plant, ctrl, pos, derivatives=(vel, acc))
    err = np.linalg.norm(res.output - pos, axis=1)
    assert np.all(np.isfinite(err))
    return float(err[len(pos) // laps :].max())


def test_dob_estimates_a_force_step_as_q_step_response():
    """1 N load force on both axes from t = 0, stage at rest, reference at rest."""
    cfg = config()
    ctrl = PreviewDOB(cfg)
    plant = stage(lag=5e-6)  # a fast amplifier: its lag enters the estimate (20 µs: 2.3 %)
    n = 400
    ref = np.zeros((n, 2))
    st = LoopState.at_rest(plant, Loop(controller=ctrl))
    st.plant[3] = st.plant[7] = 1.0  # F_l of x and y, N
    res = simulate(plant, ctrl, ref, state=st, derivatives=(ref, ref))
    log = ctrl.replay(reference_array(ref, (ref, ref)), res.measured)
    np.testing.assert_array_equal(log.command, res.command)
    q = control.tf([cfg.g1], [1.0, cfg.g2, cfg.g1])
    _, q_step = control.step_response(q, np.arange(n) * DT)
    for a in range(2):
        assert np.max(np.abs(log.disturbance[:, a] - q_step)) <= 0.02  # N, of a 1 N step
    assert log.disturbance[-1] == pytest.approx([1.0, 1.0], abs=1e-3)
    # the read-out of the final state is the last sample's estimate
    np.testing.assert_allclose(
        ctrl.disturbance_estimate(res.final_state.controller), log.disturbance[-1], rtol=1e-12
    )
    # and the DOB is what holds the stage: without it the force pushes it 10x further
    res0 = simulate(plant, PreviewDOB(cfg.with_(dob=False)), ref, state=st, derivatives=(ref, ref))
    assert np.abs(res0.output[-1]).min() > 10 * np.abs(res.output[-1]).max()


def test_acceleration_feedforward_cuts_the_circle_error_twentyfold():
    """100 µm circle at 10 mm/s (seed 004 Fig. 7's), K_a = 1 against K_a = 0."""
    plant = stage()
    e1 = max_error_after_first_lap(plant, PreviewDOB(config()))
    e0 = max_error_after_first_lap(plant, PreviewDOB(config(k_a=0.0)))
    assert e1 * 20 <= e0
    # K_a = 0 leaves a ≈ |r̈| / K_p = 1 m/s² / ω_c²: the loop is what the gains say
    assert e0 == pytest.approx(1.0 / config().k_p, rel=0.1)
    epd = max_error_after_first_lap(plant, PreviewDOB(PreviewDOBConfig.pd_only(
        mass_kg=MASS, force_constant_n_per_a=KF)))  # fmt: skip
    assert e1 * 20 <= epd


@pytest.mark.parametrize("scale", [0.7, 1.3])
def test_thirty_percent_mass_mismatch_still_tracks(scale: float):
    plant = stage(scale=scale)
    e = max_error_after_first_lap(plant, PreviewDOB(config()), laps=4)
    e0 = max_error_after_first_lap(plant, PreviewDOB(config(k_a=0.0)), laps=4)
    assert e <= 0.05 * e0  # bounded, and still well below the loop without feedforward


def test_linear_model_reproduces_the_kernel_commands():
    ctrl = PreviewDOB(config())
    rng = np.random.default_rng(4)
    n = 500
    R = np.zeros((n, 3, 2))
    ym = np.zeros((n, 2))
    R[1:] = rng.standard_normal((n - 1, 3, 2)) * [[1e-4], [1e-2], [1.0]]
    ym[1:] = rng.standard_normal((n - 1, 2)) * 1e-4  # inputs start at zero (module)
    log = ctrl.replay(R, ym)
    for a in range(2):
        lm = ctrl.linear_model(a)
        assert lm.input_names == ("x_ref", "v_ref", "a_ref", "x_fb")
        u_in = np.column_stack([R[:, 0, a], R[:, 1, a], R[:, 2, a], ym[:, a]])
        s = np.zeros(lm.n_states)
        out = np.empty(n)
        for k in range(n):
            out[k] = (lm.C @ s + lm.D @ u_in[k])[0]
            s = lm.A @ s + lm.B @ u_in[k]
        scale = np.max(np.abs(log.command[:, a]))
        assert np.max(np.abs(out - log.command[:, a])) <= 1e-12 * scale


def test_linear_closed_loop_matches_the_per_sample_loop():
    """The closed loop built from the linear plant and linear_model (what an experiment
    checks the per-sample loop against)."""
    cfg = config()
    ctrl = PreviewDOB(cfg)
    # one sample at rest first: the kernel sets its filters to rest at their first
    # inputs, the linear model starts from zero; from inputs at zero the two agree
    pos, vel, acc = (np.vstack([np.zeros((1, 2)), s]) for s in circle(1.0))
    res = simulate(stage(), ctrl, pos, derivatives=(vel, acc))
    for a in range(2):
        P = axis_plant(MASS[a], KF[a], AMP_LAG)
        Cm = ctrl.linear_model(a)
        p = control.ss(P.A, P.B, P.C, P.D, DT)
        c = control.ss(Cm.A, Cm.B, Cm.C, Cm.D, DT)
        # plant input from the controller's output, controller's x_fb from the plant
        cl = control.interconnect(
            [control.ss(p, inputs="i", outputs="x", name="p"),
             control.ss(c, inputs=["r", "v", "ac", "x"], outputs="i", name="c")],
            inplist=["r", "v", "ac"], outlist=["x", "i"],
        )  # fmt: skip
        t = np.arange(len(pos)) * DT
        resp = control.forced_response(cl, t, np.vstack([pos[:, a], vel[:, a], acc[:, a]]))
        for i, sig in enumerate((res.output[:, a], res.command[:, a])):
            scale = np.max(np.abs(sig))
            assert np.max(np.abs(resp.outputs[i] - sig)) <= 1e-9 * scale


def friction_laws() -> tuple[StageFriction, ...]:
    """LuGre friction only, per axis (values of the seed 004 twin's x axis, assumed there)."""
    law = StageFriction(
        coulomb_n=0.15, static_n=0.225, stribeck_m_s=1e-3, bristle_stiffness_n_per_m=1.5e5,
        bristle_damping_n_s_per_m=100.0, viscous_n_s_per_m=1.0, cogging_n=0.0,
        cogging_pitch_m=0.024, cogging_phase_rad=0.0, cogging=False, cable=False,
    )  # fmt: skip
    return (law, law)


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"dob": False},
        {"k_a": 0.0, "match_velocity_filter": False},
        {"friction_ff": "laws", "friction_ff_scale": 2.0},
        {"friction_ff": "laws", "dob": False},
    ],
)
def test_kernel_and_python_step_agree(kw):
    if kw.get("friction_ff") == "laws":
        kw = {**kw, "friction_ff": friction_laws()}
    ctrl = PreviewDOB(config(**kw))
    pos, vel, acc = circle(0.5)
    plant = stage()
    st = LoopState.at_rest(plant, Loop(controller=ctrl))
    st.plant[3], st.plant[7] = 0.3, -0.2  # a load force too
    fast = simulate(plant, ctrl, pos, state=st, derivatives=(vel, acc))
    slow = simulate_python(plant, ctrl, pos, state=st.copy(), derivatives=(vel, acc))
    for sig in ("output", "command"):
        a, b = getattr(fast, sig), getattr(slow, sig)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), sig
    # the read-outs are parts of the command: compared at the command's scale (the DOB's
    # high-gain Q s² turns the loops' last-bit differences into ~1e-12 of its own value)
    a, b = fast.final_state.controller, slow.final_state.controller
    i_max = np.max(np.abs(slow.command), axis=0)
    for read, scale in (
        (ctrl.disturbance_estimate, np.array(KF) * i_max),  # N
        (ctrl.acceleration_demand, i_max * np.array(KF) / np.array(MASS)),  # m/s²
    ):
        assert np.all(np.abs(read(a) - read(b)) <= 1e-12 * scale), read.__name__
    va, vb = ctrl.velocity_estimate(a), ctrl.velocity_estimate(b)
    assert np.max(np.abs(va - vb)) <= 1e-12 * np.max(np.abs(vel))


def test_nominal_loop_poles_and_gains_from_bandwidths():
    cfg = config()
    assert cfg.k_p == pytest.approx((2 * np.pi * 50.0) ** 2)
    assert cfg.k_v == pytest.approx(2 * 1.0 * 2 * np.pi * 50.0)
    assert cfg.g1 == pytest.approx((2 * np.pi * 500.0) ** 2)
    assert cfg.g2 == pytest.approx(2 * 1.0 * 2 * np.pi * 500.0)
    for a in range(2):
        assert np.max(np.abs(nominal_closed_loop_poles(cfg, a))) < 1.0
    pd = PreviewDOBConfig.pd_only(mass_kg=MASS, force_constant_n_per_a=KF)
    assert (pd.k_a, pd.dob) == (0.0, False)


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"mass_kg": (1.2, -0.6)}, ["mass_kg", "-0.6", "kg"]),
        ({"mass_kg": (1.2,)}, ["one value per axis"]),
        ({"force_constant_n_per_a": (0.0, 8.0)}, ["K_fn", "N/A"]),
        ({"bandwidth_hz": 0.0}, ["bandwidth_hz", "Hz"]),
        ({"damping": -1.0}, ["damping"]),
        ({"dob_bandwidth_hz": 5000.0}, ["dob_bandwidth_hz", "Nyquist", "5000", "lower it"]),
        ({"dob_damping": 0.0}, ["dob_damping"]),
        ({"k_a": -1.0}, ["k_a"]),
        ({"bandwidth_hz": 1500.0}, ["unstable", "pole magnitude", "lower"]),
        ({"dob": 1}, ["dob", "true or false"]),
        ({"estimator": VelocityEstimator(bandwidth_hz=6000.0)}, ["Nyquist"]),
    ],
)
def test_refusals_name_parameter_value_and_fix(kw, words):
    args = {"mass_kg": MASS, "force_constant_n_per_a": KF, **kw}
    with pytest.raises(ValueError) as err:
        PreviewDOBConfig(**args)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_reference_without_acceleration_is_refused():
    ctrl = PreviewDOB(config())
    pos, vel, _ = circle(0.1)
    with pytest.raises(ValueError, match="velocity and acceleration"):
        simulate(stage(), ctrl, pos, derivatives=(vel,))


def ramp(n: int, speed: float) -> tuple:
    """Accelerate for 20 ms to ``speed`` along x (y at rest), then cruise; n samples."""
    t = np.arange(n) * DT
    ta = 0.02
    a = speed / ta
    v = np.where(t < ta, a * t, speed)
    x = np.where(t < ta, 0.5 * a * t**2, 0.5 * a * ta**2 + speed * (t - ta))
    acc = np.where(t < ta, a, 0.0)
    z = np.zeros(n)
    return np.column_stack([x, z]), np.column_stack([v, z]), np.column_stack([acc, z])


@pytest.mark.parametrize("dob", [True, False])
def test_friction_feedforward_passes_the_dob_only_what_it_leaves(dob):
    """On a plant without friction the feedforward is a wrong force: with the DOB it sees
    the current less the feedforward, so the DOB takes the feedforward's steady part back
    out (position as without it); without DOB the position loop must hold the
    feedforward's force with a steady error ``F_ff / (M K_p)``. At cruise the plant needs
    no force, so the command ends as the plain one's either way."""
    pos, vel, acc = ramp(3000, 2e-3)
    plant = stage()
    laws = friction_laws()
    plain = simulate(plant, PreviewDOB(config(dob=dob)), pos, derivatives=(vel, acc))
    ff = simulate(plant, PreviewDOB(config(dob=dob, friction_ff=laws)), pos,
                  derivatives=(vel, acc))  # fmt: skip
    f_ss, _zd, _g = laws[0].force(0.0, 2e-3, laws[0].coulomb_n / 1.5e5)
    i_ff = f_ss / KF[0]  # the feedforward's steady current, A (0.15 N + 2 mN)
    gap = abs(ff.command[-1, 0] - plain.command[-1, 0])
    err = abs(ff.output[-1, 0] - plain.output[-1, 0])
    assert gap <= 1e-3 * i_ff, gap
    if dob:
        assert err <= 1e-10, err  # measured 3e-13 m
    else:
        k_p = config().k_p
        assert err == pytest.approx(f_ss / MASS[0] / k_p, rel=0.05)  # F_ff / (M K_p)


def test_friction_feedforward_refusals():
    with pytest.raises(ValueError, match="one per axis"):
        config(friction_ff=friction_laws()[:1])
    with pytest.raises(ValueError, match="StageFriction"):
        config(friction_ff=(1.0, 2.0))
    with pytest.raises(ValueError, match="friction_ff_scale"):
        config(friction_ff=friction_laws(), friction_ff_scale=-1.0)
