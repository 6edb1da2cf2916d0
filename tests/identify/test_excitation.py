"""Experiment design for the seed 002 XY stage (`identify.excitation`, §III-C)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.core.limits import LimitViolation
from microfab.identify.excitation import (
    DT,
    FIG1_SPIRAL_B,
    INDEX_FILE,
    LIMITS,
    ExcitationRun,
    ann_dataset,
    chirp_runs,
    prbs_runs,
    random_runs,
    read_runs,
    shape_catalogue,
    shape_runs,
    split_runs,
    write_runs,
)
from microfab.identify.excitation_random import (
    HOME,
    RandomDesign,
    _brake_plan,
    _extrema,
)
from microfab.identify.excitation_signals import classic_runs
from microfab.io.trace import read_trace

SHORT = RandomDesign(run_s=(2.0, 4.0))  # short runs keep the tests fast


def _diffs(cmd: np.ndarray, dt: float = DT) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampled velocity, acceleration, jerk with the machine at rest before and after."""
    x = np.vstack([cmd[:1], cmd[:1], cmd, cmd[-1:], cmd[-1:]])
    return (np.diff(x, axis=0) / dt, np.diff(x, 2, axis=0) / dt**2, np.diff(x, 3, axis=0) / dt**3)


def _at_home_at_rest(run: ExcitationRun, a_max: float) -> None:
    """Starts at the origin from rest and ends there at rest.

    From rest, ``|a| <= a_max`` allows a first (and last) step of at most ``a_max dt²/2``.
    """
    np.testing.assert_allclose(run.command[0], HOME, atol=1e-15)  # a curve's start: ~1e-16
    np.testing.assert_allclose(run.command[-1], HOME, atol=1e-15)
    step = 0.5 * a_max * DT**2 * (1 + 1e-6)
    assert np.all(np.abs(run.command[1] - run.command[0]) <= step)
    assert np.all(np.abs(run.command[-1] - run.command[-2]) <= step)


# --- random -------------------------------------------------------------------------------------


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32), a_max=st.floats(0.5, 12.0))
def test_random_runs_stay_within_their_levels_and_the_workspace(seed: int, a_max: float) -> None:
    runs = random_runs(5.0, a_max=a_max, seed=seed, design=SHORT)
    assert sum(r.n_samples for r in runs) == round(5.0 / DT)
    lo, hi = LIMITS.workspace[0]
    for r in runs:
        _at_home_at_rest(r, a_max)
        v, a, _ = _diffs(r.command)
        assert np.max(np.abs(a)) <= r.params["a_peak"] <= a_max
        assert np.max(np.abs(v)) <= r.params["v_cap"] <= 1.5
        assert r.command.min() >= lo + SHORT.margin_m and r.command.max() <= hi - SHORT.margin_m


def test_600_s_of_random_runs_hold_6e6_samples_reach_5_m_s2_and_change_jerk_sharply() -> None:
    runs = random_runs(seed=0)  # seed 002 §III-C 1: 6e6 points; §III-D: up to 5 m/s²
    assert sum(r.n_samples for r in runs) == 6_000_000
    assert len({r.name for r in runs}) == len(runs)
    peaks, levels, sharp, knots, speeds = [], [], 0, 0, []
    for r in runs:
        v, a, j = _diffs(r.command)
        peaks.append(np.max(np.abs(a)))
        levels.append(r.params["a_peak"])
        speeds.append(np.max(np.abs(v)))
        # sharp acceleration transitions: |a| swings by more than a_max within 5 ms
        w = 50
        swing = np.max(np.abs(a[w:] - a[:-w]), axis=1)
        sharp += int(np.sum(swing > 5.0))
        # jerk changes between consecutive samples (knots) of more than 1000 m/s³
        knots += int(np.sum(np.abs(np.diff(j, axis=0)) > 1e3))
    assert 0.999 * 5.0 <= max(peaks) <= 5.0
    assert min(levels) < 0.6 * 5.0  # and lower levels too (Fig. 9 needs them)
    assert max(speeds) / min(speeds) > 3.0  # varied speeds
    assert sharp > 100
    assert knots > 10_000


def test_random_runs_are_determined_by_their_seed() -> None:
    a = random_runs(6.0, seed=7, design=SHORT)
    b = random_runs(6.0, seed=7, design=SHORT)
    c = random_runs(6.0, seed=8, design=SHORT)
    assert [r.digest for r in a] == [r.digest for r in b]
    assert [r.params for r in a] == [r.params for r in b]
    assert a[0].digest != c[0].digest


def test_the_knot_loop_kernel_equals_its_python_reference() -> None:
    fast = random_runs(8.0, seed=3, design=SHORT)
    slow = random_runs(8.0, seed=3, design=SHORT, python=True)
    for f, s in zip(fast, slow, strict=True):
        np.testing.assert_array_equal(f.command, s.command)


