from __future__ import annotations

import re

import numpy as np
import pytest

from microfab.core.signals import (
    Trace,
    check_axes,
    check_name,
    check_samples,
    check_time_base,
    check_unit,
)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def trace(rng):
    # Axis order deliberately not alphabetical, values with full float64 mantissas.
    values = rng.normal(scale=1e-3, size=(257, 3)) * np.array([1.0, 1e-9, 1e6])
    return Trace(dt=2.5e-5, values=values, axes=("z", "x", "b_2"), unit="m", t0=0.125)


# --- construction and properties -------------------------------------------------------


def test_properties(trace):
    assert trace.n_samples == 257
    assert trace.n_axes == 3
    assert trace.duration == pytest.approx(257 * 2.5e-5, rel=1e-15)
    assert trace.fs == pytest.approx(40_000.0, rel=1e-15)
    assert trace.time.shape == (257,)
    assert trace.time[0] == 0.125
    np.testing.assert_allclose(np.diff(trace.time), 2.5e-5, rtol=1e-9)
    np.testing.assert_array_equal(trace["x"], trace.values[:, 1])


def test_values_are_copied_and_read_only(rng):
    raw = rng.normal(size=(10, 2))
    t = Trace(dt=0.1, values=raw, axes=("a", "b"))
    raw[0, 0] = 99.0
    assert t.values[0, 0] != 99.0
    assert t.values.dtype == np.float64
    assert not t.values.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        t.values[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        t["a"][0] = 1.0


def test_integer_values_become_float64():
    t = Trace(dt=1, values=[[1, 2], [3, 4]], axes=["a", "b"])
    assert t.values.dtype == np.float64
    assert t.axes == ("a", "b")
    assert t.dt == 1.0
    assert isinstance(t.dt, float)


def test_one_d_values_with_one_axis_are_reshaped():
    t = Trace(dt=0.5, values=np.array([1.0, 2.0, 3.0]), axes=("x",))
    assert t.values.shape == (3, 1)
    np.testing.assert_array_equal(t["x"], [1.0, 2.0, 3.0])


def test_getitem_unknown_axis_lists_available():
    t = Trace(dt=1.0, values=np.zeros((2, 2)), axes=("x", "y"))
    with pytest.raises(KeyError, match=r"no axis 'q'.*\['x', 'y'\]"):
        t["q"]


def test_select_and_with_values(trace):
    sub = trace.select("b_2", "z")
    assert sub.axes == ("b_2", "z")
    np.testing.assert_array_equal(sub.values, trace.values[:, [2, 0]])
    assert (sub.dt, sub.t0, sub.unit) == (trace.dt, trace.t0, trace.unit)
    with pytest.raises(KeyError):
        trace.select("nope")
    doubled = trace.with_values(2 * trace.values)
    np.testing.assert_array_equal(doubled.values, 2 * trace.values)
    assert (doubled.axes, doubled.dt, doubled.unit, doubled.t0) == (
        trace.axes,
        trace.dt,
        trace.unit,
        trace.t0,
    )
    with pytest.raises(ValueError, match="shape"):
        trace.with_values(np.zeros((4, 2)))


def test_to_dict_order(trace):
    d = trace.to_dict()
    assert list(d) == ["time", "z", "x", "b_2"]
    np.testing.assert_array_equal(d["time"], trace.time)
    np.testing.assert_array_equal(d["b_2"], trace.values[:, 2])


def test_equality_and_hash(trace):
    same = Trace(dt=trace.dt, values=trace.values.copy(), axes=trace.axes, unit="m", t0=0.125)
    assert same == trace
    assert hash(same) == hash(trace)
    assert trace.with_values(trace.values + 1.0) != trace
    assert Trace(dt=1.0, values=[-0.0], axes="x") == Trace(dt=1.0, values=[0.0], axes="x")
    assert hash(Trace(dt=1.0, values=[-0.0], axes="x")) == hash(
        Trace(dt=1.0, values=[0.0], axes="x")
    )


# --- validation ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("dt", "shown"), [(-1.0, "-1.0"), (0.0, "0.0"), (np.nan, "nan"), (np.inf, "inf"), ("x", "'x'")]
)
def test_bad_dt(dt, shown):
    with pytest.raises(ValueError) as info:
        Trace(dt=dt, values=np.zeros((3, 1)), axes=("x",))
    assert str(info.value) == f"dt must be a positive finite number of seconds, got {shown} s"


