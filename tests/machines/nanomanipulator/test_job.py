"""The seed 001 job on the twin: gate, hand-over, resume, cured lines (issue 14 acceptance)."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.machines.nanomanipulator.chunks import job_segments
from microfab.machines.nanomanipulator.cure import cure_circles
from microfab.machines.nanomanipulator.job import (
    JobConfig,
    RCSettings,
    TwinSettings,
    run_job,
)
from microfab.trajectory.circle_pattern import PatternConfig

#: The twin the seed's network was calibrated on (issue 14's white sensor noise fitted to
#: the axial RMS of seed 001 §4.2 under that network, and the assumed d0 of 20 / 40
#: mm/s²): the mechanics below are tested on that fixed scenario, not on the shipped
#: twin, which issue 45 calibrates for the default, proposed controller.
SEED_NETWORK_TWIN = TwinSettings(
    noise_rms_mm=(3.2323e-4, 7.2690e-4),
    noise_time_constant_s=(0.0, 0.0),
    disturbance_mm_s2=(20.0, 40.0),
)


@pytest.fixture(scope="module")
def default_run():
    """Four circles, six periods, noise and disturbance on, under the seed's network.

    The job's mechanics (hand-over, RC, gate, cured lines) as issue 14 built them around
    the seed's network (``controller = "seed"``) on `SEED_NETWORK_TWIN`; the default,
    proposed controller is tested on a smaller job below.
    """
    return run_job(JobConfig(controller="seed", twin=SEED_NETWORK_TWIN))


@pytest.fixture(scope="module")
def cures(default_run):
    return cure_circles(default_run)


SMALL = JobConfig(
    pattern=PatternConfig(n_circles=2, periods=3, field_mm=0.3),
    controller="seed",
    twin=SEED_NETWORK_TWIN,
)


def test_segments_cover_the_job_once(default_run):
    ref = default_run.reference
    segs = job_segments(ref, default_run.config.pattern)
    assert segs[0].start == 0 and segs[-1].stop == ref.n_samples
    assert all(a.stop == b.start for a, b in itertools.pairwise(segs))
    circles = [s for s in segs if s.circle is not None]
    assert [s.circle for s in circles] == list(range(len(ref.starts)))
    for s, start in zip(circles, ref.starts, strict=True):
        assert s.start < start and start + ref.periods * ref.period_samples <= s.stop


def test_gate_opens_in_period_3_or_4(default_run):
    # seed 001 §4.2: "the tracking error reaches submicrons in 3-4 periods"
    periods = [c.gate_period for c in default_run.circles]
    assert all(p in paper.GATE_PERIODS for p in periods), periods


def test_gate_exposes_one_loop_after_a_period_under_the_threshold(default_run):
    run = default_run
    N = run.reference.period_samples
    e = run.error
    for c in run.circles:
        assert c.gate_closed - c.gate_opened == N
        before = e[c.gate_opened - N : c.gate_opened]
        assert np.sqrt(np.mean(np.sum(before**2, axis=1))) < run.config.gate_threshold_mm
        on = np.flatnonzero(run.laser[max(c.start - N, 0) : c.start + run.reference.periods * N])
        assert on.size == N


def test_handover_keeps_the_pause_on_the_circle(default_run):
    """The RBF takes over from the transfer PID without a bump (rbf_handover)."""
    run = default_run
    segs = job_segments(run.reference, run.config.pattern)
    for s in segs:
        if s.circle is None or s.start == 0:
            continue
        first = run.reference.starts[s.circle]
        worst = np.abs(run.true_error[s.start : first]).max()
        assert worst < 5e-3, f"circle {s.circle}: {worst * 1e3:.1f} µm during pause and ramp"


def test_rc_converges_below_the_first_period(default_run):
    m = default_run.metrics()
    assert np.all(m.period_rms_nm[:, -1] < 0.7 * m.period_rms_nm[:, 0])


@pytest.mark.parametrize(("carry", "checkpoint_s"), [(False, 1.0), (True, 1.0), (False, 0.0)])
def test_resume_after_interruption_is_bit_identical(tmp_path, carry, checkpoint_s):
    # 5 chunks: the first transfer and circle 1; circle 2 then starts after the resume.
    # checkpoint_s 1: the small job runs in well under 1 s, so the 5 chunks are saved by
    # the interruption itself; 0: one checkpoint per chunk.
    config = dataclasses.replace(SMALL, rc=RCSettings(carry=carry))
    whole = run_job(config)

    class StopError(Exception):
        pass

    def stop_after(task, done, total):
        if done == 5:
            raise StopError

    with pytest.raises(StopError):
        run_job(config, tmp_path, stop_after, checkpoint_s=checkpoint_s)
    files = sorted(p.name for p in (tmp_path / "run" / "chunks").glob("*.npz"))
    if checkpoint_s == 0.0:
        assert files == [f"{c:05d}.npz" for c in range(5)]
    again = run_job(config, tmp_path, checkpoint_s=checkpoint_s)
    assert again.resumed_from == 5
    for name in ("output", "measured", "command", "laser", "weight_norm", "s"):
        np.testing.assert_array_equal(getattr(again, name), getattr(whole, name), err_msg=name)
    for a, b in zip(again.circles, whole.circles, strict=True):
        np.testing.assert_array_equal(a.weights, b.weights)
        np.testing.assert_array_equal(a.rc_memory.memory, b.rc_memory.memory)


def test_another_config_refuses_the_saved_run(tmp_path):
    one = JobConfig(pattern=PatternConfig(n_circles=1, periods=1), controller="seed")
    run_job(one, tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    other = dataclasses.replace(one, twin=TwinSettings(seed=1))
    with pytest.raises(ValueError, match="job checkpoint of other settings"):
        run_job(other, tmp_path)
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_carry_seeds_the_next_circle(tmp_path):
    plain = run_job(SMALL)
    carried = run_job(dataclasses.replace(SMALL, rc=RCSettings(carry=True)))
    m0, m1 = plain.metrics(), carried.metrics()
    # same first circle; the second starts from a learned memory
    np.testing.assert_array_equal(m0.period_rms_nm[0], m1.period_rms_nm[0])
    assert m1.period_rms_nm[1, 0] < m0.period_rms_nm[1, 0]


def test_gated_line_is_the_seed_width(cures):
    # seed 001 §4.2, Fig. 15: "~2.5 µm"; issue 14: 2.5 µm ± 10 % along the gated loop (mean)
    for c in cures:
        lp = c.prints["compensated"].loop
        assert lp.closed
        w = lp.widths.width_m[lp.widths.width_m > 0] * 1e6
        assert abs(np.mean(w) - paper.LINE_WIDTH_UM) <= 0.1 * paper.LINE_WIDTH_UM


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="pointwise: 93.0-94.6 % of each gated loop is within 2.5 µm ± 10 % (the spot "
    "follows the fed-back sensor noise; width std 0.13 µm), not 95 %",
)
def test_gated_line_width_holds_at_95_percent_of_the_loop(cures):
    for c in cures:
        lp = c.prints["compensated"].loop
        w = lp.widths.width_m[lp.widths.width_m > 0] * 1e6
        share = np.mean(np.abs(w - paper.LINE_WIDTH_UM) <= 0.1 * paper.LINE_WIDTH_UM)
        assert share >= 0.95, f"circle {c.circle}: {share:.1%} of the loop within 10 %"


def test_warmup_compensation_closes_the_loop(cures):
    for c in cures:
        gated, comp = c.prints["gated"].loop, c.prints["compensated"].loop
        assert not gated.closed and gated.gap_m > 0.5e-6
        assert comp.closed and comp.gap_m == 0.0
        assert abs(comp.closing_width_m * 1e6 - paper.LINE_WIDTH_UM) <= 0.1 * paper.LINE_WIDTH_UM


def test_ungated_print_is_off_the_circle(cures):
    """Exposing the first (unconverged) loop puts the line farther off the intended circle."""
    for c in cures:
        off = {}
        for name in ("compensated", "ungated"):
            lp = c.prints[name].loop
            o = lp.widths.offset_m[lp.widths.width_m > 0]
            off[name] = np.sqrt(np.mean(o**2))
        assert off["ungated"] > 1.2 * off["compensated"], off


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="cured-line overlap: gap is speed x warm-up - 2 tails",
)
def test_uncompensated_gap_is_speed_times_warmup(cures, default_run):
    cfg = default_run.config
    speed = np.pi * cfg.pattern.diameter_mm * 1e-3 / cfg.pattern.period_s
    expect = speed * cfg.laser.warmup_s
    cell = cfg.dose.cell_m
    gaps = [c.prints["gated"].loop.gap_m for c in cures]
    assert all(abs(g - expect) <= cell for g in gaps), (gaps, expect)


@pytest.fixture(scope="module")
def proposed_run():
    """The default controller (eq. 6's PD + the state-model network, in the RC), one
    circle, four periods, the twin's sensor noise off."""
    cfg = JobConfig(pattern=PatternConfig(n_circles=1, periods=4), twin=TwinSettings(noise=False))
    assert cfg.controller == "proposed" == JobConfig().controller
    return run_job(cfg)


def test_proposed_controller_tracks_submicron_from_its_first_period(proposed_run):
    # measured (noise off): 202, 298, 211, 234 nm; its network adapts (‖Ŵ‖ grows from 0)
    m = proposed_run.metrics()
    assert np.all(m.period_rms_nm < 400.0), m.period_rms_nm
    assert proposed_run.circles[0].gate_period == 2
    assert np.all(np.linalg.norm(proposed_run.circles[0].weights, axis=1) > 0)
    assert proposed_run.circles[0].rbf.n_nodes == 189


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 45: the proposed controller is submicron from its first period (noise "
    "off 202 nm), so the gate opens in period 2, not the seed's 3-4 (the seed's network: 3); "
    "on the twin recalibrated for it (`calibrate nanomanipulator`, axial RMS fitted) the "
    "gate-period check is missed the same way (period 2)",
)
def test_proposed_gate_opens_in_period_3_or_4(proposed_run):
    assert proposed_run.circles[0].gate_period in paper.GATE_PERIODS


def test_an_unknown_controller_is_refused():
    with pytest.raises(ValueError, match="controller must be one of proposed, seed"):
        JobConfig(controller="pid")