@settings(max_examples=200, deadline=None)
@given(
    v=st.floats(-1.5, 1.5),
    a=st.floats(-5.0, 5.0),
    ab=st.floats(0.5, 5.0),
    ramp=st.floats(1e-3, 0.05),
)
def test_the_brake_ends_at_rest_within_the_acceleration(
    v: float, a: float, ab: float, ramp: float
) -> None:
    a = max(-ab, min(ab, a))
    jb = ab / ramp
    plan = np.empty((4, 2))
    m = _brake_plan(v, a, jb, ab, plan)
    x = 0.0
    vmax = abs(v)
    for d, j in plan[:m]:
        assert d >= 0.0
        x, v2, a2, _, _, vm = _extrema(x, v, a, j, d)
        assert abs(a2) <= ab * (1 + 1e-12)
        vmax = max(vmax, vm)
        v, a = v2, a2
    assert v == pytest.approx(0.0, abs=1e-12)
    assert a == pytest.approx(0.0, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-0.1, 0.1),
    v=st.floats(-1.5, 1.5),
    a=st.floats(-5.0, 5.0),
    j=st.floats(-2e4, 2e4),
    d=st.floats(1e-4, 0.5),
)
def test_segment_extrema_bound_a_dense_sampling(
    x: float, v: float, a: float, j: float, d: float
) -> None:
    x1, v1, a1, xmin, xmax, vmax = _extrema(x, v, a, j, d)
    t = np.linspace(0.0, d, 2001)
    xs = x + v * t + a * t**2 / 2 + j * t**3 / 6
    vs = v + a * t + j * t**2 / 2
    assert xs.min() >= xmin - 1e-12 and xs.max() <= xmax + 1e-12
    assert np.abs(vs).max() <= vmax + 1e-12
    assert x1 == pytest.approx(xs[-1], abs=1e-12) and v1 == pytest.approx(vs[-1], abs=1e-9)
    assert a1 == pytest.approx(a + j * d, abs=1e-9)


# --- the run and its check -------------------------------------------------------------------


def test_a_run_beyond_table_i_is_refused_naming_the_check() -> None:
    cmd = np.zeros((100, 2))
    cmd[50:, 0] = 1e-3  # a 1 mm step in one sample: 10 m/s, 1e5 m/s²
    with pytest.raises(LimitViolation, match=r"run bad \(random\) fails check_trajectory.*axis x"):
        ExcitationRun(kind="random", name="bad", dt=DT, command=cmd)
    out = np.zeros((10, 2))
    out[:, 1] = 0.2  # outside the ±0.19 m workspace
    with pytest.raises(LimitViolation, match="workspace"):
        ExcitationRun(kind="shape", name="out", dt=DT, command=out)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [("kind", "sine", "kind"), ("name", "a/b", "name"), ("dt", 0.0, "dt"), ("seed", -1, "seed")],
)
def test_a_run_with_bad_fields_is_refused(field: str, value: object, match: str) -> None:
    args = {"kind": "random", "name": "ok", "dt": DT, "command": np.zeros((10, 2)), "seed": 0}
    args[field] = value
    with pytest.raises(ValueError, match=match):
        ExcitationRun(**args)


def test_to_trace_names_the_input_columns() -> None:
    (run,) = random_runs(2.0, seed=1, design=SHORT)
    tr = run.to_trace()
    assert tr.axes == ("input_x", "input_y") and tr.unit == "m" and tr.dt == DT
    np.testing.assert_array_equal(tr.values, run.command)


# --- shapes --------------------------------------------------------------------------------------


