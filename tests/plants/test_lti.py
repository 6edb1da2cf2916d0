"""Tests of the discrete LTI container, discretisation, delays and block stacking."""

from __future__ import annotations

import numpy as np
import pytest

import control
from microfab.plants.lti import DiscreteLTI, block_diag, discretize, with_input_delay

DT = 1e-4  # 10 kHz: coarse enough that discretisation effects are visible
FREQS = np.array([1.0, 10.0, 100.0, 500.0, 1000.0, 3000.0, 4900.0])


def first_order_lag(tau: float) -> control.TransferFunction:
    return control.tf([1.0], [tau, 1.0])


# --------------------------------------------------------------------- discretisation
def test_zoh_first_order_lag_matches_analytic_discrete_response():
    tau = 1e-3
    sysd = discretize(first_order_lag(tau), DT, "zoh")
    # ZOH of 1/(tau s + 1): H(z) = (1 - p) / (z - p), p = exp(-dt/tau).
    p = np.exp(-DT / tau)
    z = np.exp(2j * np.pi * FREQS * DT)
    expected = (1 - p) / (z - p)
    got = sysd.frequency_response(FREQS)[:, 0, 0]
    np.testing.assert_allclose(got, expected, rtol=1e-10)
    np.testing.assert_allclose(sysd.poles(), [p], rtol=1e-12)
    assert sysd.dt == DT
    assert (sysd.n_states, sysd.n_inputs, sysd.n_outputs) == (1, 1, 1)


def test_tustin_first_order_lag_matches_frequency_warping():
    tau = 1e-3
    sysd = discretize(first_order_lag(tau), DT, "tustin")
    # Tustin: H(e^{jw dt}) = G(j (2/dt) tan(w dt / 2)).
    w = 2 * np.pi * FREQS
    s = 1j * (2 / DT) * np.tan(w * DT / 2)
    expected = 1.0 / (tau * s + 1.0)
    got = sysd.frequency_response(FREQS)[:, 0, 0]
    np.testing.assert_allclose(got, expected, rtol=1e-10)


def test_negative_frequency_gives_conjugate_response():
    sysd = discretize(first_order_lag(1e-3), DT, "zoh")
    pos = sysd.frequency_response(FREQS)[:, 0, 0]
    neg = sysd.frequency_response(-FREQS)[:, 0, 0]
    np.testing.assert_allclose(neg, np.conj(pos), rtol=1e-12)


def test_zoh_of_double_integrator_has_zero_at_minus_one():
    # ZOH of 1/s^2: H(z) = dt^2/2 (z + 1) / (z - 1)^2, a single zero at z = -1.
    sysd = discretize(control.tf([1.0], [1.0, 0.0, 0.0]), DT, "zoh")
    zeros = sysd.zeros()
    assert zeros.size == 1
    np.testing.assert_allclose(zeros, [-1.0], atol=1e-9)
    f = np.array([10.0, 100.0, 1000.0])
    z = np.exp(2j * np.pi * f * DT)
    np.testing.assert_allclose(
        sysd.frequency_response(f)[:, 0, 0], DT**2 / 2 * (z + 1) / (z - 1) ** 2, rtol=1e-9
    )


def test_discretize_rejects_bad_dt():
    for dt in (0.0, -1e-3, np.nan, np.inf):
        with pytest.raises(ValueError, match="dt"):
            discretize(first_order_lag(1e-3), dt)


# ----------------------------------------------------------------------------- zeros
def test_zeros_of_known_discrete_transfer_function():
    # H(z) = (z - 0.5)(z + 0.3) / ((z - 0.2)(z - 0.9)(z + 0.1)): zeros 0.5 and -0.3.
    num = np.polymul([1.0, -0.5], [1.0, 0.3])
    den = np.polymul(np.polymul([1.0, -0.2], [1.0, -0.9]), [1.0, 0.1])
    ss = control.ss(control.tf(num, den, DT))
    sys = DiscreteLTI(ss.A, ss.B, ss.C, ss.D, DT)
    np.testing.assert_allclose(np.sort(sys.zeros().real), [-0.3, 0.5], atol=1e-10)
    np.testing.assert_allclose(np.abs(sys.zeros().imag), 0.0, atol=1e-10)
    np.testing.assert_allclose(np.sort(sys.poles().real), [-0.1, 0.2, 0.9], atol=1e-10)


def test_zeros_of_a_channel_of_a_mimo_system():
    a = DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[0.0]], DT)  # 1/(z - 0.5): no zero
    # (z - 0.7)/(z - 0.1) = 1 - 0.6/(z - 0.1): zero at 0.7
    b = DiscreteLTI([[0.1]], [[1.0]], [[-0.6]], [[1.0]], DT)
    both = block_diag(a, b)
    # The channel keeps the other block's (uncontrollable, unobservable) state, which the
    # system pencil reports as a decoupling zero; the transmission zero must be there and
    # nothing else but the other block's pole.
    z11 = both.zeros(1, 1)
    assert np.any(np.abs(z11 - 0.7) < 1e-12), z11
    assert np.all(np.isclose(z11, 0.7, atol=1e-12) | np.isclose(z11, 0.5, atol=1e-12)), z11
    z00 = both.zeros(0, 0)
    assert np.all(np.isclose(z00, 0.1, atol=1e-12)), z00
    # on its own each block has exactly its transmission zeros
    assert a.zeros().size == 0
    np.testing.assert_allclose(b.zeros(), [0.7], atol=1e-12)


