"""Laser gate (seed 001 §4.2): off -> settling -> exposing -> done, property-tested."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from microfab.control.gate import (
    DONE,
    EXPOSING,
    OFF,
    SETTLING,
    GateConfig,
    LaserGate,
    run_gate,
)

H = 2.0**-12  # mm: errors are integer multiples of H, so every sum of squares is exact


def decaying_error(n: int, periods: int, ratio: float, first_rms: float) -> np.ndarray:
    """A 2-D error whose RMS norm over period j is first_rms * ratio**j."""
    t = np.arange(n * periods)
    j = t // n
    amp = first_rms * ratio**j
    ph = 2 * np.pi * t / n
    return amp[:, None] * np.column_stack([np.cos(ph), np.sin(ph)])


def test_opens_at_the_start_after_the_first_sub_micron_period_and_exposes_one_loop():
    n = 100
    # RMS per period 3, 1.5, 0.75, ... µm: the 3rd period (j = 2) is the first below 1 µm
    e = decaying_error(n, 8, 0.5, 3e-3)
    run = run_gate(e, GateConfig(period_samples=n))
    assert run.opened_at == 3 * n
    assert run.closed_at == 4 * n
    np.testing.assert_array_equal(np.flatnonzero(run.laser), np.arange(3 * n, 4 * n))
    assert run.mode[0] == SETTLING  # the contour starts at sample 0
    assert run.mode[3 * n - 1] == SETTLING and run.mode[3 * n] == EXPOSING
    assert run.mode[4 * n - 1] == EXPOSING and run.mode[4 * n] == DONE
    assert run.last_rms_mm == pytest.approx(0.75e-3)
    # a threshold never met: the gate stays closed
    never = run_gate(e, GateConfig(period_samples=n, threshold_mm=1e-6))
    assert never.opened_at is None and not never.laser.any()
    assert never.mode[-1] == SETTLING


def test_given_starts_and_leads():
    n = 50
    e = np.zeros((600, 2))
    e[:120] = 5e-3  # large before and during the first loop
    cfg = GateConfig(
        period_samples=n, starts=(100, 150, 260, 400), lead_on_samples=7, lead_off_samples=3
    )
    run = run_gate(e, cfg)
    assert run.mode[99] == OFF and run.mode[100] == SETTLING
    # loops [100, 150), [150, 200), [260, 310), [400, 450); decisions 7 samples before each
    # start: at 143 the last 50 samples begin before the contour (93), at 253 and 393 they
    # lie in the gaps between loops: no decision is valid, whatever the error
    assert run.opened_at is None
    cfg = GateConfig(
        period_samples=n, starts=(100, 150, 200, 250), lead_on_samples=7, lead_off_samples=3
    )
    run = run_gate(e, cfg)
    # loops back to back from 100: at 193 the window [143, 193) lies on the contour and is
    # clean (the error stops at 120): on from 193 to the loop's end 250 less lead_off 3
    assert run.opened_at == 193 and run.closed_at == 247
    assert run.laser.sum() == n + 7 - 3


def test_step_agrees_with_run_and_nan_fails_its_period():
    n = 20
    e = decaying_error(n, 6, 0.3, 3e-3)
    gate = LaserGate(GateConfig(period_samples=n))
    x = gate.init()
    on = []
    for k in range(e.shape[0]):
        lk, x = gate.step(x, e[k])
        on.append(lk)
    run = gate.run(e)
    np.testing.assert_array_equal(np.array(on), run.laser)
    np.testing.assert_array_equal(x, run.state)
    assert gate.mode_of(x) == "done"
    # a NaN sample in the period that would pass keeps the gate closed for that period
    x = gate.init()
    e2 = e.copy()
    e2[n + 5] = np.nan  # in period 1, the first below the threshold
    opened = None
    for k in range(e2.shape[0]):
        lk, x = gate.step(x, e2[k])
        if lk and opened is None:
            opened = k
    assert run.opened_at == 2 * n and opened == 3 * n
    with pytest.raises(ValueError, match="errors hold nan at sample 25, axis 0"):
        run_gate(e2, gate.config)


def test_run_continues_from_a_state():
    n = 10
    e = decaying_error(n, 6, 0.3, 3e-3)
    cfg = GateConfig(period_samples=n)
    whole = run_gate(e, cfg)
    a = run_gate(e[:23], cfg)
    b = run_gate(e[23:], cfg, a.state)
    np.testing.assert_array_equal(np.concatenate([a.laser, b.laser]), whole.laser)
    assert b.opened_at == whole.opened_at


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"threshold_mm": 0.0}, r"threshold_mm \(gate threshold\) must be positive"),
        ({"threshold_mm": -1e-3}, "threshold_mm"),
        ({"threshold_mm": float("nan")}, "must be positive and finite, got nan mm"),
        ({"period_samples": 1}, "period_samples must be an integer >= 2"),
        ({"period_samples": 2.5}, "period_samples must be an integer >= 2"),
        ({"lead_on_samples": 10}, r"lead_on_samples must be below the period \(10 samples\)"),
        ({"lead_off_samples": -1}, "lead_off_samples must be an integer >= 0"),
        ({"starts": (0, 5)}, "by fewer than one period"),
        ({"starts": ()}, "at least one"),
        ({"starts": (-1,)}, "contour start 0 must be an integer >= 0"),
    ],
)
def test_config_refused(kwargs: dict, match: str):
    with pytest.raises(ValueError, match=match):
        GateConfig(**({"period_samples": 10} | kwargs))


def test_from_period_refuses_a_fractional_period():
    assert GateConfig.from_period(period_s=1.0, dt=1e-4).period_samples == 10000
    with pytest.raises(ValueError, match="whole number"):
        GateConfig.from_period(period_s=1.00005, dt=1e-4)
    with pytest.raises(ValueError, match="errors must be shaped"):
        run_gate(np.zeros((0, 2)), GateConfig(period_samples=4))


@st.composite
def gate_cases(draw: st.DrawFn) -> tuple[np.ndarray, GateConfig]:
    n = draw(st.integers(2, 6))
    length = draw(st.integers(1, 60))
    ints = draw(
        st.lists(st.integers(-4, 4), min_size=2 * length, max_size=2 * length).map(
            lambda v: np.array(v, dtype=float).reshape(length, 2)
        )
    )
    thr = draw(st.integers(1, 5)) * H * draw(st.sampled_from([0.5, 1.0, 1.5, 2.0]))
    lead_on = draw(st.integers(0, n - 1))
    lead_off = draw(st.integers(0, n - 1))
    starts = None
    if draw(st.booleans()):
        gaps = draw(st.lists(st.integers(0, 3), min_size=1, max_size=12))
        s0 = draw(st.integers(0, 8))
        starts = [s0]
        for g in gaps[1:]:
            starts.append(starts[-1] + n + g)
        starts = tuple(starts)
    cfg = GateConfig(
        period_samples=n,
        threshold_mm=thr,
        starts=starts,
        lead_on_samples=lead_on,
        lead_off_samples=lead_off,
    )
    return ints * H, cfg


def _passes(e: np.ndarray, d: int, cfg: GateConfig, loops: list[tuple[int, int]]) -> bool:
    """Whether a decision at sample d may open: N samples before it, all on a loop, RMS < thr."""
    n = cfg.period_samples
    if d - n < 0:
        return False
    on = all(any(a <= k < b for a, b in loops) for k in range(d - n, d))
    if not on:
        return False
    return bool(np.sqrt(np.sum(e[d - n : d] ** 2) / n) < cfg.threshold_mm)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(gate_cases())
def test_gate_never_opens_unless_the_previous_full_period_met_the_criterion(case):
    e, cfg = case
    n, length = cfg.period_samples, e.shape[0]
    run = run_gate(e, cfg)
    starts = cfg.starts if cfg.starts is not None else tuple(range(0, length + n + 1, n))
    loops = [(s, s + n) for s in starts]
    decisions = [(s - cfg.lead_on_samples, s) for s in starts if s - cfg.lead_on_samples < length]
    on = np.flatnonzero(run.laser)
    first_ok = next(((d, s) for d, s in decisions if _passes(e, d, cfg, loops)), None)
    if first_ok is None:
        assert on.size == 0 and run.opened_at is None
        return
    d, s = first_ok
    # opens at the first decision instant whose previous full period met the criterion ...
    assert run.opened_at == d and on[0] == d
    # ... and exposes exactly one loop (shifted by the leads), then never again
    end = s + n - cfg.lead_off_samples
    np.testing.assert_array_equal(on, np.arange(d, min(end, length)))
    if end < length:
        assert run.closed_at == end and run.mode[-1] == DONE
    # the step-wise state machine gives the same laser command
    gate = LaserGate(cfg)
    x = gate.init()
    for k in range(length):
        lk, x = gate.step(x, e[k])
        assert lk == run.laser[k]