def test_the_fig1_spiral_is_r_equal_b_theta_over_two_turns() -> None:
    shapes = [s for s in shape_catalogue(0) if s[0] == "spiral_fig1"]
    (run,) = shape_runs([0.3], shapes=shapes)
    _at_home_at_rest(run, 5.0)
    n_shape = round(run.params["home_from_s"] / DT)
    p = run.command[:n_shape]
    r = np.hypot(p[:, 0], p[:, 1])
    theta = np.unwrap(np.arctan2(p[:, 1], p[:, 0]))
    far = r > 1e-3  # the angle of points near the pole is ill-defined
    theta = theta - 2 * math.pi * np.round(
        (theta[far][0] - r[far][0] / FIG1_SPIRAL_B) / (2 * math.pi)
    )
    np.testing.assert_allclose(r[far], FIG1_SPIRAL_B * theta[far], atol=1e-9)
    assert theta[-1] == pytest.approx(4 * math.pi, abs=1e-9)  # seed 002 Fig. 1: θ ∈ [0, 4π]
    assert r[-1] == pytest.approx(0.1, abs=1e-12)  # b · 4π = 100 mm
    # closed form 0.5 b (θ√(1+θ²) + asinh θ) at θ = 4π
    th = 4 * math.pi
    length = 0.5 * FIG1_SPIRAL_B * (th * math.sqrt(1 + th * th) + math.asinh(th))
    assert run.params["length_m"] == pytest.approx(length, rel=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_every_shape_starts_at_the_origin_and_fits_the_workspace(seed: int) -> None:
    lo, hi = LIMITS.workspace[0]
    cat = shape_catalogue(seed)
    names = [n for n, _ in cat]
    assert len(set(names)) == len(names)
    assert {"circle", "triangle", "square", "spiral"} <= {n.split("_")[0] for n in names}
    for _, path in cat:
        np.testing.assert_allclose(path.start, HOME, atol=1e-15)
        x0, y0, x1, y1 = path.bbox
        assert lo < min(x0, y0) and max(x1, y1) < hi


def test_shapes_run_at_constant_speed_from_rest_within_a_max() -> None:
    cat = dict(shape_catalogue(1))
    shapes = [(n, cat[n]) for n in ("circle_r50mm", "square_r80mm")]
    runs = shape_runs([0.1, 0.4], seed=1, a_max=3.0, shapes=shapes)
    assert [r.name for r in runs] == [
        "shape_circle_r50mm_v100mms",
        "shape_circle_r50mm_v400mms",
        "shape_square_r80mm_v100mms",
        "shape_square_r80mm_v400mms",
    ]
    for r in runs:
        _at_home_at_rest(r, 3.0)
        v, a, _ = _diffs(r.command)
        assert np.max(np.abs(a)) <= 3.0 + 1e-6  # rounding of the samples
        speed = np.hypot(v[:, 0], v[:, 1])
        assert speed.max() <= r.params["speed_m_s"] * (1 + 1e-9)
    circle_slow = runs[0]
    assert circle_slow.params["share_at_speed"] > 0.9
    assert circle_slow.duration >= 2 * math.pi * 0.05 / 0.1


# --- classic inputs ------------------------------------------------------------------------


def test_prbs_switches_within_a_max_between_its_levels() -> None:
    runs = prbs_runs(4.0, amplitudes=(1e-4, 1e-3), a_max=5.0, seed=2)
    assert len(runs) == 2
    for r in runs:
        amp = r.params["amplitude_m"]
        _at_home_at_rest(r, 5.0)
        _, a, _ = _diffs(r.command)
        assert 0.98 * 5.0 < np.max(np.abs(a)) <= 5.0
        assert np.max(np.abs(r.command)) == pytest.approx(amp, rel=1e-12)
        held = r.command[round((r.params["clock_s"] + r.params["switch_s"]) / DT)]  # 1st level
        np.testing.assert_allclose(np.abs(held), amp, rtol=1e-12)
        assert not np.array_equal(r.command[:, 0], r.command[:, 1])  # independent axes


def test_chirp_is_a_few_micrometres_at_a_max() -> None:
    runs = chirp_runs(4.0, f0_hz=1.0, f1_hz=200.0, a_max=5.0, fade_s=0.5)
    assert [r.params["axis"] for r in runs] == ["x", "y"]
    for k, r in enumerate(runs):
        _at_home_at_rest(r, 5.0)
        _, a, _ = _diffs(r.command)
        assert np.max(np.abs(a[:, k])) == pytest.approx(5.0, rel=2e-6)
        assert np.all(r.command[:, 1 - k] == 0.0)
        # A (2π f1)² <= a_max at the top of the sweep: microns, the seed's point (§III-C)
        assert 5.0 / (2 * math.pi * 200) ** 2 < r.params["amplitude_m"] < 10e-6


# --- data sets and files ---------------------------------------------------------------------


def test_ann_dataset_is_sixty_percent_random_and_splits_by_whole_runs() -> None:
    runs = ann_dataset(40.0, seed=4, speed_range=(0.3, 1.0))
    kinds = {r.kind for r in runs}
    assert kinds == {"random", "shape"}
    total = sum(r.duration for r in runs)
    rand = sum(r.duration for r in runs if r.kind == "random")
    longest_shape = max(r.duration for r in runs if r.kind == "shape")
    assert rand == pytest.approx(0.6 * 40.0, abs=DT)
    assert abs(total - 40.0) <= max(1.0, longest_shape)
    assert len({r.name for r in runs}) == len(runs)
    train, valid = split_runs(runs, 0.2, seed=1)
    assert {r.name for r in train}.isdisjoint({r.name for r in valid})
    assert sorted(r.name for r in train + valid) == sorted(r.name for r in runs)
    for kind in kinds:
        of = [r for r in runs if r.kind == kind]
        got = sum(r.n_samples for r in valid if r.kind == kind)
        goal = 0.2 * sum(r.n_samples for r in of)
        assert abs(got - goal) <= max(r.n_samples for r in of) / 2
    again = split_runs(runs, 0.2, seed=1)
    assert [r.name for r in again[1]] == [r.name for r in valid]


def test_split_keeps_shares_on_many_runs() -> None:
    runs = [
        ExcitationRun(kind="shape", name=f"s{i}", dt=DT, command=np.zeros((100 + 7 * i, 2)))
        for i in range(50)
    ]
    _, valid = split_runs(runs, 0.2, seed=3)
    share = sum(r.n_samples for r in valid) / sum(r.n_samples for r in runs)
    assert share == pytest.approx(0.2, abs=(100 + 7 * 49) / 2 / sum(r.n_samples for r in runs))
    assert split_runs(runs, 0.2, seed=4)[1] != valid


@pytest.mark.parametrize("fmt", ["csv", "h5"])
def test_write_read_round_trip(tmp_path, fmt: str) -> None:
    runs = random_runs(3.0, seed=9, design=SHORT) + prbs_runs(1.0, amplitudes=(1e-4,))
    index = write_runs(runs, tmp_path, fmt=fmt)
    meta = json.loads(index.read_text())
    assert meta["total_samples"] == sum(r.n_samples for r in runs)
    assert [e["sha256"] for e in meta["runs"]] == [r.digest for r in runs]
    tr = read_trace(tmp_path / meta["runs"][0]["file"])
    assert tr.axes == ("input_x", "input_y")
    assert tr.dt == pytest.approx(DT, rel=1e-9)
    back = read_runs(tmp_path)
    for a, b in zip(runs, back, strict=True):
        assert (a.name, a.kind, a.seed, a.dt) == (b.name, b.kind, b.seed, b.dt)
        np.testing.assert_array_equal(a.command, b.command)
        assert dict(b.params) == json.loads(json.dumps(dict(a.params)))


def test_nothing_is_written_when_a_run_fails(tmp_path) -> None:
    good = random_runs(2.0, seed=1, design=SHORT)
    bad = prbs_runs(1.0, amplitudes=(1e-4,))[0]
    tampered = bad.command.copy()
    tampered[100, 0] += 1e-3  # a spike after the run was built
    object.__setattr__(bad, "command", tampered)
    with pytest.raises(LimitViolation, match="prbs_a100um"):
        write_runs([*good, bad], tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="unique"):
        write_runs([good[0], good[0]], tmp_path / "dup")
    assert not (tmp_path / "dup").exists()
    (tmp_path / "x").mkdir()
    write_runs(good, tmp_path / "x")
    meta = json.loads((tmp_path / "x" / INDEX_FILE).read_text())
    tampered = tmp_path / "x" / meta["runs"][0]["file"]
    text = tampered.read_text().splitlines()
    text[-1] = text[-1].rsplit(",", 1)[0] + ",1e-9"
    tampered.write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError, match="SHA-256"):
        read_runs(tmp_path / "x")


