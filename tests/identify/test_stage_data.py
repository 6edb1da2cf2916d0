"""Measured XY stage runs and their linear model (`identify.stage_data`, seed 002 eq. 6).

The twin (`plants/xy_stage.py`, with its nonlinearities and 2 µm noise) plays 20 s of
seeded random runs through the compiled loop from rest; `fit_linear` must give a
4-state model whose error is far below the D = 0 fit's and whose slowest time constant
sits near the twin's 20 ms only after decimation.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.signal

from microfab.control.setpoint import SetPoint
from microfab.core.signals import Trace
from microfab.identify.excitation import random_runs
from microfab.identify.excitation_random import RandomDesign
from microfab.identify.stage_data import (
    COLUMNS,
    FORMAT,
    StageLinearModel,
    StageRecord,
    check_decimate,
    decimate,
    fit_linear,
    read_stage_model,
    rest_state,
    run_errors,
    stage_record,
    write_stage_model,
)
from microfab.machines.xy_stage.calibration import assumed_changes
from microfab.plants.xy_stage import xy_stage_twin
from microfab.sim.loop import simulate

DT = 1e-4  # seed 002 Table I: 10 kHz


@pytest.fixture(scope="module")
def twin_records() -> list[StageRecord]:
    """20 s of random runs (3 runs) played on the twin from rest, with its 2 µm noise."""
    # every magnitude as assumed before calibration: a twin whose linear part the fit can
    # be checked against (the calibrated one's feedforward is off on purpose, and its error
    # is the seed002_stage tests')
    twin = xy_stage_twin(**dict(assumed_changes()))
    runs = random_runs(20.0, seed=1, design=RandomDesign(run_s=(4.0, 8.0)))
    out = []
    for i, r in enumerate(runs):
        res = simulate(twin, SetPoint(2), r.command, twin.noise(r.n_samples, seed=i))
        assert twin.guard_counts(res.final_state.plant).limited == 0
        out.append(StageRecord(name=r.name, u=r.command, y=res.measured))
    return out


@pytest.fixture(scope="module")
def fitted(twin_records):
    return fit_linear(twin_records, DT)


def test_fit_linear_on_the_twin_follows_within_the_noise_and_nonlinearity(fitted, twin_records):
    err = run_errors(fitted, twin_records, 10)
    assert fitted.dt == pytest.approx(1e-3) and fitted.order == 4
    assert err.rate_hz == pytest.approx(1000.0)
    assert err.n_samples == sum(-(-r.n_samples // 10) for r in twin_records)
    # the 2 µm output noise is a floor; the nonlinearities keep it well above
    assert np.all(err.std > 2e-6) and np.all(err.std < 30e-6)
    assert np.all(np.abs(err.mean) <= np.maximum(2e-6, err.std / 3))
    # eq. (6b)'s D: the built-in loop's feedforward makes the stage follow its set-point
    assert np.all(np.abs(np.diag(fitted.d) - 1.0) < 0.1)
    # per run and overall agree
    n = np.array([-(-r.n_samples // 10) for r in twin_records])
    means = np.array([m for _, m, _ in err.per_run])
    np.testing.assert_allclose(err.mean, n @ means / n.sum(), rtol=1e-9, atol=1e-15)


def test_feedthrough_is_what_makes_order_4_fit(fitted, twin_records):
    with_d = run_errors(fitted, twin_records, 10).std
    no_d = run_errors(fit_linear(twin_records, DT, feedthrough=False), twin_records, 10).std
    assert np.all(no_d > 10 * with_d)  # measured: ~325 µm vs 8 / 17 µm


def test_decimation_brings_the_slowest_time_constant_to_the_twins(fitted, twin_records):
    twin_slow = -1.0 / xy_stage_twin().continuous_poles().real.max()  # 19.9 ms
    assert twin_slow == pytest.approx(0.02, rel=0.01)
    assert fitted.time_constants_s()[0] == pytest.approx(twin_slow, rel=0.5)
    at_10khz = fit_linear(twin_records, DT, decimate=1)  # ill-conditioned: poles near z = 1
    assert at_10khz.time_constants_s()[0] > 2.0 * twin_slow


def test_rest_state_holds_a_constant_input(fitted):
    u0 = np.array([0.05, -0.1])
    y = fitted.simulate(np.tile(u0, (50, 1)), rest_state(fitted, u0))
    np.testing.assert_allclose(y, np.tile(y[0], (50, 1)), atol=1e-15)
    assert np.all(np.abs(y[0] - u0) < 1e-3)  # static gain near 1


def test_decimate_is_scipys_fir_inside_holds_ends_and_stops_aliases():
    t = np.arange(20_000) * DT
    x = 0.01 * np.sin(2 * np.pi * 50 * t) + 0.02
    got = decimate(x, 10)
    assert got.shape == (2000,)
    ref = scipy.signal.decimate(x, 10, ftype="fir", zero_phase=True)
    np.testing.assert_allclose(got[20:-20], ref[20:-20], rtol=0, atol=1e-15)
    # 50 Hz passes within the Hamming design's ripple, with no phase (one 10 kHz sample of
    # delay would show as cos / sin = 0.031)
    tk = t[::10][20:-20]
    w = 2 * np.pi * 50
    basis = np.column_stack([np.sin(w * tk), np.cos(w * tk), np.ones_like(tk)])
    s, c, off = np.linalg.lstsq(basis, got[20:-20], rcond=None)[0]
    assert s == pytest.approx(0.01, rel=5e-3) and off == pytest.approx(0.02, rel=1e-6)
    assert abs(c / s) < 1e-4
    rest = np.full((3000, 2), [0.1, -0.05])
    np.testing.assert_allclose(decimate(rest, 10), rest[::10], rtol=1e-13)  # ends held
    alias = decimate(1e-3 * np.sin(2 * np.pi * 800 * t), 10)  # above the new 500 Hz Nyquist
    assert np.abs(alias[20:-20]).max() < 1e-5
    np.testing.assert_array_equal(decimate(x, 1), x)


def test_check_decimate_keeps_400_hz():
    assert check_decimate(25, 1e4) == 25
    with pytest.raises(ValueError, match="below 400 Hz; use decimate <= 25"):
        check_decimate(26, 1e4)
    with pytest.raises(ValueError, match="decimate"):
        check_decimate(0, 1e4)


def _trace(n: int = 6000, dt: float = DT, **cols) -> Trace:
    rng = np.random.default_rng(0)
    data = {c: np.cumsum(rng.standard_normal(n)) * 1e-6 for c in COLUMNS}
    data.update(cols)
    return Trace(dt=dt, values=np.column_stack(list(data.values())), axes=tuple(data), unit="m")


@pytest.mark.parametrize(
    ("trace", "says"),
    [
        (Trace(dt=DT, values=np.zeros((6000, 3)), axes=COLUMNS[:3], unit="m"), "'output_y'"),
        (Trace(dt=DT, values=np.zeros((6000, 4)), axes=COLUMNS, unit="mm"), "unit 'mm'"),
        (_trace(dt=1 / 10_001), "not a whole multiple of 400 Hz"),
        (_trace(dt=1 / 200), "not a whole multiple of 400 Hz"),
        (_trace(n=4999), "shorter than 500 ms"),
        (_trace(input_y=np.r_[np.zeros(5999), 0.2]), "input_y = 0.2 m at t = 0.5999 s"),
        (
            _trace(output_x=np.r_[np.zeros(10), 1e300, np.zeros(5989)]),
            "at t = 0.001 s is beyond 1 m",
        ),
    ],
)
def test_stage_record_refuses(trace: Trace, says: str):
    with pytest.raises(ValueError, match=says.replace("(", r"\(")):
        stage_record(trace, "f.csv")


def test_stage_record_takes_a_good_run_and_refuses_nan():
    rec = stage_record(_trace(n=5000), "f.csv")  # exactly 500 ms at 10 kHz
    assert rec.u.shape == rec.y.shape == (5000, 2) and not rec.u.flags.writeable
    y = np.zeros((10, 2))
    y[3, 1] = np.nan
    with pytest.raises(ValueError, match="output_y is nan at sample 3"):
        StageRecord(name="r", u=np.zeros((10, 2)), y=y)


def test_fit_linear_refusals(twin_records):
    with pytest.raises(ValueError, match="above block_rows"):
        fit_linear(twin_records, DT, order=5, block_rows=4)
    with pytest.raises(ValueError, match="order"):
        fit_linear(twin_records, DT, order=0)
    const = [StageRecord(name="c", u=np.full((6000, 2), 0.01), y=np.full((6000, 2), 0.01))]
    with pytest.raises(ValueError, match="not exciting enough"):
        fit_linear(const, DT)
    with pytest.raises(ValueError, match="400 Hz"):
        fit_linear(twin_records, 1 / 9000)


def test_model_file_round_trip_and_refusals(fitted, twin_records, tmp_path):
    path = tmp_path / "m.json"
    stage = StageLinearModel(model=fitted, input_dt=DT, decimate=10)
    write_stage_model(path, stage)
    back = read_stage_model(path)
    assert isinstance(back, StageLinearModel) and back.decimate == 10
    assert back.input_rate_hz == pytest.approx(1e4)
    np.testing.assert_array_equal(back.model.a, fitted.a)
    np.testing.assert_array_equal(back.errors(twin_records).std, stage.errors(twin_records).std)
    data = json.loads(path.read_text())
    assert data["format"] == FORMAT and data["kind"] == "linear"
    for change, says in [
        ({"version": 2}, "version 2 is not supported"),
        ({"kind": "ann"}, "kind 'ann' is not known"),
        ({"format": "x"}, "not a stage model"),
        ({"extra": 1}, "extra = 1 Extra inputs are not permitted"),
        ({"decimate": 5}, "not input_dt"),
        ({"model_rate_hz": 500.0}, "disagrees"),
        ({"axes": ["y", "x"]}, "expected ['x', 'y']"),
    ]:
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps({**data, **change}))
        with pytest.raises(ValueError, match=str(bad)) as exc:
            read_stage_model(bad)
        assert says in str(exc.value)
    with pytest.raises(ValueError, match=r"no model\.json: not a network model"):
        read_stage_model(tmp_path)  # a directory is a network model of `identify ann`
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(ValueError, match=r"not a stage model .*not JSON"):
        read_stage_model(tmp_path / "broken.json")


def test_reading_a_linear_model_imports_no_torch(fitted, tmp_path):
    # the "ann" reader of MODEL_KINDS imports `stage_ann` (so PyTorch) only when it reads
    path = tmp_path / "m.json"
    write_stage_model(path, StageLinearModel(model=fitted, input_dt=DT, decimate=10))
    code = (
        "import sys\n"
        "from microfab.identify.stage_data import read_stage_model\n"
        f"assert read_stage_model({str(path)!r}).kind == 'linear'\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'torch'\n"
        "             or m == 'microfab.identify.stage_ann'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_default_decimation_brings_any_rate_to_about_1_khz():
    from microfab.identify.stage_data import FIT_RATE_HZ, check_decimate, default_decimate

    assert FIT_RATE_HZ == 1000.0
    for rate, q in ((10_000.0, 10), (2_000.0, 2), (4_000.0, 4), (1_200.0, 1), (400.0, 1)):
        assert default_decimate(rate) == q
        assert check_decimate(q, rate) == q  # never below the 400 Hz floor
