"""The shared argument checks: what passes, what is refused and what the message says."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.core.validate import (
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
)

SEEDED = settings(derandomize=True, max_examples=200, deadline=None)

names = st.from_regex(r"[a-z][a-z_]{0,11}", fullmatch=True)
non_positive = st.floats(max_value=0.0, allow_nan=False) | st.integers(max_value=0)
not_finite = st.sampled_from([math.nan, math.inf, -math.inf, np.float64("nan"), np.inf])


@SEEDED
@given(value=st.floats(min_value=0.0, exclude_min=True, allow_infinity=False))
def test_any_finite_positive_float_passes(value: float) -> None:
    assert check_positive("x_m", value, "m") == value


@SEEDED
@given(name=names, value=non_positive | not_finite)
def test_non_positive_nan_or_inf_is_refused_by_name(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=rf"^{name} must be positive and finite, got ") as info:
        check_positive(name, value, "m")
    assert str(info.value).endswith(" m")


@SEEDED
@given(value=st.floats(min_value=0.0, allow_infinity=False))
def test_any_finite_nonnegative_float_passes(value: float) -> None:
    assert check_nonnegative("x_m", value, "m") == value


@SEEDED
@given(name=names, value=st.floats(max_value=0.0, exclude_max=True) | not_finite)
def test_negative_nan_or_inf_is_refused_as_negative(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=rf"^{name} must be non-negative and finite, got "):
        check_nonnegative(name, value, "s")


@pytest.mark.parametrize(
    ("check", "value", "message"),
    [
        (check_positive, -1.5, "dwell_s must be positive and finite, got -1.5 s"),
        (check_positive, 0, "dwell_s must be positive and finite, got 0 s"),
        (check_positive, np.float64(-2.0), "dwell_s must be positive and finite, got -2.0 s"),
        (check_nonnegative, -1e-9, "dwell_s must be non-negative and finite, got -1e-09 s"),
        (check_finite, math.inf, "dwell_s must be finite, got inf s"),
        (check_finite, -math.inf, "dwell_s must be finite, got -inf s"),
    ],
)
def test_message_names_parameter_value_and_unit(check, value, message) -> None:
    with pytest.raises(ValueError) as info:
        check("dwell_s", value, "s")
    assert str(info.value) == message


def test_no_unit_leaves_no_trailing_space() -> None:
    with pytest.raises(ValueError) as info:
        check_positive("gain_ratio", -1.0)
    assert str(info.value) == "gain_ratio must be positive and finite, got -1.0"


@pytest.mark.parametrize("check", [check_finite, check_positive, check_nonnegative])
@pytest.mark.parametrize("value", [True, False, np.True_, "1.0", None, [1.0], np.array([1.0])])
def test_non_numbers_and_bools_are_refused(check, value) -> None:
    with pytest.raises(ValueError, match=r"^x_m must be a number in m, got "):
        check("x_m", value, "m")


@pytest.mark.parametrize("check", [check_finite, check_positive, check_nonnegative])
def test_returns_a_float(check) -> None:
    for value in (3, np.float32(0.5), np.int64(7), 2.5):
        out = check("x", value)
        assert type(out) is float and out == float(value)


def test_finite_accepts_any_sign() -> None:
    assert check_finite("t0_s", -3.0, "s") == -3.0
    assert check_finite("t0_s", 0, "s") == 0.0


@pytest.mark.parametrize(
    ("value", "low_closed", "high_closed", "ok"),
    [
        (0.0, True, True, True),
        (1.0, True, True, True),
        (0.0, False, True, False),
        (1.0, True, False, False),
        (0.5, False, False, True),
        (-0.1, True, True, False),
        (1.1, True, True, False),
        (math.nan, True, True, False),
        (math.inf, True, True, False),
        (-math.inf, True, True, False),
    ],
)
def test_in_range_bounds(value, low_closed, high_closed, ok) -> None:
    kwargs = {"low_closed": low_closed, "high_closed": high_closed}
    if ok:
        assert check_in_range("f", value, 0.0, 1.0, **kwargs) == value
    else:
        with pytest.raises(ValueError, match=r"^f must lie in [\[(]0, 1[\])], got "):
            check_in_range("f", value, 0.0, 1.0, **kwargs)


def test_in_range_message_shows_the_interval() -> None:
    with pytest.raises(ValueError) as info:
        check_in_range("gain", 2.5, 0, 2, "(ratio)", low_closed=False)
    assert str(info.value) == "gain must lie in (0, 2], got 2.5 (ratio)"
    with pytest.raises(ValueError, match=r"^gain must be a number in \(ratio\), got True$"):
        check_in_range("gain", True, 0, 2, "(ratio)")


def test_int() -> None:
    assert check_int("width_px", 2, 2, "px") == 2
    out = check_int("width_px", np.int64(64), 2, "px")
    assert type(out) is int and out == 64
    for bad, shown in ((1, "1"), (2.0, "2.0"), (True, "True"), (np.int64(-3), "-3"), ("3", "'3'")):
        with pytest.raises(ValueError) as info:
            check_int("width_px", bad, 2, "px")
        assert str(info.value) == f"width_px must be an integer >= 2, got {shown} px"
