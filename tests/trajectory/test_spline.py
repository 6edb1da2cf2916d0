"""Time-based cubic spline of seed 004 eq. (1): continuity, ends, exact maxima, sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from microfab.trajectory.spline import TimeSpline

RNG_SEED = 4


def knots_and_points(k: int = 9, seed: int = RNG_SEED) -> tuple[np.ndarray, np.ndarray]:
    """Irregular times (s) and a smooth-ish 2-D point sequence (m)."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.02, 0.08, k))])
    p = np.column_stack([0.01 * np.sin(7 * t), 0.02 * np.cos(5 * t) + 0.003 * t])
    p += rng.normal(0.0, 1e-4, p.shape)
    return t, p


def one_sided(sp: TimeSpline, n: int, at_end: bool) -> np.ndarray:
    """Value, 1st and 2nd derivative of piece ``n`` at its start or its end, from eq. (1)."""
    tau = sp.knots[n + 1] - sp.knots[n] if at_end else 0.0
    a, b, c, d = sp.alpha[n], sp.beta[n], sp.gamma[n], sp.delta[n]
    return np.stack(
        [
            a * tau**3 + b * tau**2 + c * tau + d,
            3 * a * tau**2 + 2 * b * tau + c,
            6 * a * tau + 2 * b,
        ]
    )


@pytest.mark.parametrize("bc", ["clamped", "natural", "rest"])
def test_c2_continuity_at_knots(bc: str) -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc=bc)
    dense = np.linspace(t[0], t[-1], 20001)
    scale = [np.max(np.abs(sp.evaluate(dense, m)), axis=0) for m in range(3)]
    for n in range(sp.n_pieces - 1):
        left, right = one_sided(sp, n, True), one_sided(sp, n + 1, False)
        for m in range(3):
            np.testing.assert_allclose(left[m], right[m], rtol=0, atol=1e-9 * scale[m].max())


@pytest.mark.parametrize("bc", ["clamped", "natural", "rest", "periodic"])
def test_interpolates_the_points(bc: str) -> None:
    t, p = knots_and_points()
    if bc == "periodic":
        p[-1] = p[0]
    sp = TimeSpline.fit(t, p, bc=bc)
    np.testing.assert_allclose(sp.evaluate(t), p, rtol=0, atol=1e-12)


def test_clamped_ends_are_at_rest_and_match_scipy() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="clamped")
    ends = sp.evaluate(t[[0, -1]], 1)
    np.testing.assert_allclose(ends, 0.0, atol=1e-12)
    # an independent reference: SciPy's clamped spline evaluated directly
    ref = CubicSpline(t, p, bc_type="clamped")
    tt = np.random.default_rng(1).uniform(t[0], t[-1], 500)
    for m in range(4):
        np.testing.assert_allclose(sp.evaluate(tt, m), ref(tt, m), rtol=1e-9, atol=1e-12)


def test_clamped_with_end_velocity() -> None:
    t, p = knots_and_points()
    v = np.array([[0.1, -0.2], [0.05, 0.3]])
    sp = TimeSpline.fit(t, p, bc="clamped", end_velocity=v)
    np.testing.assert_allclose(sp.evaluate(t[[0, -1]], 1), v, atol=1e-12)


def test_rest_ends_have_zero_velocity_and_acceleration() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="rest")
    assert sp.n_pieces == t.size + 1  # one extra break in the first and in the last interval
    for m in (1, 2):
        np.testing.assert_allclose(sp.evaluate(t[[0, -1]], m), 0.0, atol=1e-9)
    sp2 = TimeSpline.fit(t, p, bc="rest", rest_breaks=(t[0] + 0.1 * (t[1] - t[0]), t[-1] - 1e-3))
    np.testing.assert_allclose(sp2.evaluate(t), p, atol=1e-12)
    np.testing.assert_allclose(sp2.evaluate(t[[0, -1]], 2), 0.0, atol=1e-8)


def test_natural_ends_have_zero_acceleration() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="natural")
    np.testing.assert_allclose(sp.evaluate(t[[0, -1]], 2), 0.0, atol=1e-9)


def test_coefficients_reproduce_eq1() -> None:
    """x_n(t) = α t³ + β t² + γ t + δ with t local to piece n (seed 004 eq. (1))."""
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="clamped")
    tt = np.random.default_rng(2).uniform(t[0], t[-1], 300)
    n = np.searchsorted(t, tt, side="right") - 1
    tau = (tt - t[n])[:, None]
    a, b, c, d = sp.alpha[n], sp.beta[n], sp.gamma[n], sp.delta[n]
    np.testing.assert_allclose(sp.evaluate(tt, 0), a * tau**3 + b * tau**2 + c * tau + d)
    np.testing.assert_allclose(sp.evaluate(tt, 1), 3 * a * tau**2 + 2 * b * tau + c)
    np.testing.assert_allclose(sp.evaluate(tt, 2), 6 * a * tau + 2 * b)
    np.testing.assert_allclose(sp.evaluate(tt, 3), 6 * a)
    for arr in (sp.alpha, sp.beta, sp.gamma, sp.delta, sp.knots):
        assert not arr.flags.writeable