def test_bad_t0():
    with pytest.raises(ValueError, match="t0 must be a finite number of seconds, got nan s"):
        Trace(dt=1.0, values=np.zeros((3, 1)), axes=("x",), t0=np.nan)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_values_name_axis_and_sample(bad):
    values = np.zeros((6, 3))
    values[4, 1] = bad
    values[5, 2] = bad
    with pytest.raises(ValueError, match=r"axis 'y' must be finite, got -?(nan|inf) V at sample 4"):
        Trace(dt=1.0, values=values, axes=("x", "y", "z"), unit="V")


@pytest.mark.parametrize(
    ("values", "axes", "match"),
    [
        (np.zeros((4, 3)), ("x", "y"), r"shape \(n_samples, 2\).*got shape \(4, 3\)"),
        (np.zeros(4), ("x", "y"), r"got shape \(4,\)"),
        (np.zeros((2, 2, 2)), ("x", "y"), r"got shape \(2, 2, 2\)"),
        (np.zeros((0, 1)), ("x",), "at least 1 sample"),
        (np.zeros((3, 2)), ("x", "x"), r"unique.*\['x'\]"),
        (np.zeros((3, 1)), ("1x",), "start with a letter.*'1x'"),
        (np.zeros((3, 1)), ("a-b",), "'a-b'"),
        (np.zeros((3, 1)), ("_x",), "'_x'"),
        (np.zeros((3, 1)), ("time",), "reserved"),
        (np.zeros((3, 0)), (), "at least one axis"),
        ([["a"], ["b"]], ("x",), "real numbers"),
    ],
)
def test_invalid_values_and_axes(values, axes, match):
    with pytest.raises(ValueError, match=match):
        Trace(dt=1.0, values=values, axes=axes)


def test_unit_must_be_single_line():
    with pytest.raises(ValueError, match="single-line"):
        Trace(dt=1.0, values=[1.0], axes="x", unit="m\nx")


# --- from_columns ----------------------------------------------------------------------


def test_from_columns(rng):
    time = 3.0 + 1e-3 * np.arange(50)
    cols = {"b": rng.normal(size=50), "a": rng.normal(size=50)}
    t = Trace.from_columns(time, cols, unit="N")
    assert t.axes == ("b", "a")
    assert t.dt == 1e-3
    assert t.t0 == 3.0
    assert t.unit == "N"
    np.testing.assert_array_equal(t["a"], cols["a"])


def test_from_columns_non_uniform_reports_max_deviation():
    time = np.arange(10.0)
    time[5] += 0.01
    with pytest.raises(ValueError, match=r"uniformly sampled: max deviation") as info:
        Trace.from_columns(time, {"x": np.zeros(10)})
    match = re.search(r"dt=(\S+) s is (\S+) s", str(info.value))
    assert match is not None
    assert float(match.group(1)) == pytest.approx(1.0, rel=1e-12)
    assert float(match.group(2)) == pytest.approx(0.01, rel=1e-9)


def test_from_columns_tolerates_tiny_jitter():
    time = np.arange(10.0) * 0.1
    time[3] += 1e-9  # 1e-8 relative to dt: within 1e-6
    t = Trace.from_columns(time, {"x": np.zeros(10)})
    assert t.dt == pytest.approx(0.1, rel=1e-12)