def test_the_twins_set_point_guard_passes_every_kind_untouched() -> None:
    # the twin's guard enforces Table I on its own (backward differences, seed 002 §II-B);
    # a run at Table I's full 40 m/s² must reach the loop unchanged
    from microfab.plants.xy_stage import xy_stage_twin

    twin = xy_stage_twin()
    cat = dict(shape_catalogue(3))
    runs = [
        *random_runs(2.0, a_max=40.0, seed=2, design=SHORT),
        *shape_runs([1.5], a_max=40.0, shapes=[("hexagon_r30mm", cat["hexagon_r30mm"])]),
        *prbs_runs(0.5, amplitudes=(1e-4,), a_max=40.0),
        chirp_runs(0.5, fade_s=0.1, a_max=40.0)[0],
    ]
    for r in runs:
        guarded, counts = twin.guard(r.command)
        assert counts.limited == 0, r.name
        np.testing.assert_array_equal(guarded, r.command)


def test_classic_runs_are_prbs_and_chirps_within_table_i():
    runs = classic_runs(40.0, seed=1)
    assert len(runs) == 20
    assert {r.kind for r in runs} == {"prbs", "chirp"}
    assert len({r.name for r in runs}) == 20
    assert all(isinstance(r, ExcitationRun) for r in runs)  # each passed check_trajectory
    total = sum(r.command.shape[0] * r.dt for r in runs)
    assert total == pytest.approx(40.0, rel=0.1)


def test_random_runs_are_sized_before_they_are_made() -> None:
    """Issue 32: a total of 1e308 s is refused before any sample is drawn."""
    from microfab.identify.excitation import MAX_TOTAL_S, random_runs

    with pytest.raises(ValueError, match=r"total_s = 1e\+308 s of random runs is more than 3600"):
        random_runs(1e308)
    assert MAX_TOTAL_S == 3600.0