@pytest.mark.parametrize("bc", ["clamped", "natural", "rest"])
def test_max_abs_agrees_with_dense_evaluation(bc: str) -> None:
    t, p = knots_and_points(k=12, seed=7)
    sp = TimeSpline.fit(t, p, bc=bc)
    m = sp.max_abs()
    dense = np.unique(np.concatenate([np.linspace(t[0], t[-1], 400001), sp.knots]))
    for order, peak, when in (
        (1, m.velocity, m.velocity_time),
        (2, m.acceleration, m.acceleration_time),
        (3, m.jerk, m.jerk_time),
    ):
        d = np.max(np.abs(sp.evaluate(dense, order)), axis=0)
        assert np.all(peak >= d * (1 - 1e-12))  # exact maxima bound every sample
        np.testing.assert_allclose(peak, d, rtol=1e-6)  # and the dense grid gets close
        if order < 3:  # the reported time is where the peak is
            at = np.abs(sp.evaluate(when, order))
            np.testing.assert_allclose(np.diag(at), peak, rtol=1e-9)


def test_sample_is_at_the_exact_rate_and_ends_on_the_final_knot() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="clamped")
    rate = 1000.0
    tr = sp.sample(rate, s_knots=np.linspace(0, 1, t.size))
    T = t[-1] - t[0]
    assert tr.dt == 1.0 / rate
    assert tr.n_samples == int(np.ceil(T * rate)) + 1
    assert (tr.n_samples - 2) * tr.dt < T <= (tr.n_samples - 1) * tr.dt
    np.testing.assert_allclose(tr.position[[0, -1]], p[[0, -1]], atol=1e-12)
    times = np.minimum(tr.time + t[0], t[-1])
    np.testing.assert_allclose(tr.velocity, sp.evaluate(times, 1), atol=1e-12)
    np.testing.assert_allclose(tr.jerk, sp.evaluate(times, 3), atol=1e-9)
    assert tr.at_rest
    assert tr.s is not None and np.all(np.diff(tr.s) >= 0)
    assert tr.s[0] == pytest.approx(0.0) and tr.s[-1] == pytest.approx(1.0)


def test_sample_refuses_more_samples_than_a_reference_may_hold() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="clamped")
    with pytest.raises(ValueError, match="a reference may hold"):
        sp.sample(1e300)


def test_periodic_sample_is_one_period() -> None:
    t, p = knots_and_points()
    p[-1] = p[0]
    sp = TimeSpline.fit(t, p, bc="periodic")
    a = one_sided(sp, sp.n_pieces - 1, True)
    b = one_sided(sp, 0, False)
    np.testing.assert_allclose(a, b, atol=1e-9 * float(np.max(np.abs(a))))
    tr = sp.sample(2000.0)
    assert not tr.at_rest
    assert tr.n_samples == round((t[-1] - t[0]) * 2000.0)


def test_scaled_time_and_concatenate() -> None:
    t, p = knots_and_points()
    sp = TimeSpline.fit(t, p, bc="rest")
    slow = sp.scaled_time(2.0)
    m, ms = sp.max_abs(), slow.max_abs()
    np.testing.assert_allclose(ms.velocity, m.velocity / 2)
    np.testing.assert_allclose(ms.acceleration, m.acceleration / 4)
    np.testing.assert_allclose(ms.jerk, m.jerk / 8)
    back = TimeSpline.fit(t - t[0], p[::-1], bc="rest")
    both = TimeSpline.concatenate([sp, back])
    assert both.duration == pytest.approx(sp.duration + back.duration)
    tj = sp.knots[-1]
    np.testing.assert_allclose(both.evaluate(np.array([tj]), 0)[0], p[-1], atol=1e-12)
    with pytest.raises(ValueError, match="do not join"):
        TimeSpline.concatenate([sp, sp])


def test_bad_input_is_refused() -> None:
    t, p = knots_and_points()
    with pytest.raises(ValueError, match="increase"):
        TimeSpline.fit(t[::-1], p)
    with pytest.raises(ValueError, match="rows"):
        TimeSpline.fit(t, p[:-1])
    with pytest.raises(ValueError, match="bc must be"):
        TimeSpline.fit(t, p, bc="free")
    with pytest.raises(ValueError, match="periodic"):
        TimeSpline.fit(t, p, bc="periodic")
    with pytest.raises(ValueError, match="end_velocity"):
        TimeSpline.fit(t, p, bc="natural", end_velocity=np.zeros(2))
    with pytest.raises(ValueError, match="rest_breaks"):
        TimeSpline.fit(t, p, bc="rest", rest_breaks=(t[2], t[-2]))
    sp = TimeSpline.fit(t, p)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        sp.sample(0.0)
    with pytest.raises(ValueError, match="order"):
        sp.evaluate(t, 4)
    with pytest.raises(ValueError, match="alpha must have shape"):
        TimeSpline(knots=t, alpha=sp.alpha[:-1], beta=sp.beta, gamma=sp.gamma, delta=sp.delta)