@pytest.mark.parametrize(
    ("time", "match"),
    [
        (np.array([0.0, 1.0, 1.0, 2.0]), "strictly increasing, got 1.0 s then 1.0 s at sample 2"),
        (np.array([0.0, 2.0, 1.0, 3.0]), "strictly increasing"),
        (np.zeros((4, 1)), "1-D"),
        (np.array([0.0]), ">= 2 samples"),
        (np.array([0.0, np.nan, 2.0, 3.0]), "finite"),
    ],
)
def test_from_columns_bad_time(time, match):
    with pytest.raises(ValueError, match=match):
        Trace.from_columns(time, {"x": np.zeros(len(time))})


def test_from_columns_mismatched_lengths():
    with pytest.raises(ValueError, match=r"column 'y' has shape \(9,\), time has shape \(10,\)"):
        Trace.from_columns(np.arange(10.0), {"x": np.zeros(10), "y": np.zeros(9)})


def test_from_columns_needs_a_column():
    with pytest.raises(ValueError, match="at least one axis column"):
        Trace.from_columns(np.arange(10.0), {})


# --- the shared checks -----------------------------------------------------------------


def test_check_name_and_unit():
    assert check_name("b_2") == "b_2"
    with pytest.raises(ValueError, match=r"^column name must start with a letter.*'x y'$"):
        check_name("x y", "column")
    with pytest.raises(ValueError, match=r"axis name .* got 3"):
        check_name(3)
    assert check_unit("m/s") == "m/s"
    for bad in ("m\r", 1.0, None):
        with pytest.raises(ValueError, match="single-line"):
            check_unit(bad)


def test_check_axes():
    assert check_axes("x") == ("x",)
    assert check_axes(iter(["y", "x"])) == ("y", "x")
    with pytest.raises(ValueError, match=r"unique, got duplicates \['a', 'b'\]"):
        check_axes(["a", "b", "a", "b", "c"])


def test_check_samples_two_d():
    check_samples("position", np.zeros((3, 2)), ("x", "y"), n_samples=3, unit="m")
    with pytest.raises(
        ValueError, match=r"velocity must have shape \(4, 2\) .* got shape \(3, 2\)"
    ):
        check_samples("velocity", np.zeros((3, 2)), ("x", "y"), n_samples=4)
    with pytest.raises(ValueError, match=r"position must have shape \(n_samples, 2\)"):
        check_samples("position", np.zeros((3, 1)), ("x", "y"))
    with pytest.raises(ValueError, match="position must hold at least 1 sample, got 0"):
        check_samples("position", np.zeros((0, 2)), ("x", "y"))
    values = np.zeros((5, 2))
    values[3, 1] = np.inf
    values[4, 0] = np.nan
    # the first bad axis (in axis order), then its first bad sample
    with pytest.raises(
        ValueError, match=r"^jerk of axis 'x' must be finite, got nan m/s³ at sample 4$"
    ):
        check_samples("jerk", values, ("x", "y"), unit="m/s³")


def test_check_samples_one_d():
    check_samples("s", np.arange(4.0), None, n_samples=4, unit="m")
    with pytest.raises(ValueError, match=r"s must have shape \(5,\), got shape \(4,\)"):
        check_samples("s", np.arange(4.0), None, n_samples=5)
    with pytest.raises(ValueError, match=r"s must have shape \(n_samples,\), got shape \(4, 1\)"):
        check_samples("s", np.zeros((4, 1)), None)
    with pytest.raises(ValueError, match=r"^s must be finite, got -inf m at sample 2$"):
        check_samples("s", np.array([0.0, 1.0, -np.inf]), None, unit="m")


def test_check_time_base():
    assert check_time_base(np.array([2.0, 2.5, 3.0])) == (2.0, 0.5)
    time = 3.0 + 0.1 * np.arange(10)
    assert (time[-1] - time[0]) / 9 != 0.1  # the endpoint estimate is off by an ulp
    assert check_time_base(time) == (3.0, 0.1)
    with pytest.raises(ValueError, match=r"increasing, got 2\.0 s then 1\.0 s at sample 1"):
        check_time_base(np.array([2.0, 1.0, 3.0]))
