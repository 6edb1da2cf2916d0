"""Model-inverse input shaper of seed 003 part 2 (§2): coefficients, ZOH, refusals, commands."""

from __future__ import annotations

import math
from decimal import Decimal

import numpy as np
import pytest
import scipy.signal

import control
from microfab.control.base import Feedforward
from microfab.control.shaping import (
    InverseShaperConfig,
    ShapedCommandError,
    check_shaped_command,
    design_inverse_shaper,
)
from microfab.control.shaping_metrics import (
    crossing_time,
    ramp_lag,
    ramp_speed_time,
    settling_time,
    step_response,
    step_settling_time,
)
from microfab.core.limits import AxisLimits, LimitViolation
from microfab.trajectory.base import Trajectory

DT = 1e-5  # seed 003 §2 "[fs = 1e-5]": the sample period
G = ((1.242e11,), (1.0, 9517.0, 5.773e7, 1.272e11))  # seed 003 §1
# seed 003 §2, "Input shaper (continuous)" and "(discrete)", as printed
SEED_NUM = ("3.99e17", "3.797e21", "2.303e25", "5.075e28")
SEED_DEN = ("1.272e11", "1.279e16", "4.82e20", "8.076e24", "5.075e28")
SEED_NUM_D = ("19.61", "-56.99", "55.26", "-17.88")
SEED_DEN_D = ("1", "-3.111", "3.63", "-1.882", "0.3659")
# the seed's 8.076e24 (= 4 p^3 a0) needs a0 in [1.27171e11, 1.27187e11], its 5.075e28
# (= p^4 a0) a0 in [1.27184e11, 1.27209e11]: the unrounded fit had a0 ~ 1.27185e11
A0_UNROUNDED = 1.27185e11


def printed_digits_match(value: float, printed: str) -> bool:
    """Whether ``value`` rounds to ``printed`` at the printed number of significant digits."""
    d = Decimal(printed)
    if d == 0:
        return abs(value) < 0.5 * 10.0 ** d.as_tuple().exponent
    ulp = Decimal(1).scaleb(d.adjusted() - len(d.as_tuple().digits) + 1)
    return abs(Decimal(repr(value)) - d) <= ulp / 2


@pytest.fixture(scope="module")
def shaper():
    return design_inverse_shaper(G)


def test_continuous_coefficients_have_the_seeds_printed_digits(shaper):
    # all but one match the seed from its printed model; 8.076e24 needs the unrounded a0
    misses = [
        (v, s)
        for v, s in zip((*shaper.num, *shaper.den), (*SEED_NUM, *SEED_DEN), strict=True)
        if not printed_digits_match(float(v), s)
    ]
    assert [s for _, s in misses] == ["8.076e24"]
    v, _ = misses[0]
    assert v == pytest.approx(8.076e24, rel=0.5 / 1272)  # within the printed a0's rounding
    unrounded = design_inverse_shaper((G[0], (*G[1][:3], A0_UNROUNDED)))
    for v, s in zip((*unrounded.num, *unrounded.den), (*SEED_NUM, *SEED_DEN), strict=True):
        assert printed_digits_match(float(v), s), (v, s)


def test_the_poles_are_at_2pi_4000_not_3000_rad_s():
    a0 = 1.272e11
    p_from_p4 = (5.075e28 / a0) ** 0.25  # seed's den s^0 over s^4
    p_from_4p = 1.279e16 / a0 / 4  # seed's den s^3 over s^4
    for p in (p_from_p4, p_from_4p):
        assert p == pytest.approx(2 * math.pi * 4000, rel=1e-3)
        assert p != pytest.approx(3000.0, rel=0.5)
    assert InverseShaperConfig().pole_rad_s == pytest.approx(2 * math.pi * 4000)


def test_discrete_coefficients_have_the_seeds_printed_digits(shaper):
    assert shaper.num_d[0] == 0.0  # strictly proper: one sample of delay, z^3 / z^4
    for v, s in zip(shaper.num_d[1:], SEED_NUM_D, strict=True):
        assert printed_digits_match(float(v), s), (v, s)
    for v, s in zip(shaper.den_d, SEED_DEN_D, strict=True):
        assert printed_digits_match(float(v), s), (v, s)


def test_seeds_printed_discrete_numerator_has_no_static_gain(shaper):
    printed_num = np.array([float(s) for s in SEED_NUM_D])
    # the printed numerator sums to 0 (a zero at z = 1): no static gain, taken literally
    assert abs(printed_num.sum()) < 1e-9
    # the exact filter's numerator sums to what its denominator does (unit static gain),
    # (1 - exp(-p dt))^4 = 0.00244: below the printed numerator's rounding (4 x 0.005),
    # so the filter must be built from the continuous design
    poles_sum = (1.0 - math.exp(-shaper.pole_rad_s * DT)) ** 4
    assert shaper.den_d.sum() == pytest.approx(poles_sum, rel=1e-9)
    assert shaper.num_d.sum() == pytest.approx(poles_sum, rel=1e-6)
    assert shaper.discrete_static_gain == pytest.approx(1.0, abs=1e-9)
    assert shaper.num_d.sum() < 4 * 0.005