def test_zeros_of_static_system_is_empty():
    sys = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[2.0]], DT)
    assert sys.n_states == 0
    assert sys.zeros().size == 0
    np.testing.assert_allclose(sys.frequency_response(FREQS)[:, 0, 0], 2.0)


# ------------------------------------------------------------------------- input delay
@pytest.mark.parametrize("n", [1, 3, 7])
def test_with_input_delay_adds_exactly_n_samples(n):
    base = discretize(first_order_lag(2e-4), DT, "zoh")
    delayed = with_input_delay(base, n)
    assert delayed.n_states == base.n_states + n
    ratio = delayed.frequency_response(FREQS)[:, 0, 0] / base.frequency_response(FREQS)[:, 0, 0]
    # pure delay: z^-n = exp(-j w n dt)
    np.testing.assert_allclose(ratio, np.exp(-2j * np.pi * FREQS * n * DT), rtol=1e-10)
    # and n extra poles at the origin
    assert np.sum(np.abs(delayed.poles()) < 1e-12) == n


def test_with_input_delay_time_domain_shift():
    # y = C x with x[k+1] = 0.5 x[k] + u[k]; an impulse appears n samples later when delayed.
    base = DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[0.0]], DT)
    n = 4
    delayed = with_input_delay(base, n)

    def impulse_response(s: DiscreteLTI, k: int) -> np.ndarray:
        x = np.zeros(s.n_states)
        out = []
        for i in range(k):
            u = np.array([1.0 if i == 0 else 0.0])
            out.append((s.C @ x + s.D @ u)[0])
            x = s.A @ x + s.B @ u
        return np.array(out)

    h0 = impulse_response(base, 20)
    hn = impulse_response(delayed, 20)
    np.testing.assert_allclose(hn[:n], 0.0)
    np.testing.assert_allclose(hn[n:], h0[: 20 - n], rtol=1e-15)


def test_with_input_delay_keeps_feedthrough_through_delay_and_multiple_inputs():
    # Static 2x2 gain with feed-through: delay turns D into D z^-n per input.
    D = np.array([[1.0, 2.0], [3.0, 4.0]])
    static = DiscreteLTI(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), D, DT)
    delayed = with_input_delay(static, 2)
    assert delayed.n_states == 4
    np.testing.assert_array_equal(delayed.D, 0.0)
    H = delayed.frequency_response(FREQS)
    np.testing.assert_allclose(
        H, D[None] * np.exp(-2j * np.pi * FREQS * 2 * DT)[:, None, None], rtol=1e-12
    )


def test_with_input_delay_zero_and_negative():
    base = discretize(first_order_lag(1e-3), DT)
    assert with_input_delay(base, 0) is base
    with pytest.raises(ValueError, match="delay"):
        with_input_delay(base, -1)


# ------------------------------------------------------------------------- block_diag
def test_block_diag_stacks_independent_channels():
    a = discretize(first_order_lag(1e-3), DT)
    b = discretize(control.tf([2.0], [1e-4, 1.0]), DT)
    ab = block_diag(a, b)
    assert (ab.n_states, ab.n_inputs, ab.n_outputs) == (2, 2, 2)
    H = ab.frequency_response(FREQS)
    np.testing.assert_allclose(H[:, 0, 0], a.frequency_response(FREQS)[:, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(H[:, 1, 1], b.frequency_response(FREQS)[:, 0, 0], rtol=1e-12)
    np.testing.assert_array_equal(H[:, 0, 1], 0.0)
    np.testing.assert_array_equal(H[:, 1, 0], 0.0)
    # channel() recovers each block
    np.testing.assert_allclose(
        ab.channel(1, 1).frequency_response(FREQS), b.frequency_response(FREQS), rtol=1e-12
    )


def test_block_diag_errors():
    a = discretize(first_order_lag(1e-3), DT)
    b = discretize(first_order_lag(1e-3), 2 * DT)
    with pytest.raises(ValueError, match="dt"):
        block_diag(a, b)
    with pytest.raises(ValueError, match="at least one"):
        block_diag()


def test_matrices_are_read_only():
    sys = DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[0.0]], DT)
    with pytest.raises(ValueError):
        sys.A[0, 0] = 2.0


@pytest.mark.parametrize("dt", [0.0, -1e-6, np.nan, np.inf])
def test_bad_dt_is_refused(dt):
    with pytest.raises(ValueError, match="dt"):
        DiscreteLTI([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt)


@pytest.mark.parametrize(
    ("A", "B", "C", "D"),
    [
        (np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((1, 1))),  # A not square
        (np.eye(2), np.zeros((3, 1)), np.zeros((1, 2)), np.zeros((1, 1))),  # B rows
        (np.eye(2), np.zeros((2, 1)), np.zeros((1, 3)), np.zeros((1, 1))),  # C columns
        (np.eye(2), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((2, 1))),  # D shape
        (np.eye(2), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((1, 2))),  # D shape
    ],
)
def test_shape_mismatch_is_refused(A, B, C, D):
    with pytest.raises(ValueError, match="shape"):
        DiscreteLTI(A, B, C, D, DT)


@pytest.mark.parametrize("which", "ABCD")
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_matrix_is_refused(which, bad):
    mats = {"A": np.eye(2) * 0.5, "B": np.ones((2, 1)), "C": np.ones((1, 2)), "D": np.zeros((1, 1))}
    mats[which] = mats[which].copy()
    mats[which][0, 0] = bad
    with pytest.raises(ValueError, match=f"matrix {which}"):
        DiscreteLTI(mats["A"], mats["B"], mats["C"], mats["D"], DT)
