"""`exp_fast` against numpy's exp: ULP accuracy, clipping, and that it compiles in a loop."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from microfab.core.fastexp import EXP_FAST_MAX, EXP_FAST_MIN, exp_fast


@njit(cache=True)
def _exp_all(t: np.ndarray) -> np.ndarray:
    out = np.empty_like(t)
    for i in range(t.shape[0]):
        out[i] = exp_fast(t[i])
    return out


def _ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    return np.abs(got - want) / np.spacing(want)


def test_within_three_ulp_on_a_dense_grid() -> None:
    # 2e6 points over the whole accurate range, plus the reduced-range edges near k ln 2.
    t = np.linspace(EXP_FAST_MIN, EXP_FAST_MAX, 2_000_001)
    k = np.arange(-1020, 1022)
    edges = np.concatenate([k * np.log(2.0) + d for d in (-0.5 * np.log(2.0), 0.0, 1e-12)])
    t = np.concatenate([t, edges[(edges >= EXP_FAST_MIN) & (edges <= EXP_FAST_MAX)]])
    u = _ulps(_exp_all(t), np.exp(t))
    assert u.max() <= 3.0, f"worst {u.max():.2f} ULP at t = {t[np.argmax(u)]!r}"
    assert np.mean(u) < 0.5


@settings(max_examples=500, deadline=None)
@given(st.floats(min_value=EXP_FAST_MIN, max_value=EXP_FAST_MAX))
def test_within_three_ulp_anywhere(t: float) -> None:
    got = _exp_all(np.array([t]))[0]
    assert _ulps(np.array([got]), np.array([np.exp(t)]))[0] <= 3.0


def test_exact_at_zero_and_small_arguments() -> None:
    assert _exp_all(np.array([0.0]))[0] == 1.0
    t = np.array([1e-300, -1e-17, 1e-9])
    np.testing.assert_allclose(_exp_all(t), np.exp(t), rtol=2.3e-16, atol=0.0)


def test_clips_outside_the_range() -> None:
    out = _exp_all(np.array([-800.0, -np.inf, 800.0, np.inf]))
    lo, hi = np.exp(EXP_FAST_MIN), np.exp(EXP_FAST_MAX)
    np.testing.assert_allclose(out, [lo, lo, hi, hi], rtol=5e-16)
    assert np.all(np.isfinite(out))