def test_zoh_agrees_with_scipy_and_reproduces_the_continuous_step(shaper):
    b, a, _ = scipy.signal.cont2discrete((shaper.num, shaper.den), DT, "zoh")
    np.testing.assert_allclose(shaper.den_d, a / a[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(shaper.num_d, np.squeeze(b) / a[0], rtol=1e-9, atol=1e-11)
    k = np.arange(60)
    y = scipy.signal.lfilter(shaper.num_d, shaper.den_d, np.ones(k.size))
    np.testing.assert_allclose(y, step_response((shaper.num, shaper.den), k * DT), atol=1e-10)


def test_gain_peak_and_command_peak(shaper):
    # issue 16 §3: the inverse's gain peaks at 40.3 at 6.99 kHz; a step becomes 23.7x
    gain, f = shaper.gain_peak()
    assert f"{gain:.3g}" == "40.3"
    assert f"{f / 1e3:.3g}" == "6.99"
    w = 2 * np.pi * np.linspace(1e3, 2e4, 200001)
    _, h = scipy.signal.freqs(shaper.num, shaper.den, w)  # independent dense check
    assert gain == pytest.approx(np.abs(h).max(), rel=1e-7)
    assert f"{shaper.step_peak():.3g}" == "23.7"
    t = np.arange(0, 1e-4, 1e-9)
    _, ys = scipy.signal.step((shaper.num, shaper.den), T=t)
    assert shaper.step_peak() == pytest.approx(ys.max(), rel=1e-6)
    # on the 10 us samples: 19.61, 23.63, 20.21, ...
    assert shaper.step_peak(discrete=True) == pytest.approx(
        scipy.signal.lfilter(shaper.num_d, shaper.den_d, np.ones(20)).max(), rel=1e-12
    )


def test_shaped_axis_figures_and_shaper_lag(shaper):
    gs = shaper.overall()
    assert ramp_lag(gs) == pytest.approx(4 / shaper.pole_rad_s, rel=1e-9)
    assert shaper.lag() == pytest.approx(4 / shaper.pole_rad_s - ramp_lag(G), rel=1e-9)
    assert step_settling_time(gs) == pytest.approx(362e-6, rel=0.05)
    assert ramp_speed_time(gs) == pytest.approx(309e-6, rel=0.05)


def sampled_axis(cmd: np.ndarray) -> np.ndarray:
    """The seed model sampled at 10 us (ZOH), as the twin runs it."""
    b, a, _ = scipy.signal.cont2discrete(G, DT, "zoh")
    return scipy.signal.lfilter(np.squeeze(b), a, cmd)


def test_on_the_sampled_axis_zoh_misses_and_zpetc_keeps_the_continuous_figures():
    step = np.r_[np.zeros(10), np.ones(400)]
    zoh = design_inverse_shaper(G)
    zpetc = design_inverse_shaper(G, InverseShaperConfig(discretization="zpetc"))
    assert zpetc.preview == 2  # the sampled plant's delay and its zero at -3.644
    assert zpetc.discrete_static_gain == pytest.approx(1.0, abs=1e-9)
    y_zoh = sampled_axis(zoh.shape(step))[10:]
    y_zp = sampled_axis(zpetc.shape(step))[10:]
    # the seed's ZOH filter through the 10 us staircase no longer cancels G's poles
    assert settling_time(y_zoh, DT) > 1.5 * 362e-6
    # the inverse of the sampled axis does: 362 us and 309 us as the continuous design
    assert settling_time(y_zp, DT) == pytest.approx(362e-6, rel=0.05)
    assert crossing_time(y_zp, DT, 0.95 * y_zp[-1]) == pytest.approx(309e-6, rel=0.05)
    # ramp lag of the sampled chain: 4/p plus the plant's half sample
    k = np.arange(3000.0)
    y = sampled_axis(zpetc.shape(k, tail=0))
    g0 = y[-1] - y[-2]
    assert (k[-1] - y[-1] / g0) * DT == pytest.approx(4 / zpetc.pole_rad_s + DT / 2, rel=1e-6)


def test_shape_keeps_a_held_offset_and_refuses_leaving_the_field(shaper):
    held = np.full(50, 5000.0)
    np.testing.assert_allclose(shaper.shape(held, tail=0), held, atol=1e-7)
    jump = np.r_[np.zeros(10), np.full(100, 1000.0)]  # 1000 bit: 23.6k bit peak, fits
    out = shaper.shape(jump, bounds=(-32768, 32767), unit="bit")
    assert out.shape == (110 + shaper.tail_samples(),)
    assert out[-1] == pytest.approx(1000.0, abs=1e-6)
    both = np.column_stack([jump, 2 * jump])  # 2000 bit: 47k bit, outside the field
    with pytest.raises(ShapedCommandError, match=r"axis y: .* at t = 0\.00011 s .* 32767 bit"):
        shaper.shape(both, axes=("x", "y"), bounds=(-32768, 32767), unit="bit")
    with pytest.raises(LimitViolation, match="axis x: velocity"):
        shaper.shape(jump, limits={"x": AxisLimits(position=4e4, velocity=1e8, acceleration=1e20)})
    with pytest.raises(ValueError, match="dt = 2e-05 s differs"):
        shaper.shape(jump, dt=2e-5)


def test_check_shaped_command_names_axis_time_value_and_bound():
    cmd = np.zeros((5, 2))
    cmd[3, 1] = -40000.0
    with pytest.raises(ShapedCommandError) as e:
        check_shaped_command(cmd, DT, axes=("x", "y"), bounds={"x": (-1, 1), "y": (-32768, 32767)})
    msg = str(e.value)
    assert "axis y" in msg and "t = 3e-05 s" in msg and "-40000" in msg and "-32768" in msg


def test_periodic_shaping_is_the_steady_state_of_a_long_run(shaper):
    n = 200
    period = np.where(np.arange(n) < n // 2, 1000.0, -1000.0)
    steady = shaper.shape(period, periodic=True)
    long = scipy.signal.lfilter(shaper.num_d, shaper.den_d, np.tile(period, 10))
    np.testing.assert_allclose(steady, long[-n:], atol=1e-8)


def test_feedforward_and_lti(shaper):
    assert isinstance(shaper, Feedforward)
    pos = np.column_stack([np.r_[np.zeros(5), np.ones(30)], np.zeros(35)])
    traj = Trajectory(dt=DT, position=pos)
    out = shaper.apply(traj)
    assert out.n_samples == 35 + shaper.tail_samples()
    np.testing.assert_allclose(out.position[:35, 0], shaper.shape(pos[:, 0], tail=0), atol=1e-12)
    assert out.meta["shaper"] == "inverse-zoh"
    f = np.array([100.0, 5000.0, 20000.0])
    lti = shaper.to_lti()
    np.testing.assert_allclose(
        lti.frequency_response(f)[:, 0, 0], shaper.frequency_response(f, discrete=True), rtol=1e-9
    )


def test_vibration_of_the_inverse_at_a_mirror_mode(shaper):
    # the inverse amplifies an unmodelled 3 kHz mode (zeta 0.02, issue 16 §1 option)
    v = shaper.vibration(3000.0, 0.02)[0]
    s = complex(-0.02 * 2 * np.pi * 3000, 2 * np.pi * 3000 * math.sqrt(1 - 0.02**2))
    expect = abs(np.polyval(shaper.num, s) / np.polyval(shaper.den, s))
    assert v == pytest.approx(expect, rel=1e-12)
    assert v > 1.0


@pytest.mark.parametrize(
    "model, cfg, match",
    [
        (((1.0, -1000.0), (1.0, 100.0, 1e6)), None, "right half-plane"),
        (((1.0, 0.0), (1.0, 100.0, 1e6)), None, "imaginary axis"),
        (((1.0,), (1.0, -10.0)), None, "not in the left half-plane"),
        (((1.0,), (1.0, 0.0)), None, "not in the left half-plane"),
        (G, InverseShaperConfig(order=2), "improper"),
        (G, InverseShaperConfig(pole_hz=500.0), "not faster than the model's fastest pole"),
        (control.tf(*G), InverseShaperConfig(pole_hz=900.0), "above 965"),
    ],
)
def test_design_refusals(model, cfg, match):
    with pytest.raises(ValueError, match=match):
        design_inverse_shaper(model, cfg)


def test_config_refusals():
    with pytest.raises(ValueError, match="Nyquist"):
        InverseShaperConfig(pole_hz=60e3)
    with pytest.raises(ValueError, match="discretization"):
        InverseShaperConfig(discretization="tustin")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="order"):
        InverseShaperConfig(order=0)


def test_tail_samples_refuses_a_filter_that_never_settles():
    # fuzz: at dt = 1 µs the rounded ZOH filter settles 1e-8 off its static gain, and the
    # search for the settled tail doubled its length until memory ran out
    fine = design_inverse_shaper(G, InverseShaperConfig(dt=1e-6))
    with pytest.raises(ValueError, match=r"does not settle within 1e-09 .* use a longer dt"):
        fine.tail_samples()
    assert 0 < design_inverse_shaper(G, InverseShaperConfig(dt=DT)).tail_samples() < 1000
