"""Seed 001 Fig. 9 on the paper's model: the target of paper.FIG_TARGETS and the reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from microfab.experiments.seed001_nanomanipulator import paper
from microfab.experiments.seed001_nanomanipulator.compare import ComparisonConfig
from microfab.experiments.seed001_nanomanipulator.fig9 import (
    Fig9Config,
    Fig9Matched,
    fig9_matched,
    fig9_reference,
)
from microfab.trajectory.circle_pattern import pattern_reference

DT = 1e-4  # s: the twin's 10 kHz (data/nanomanipulator_twin.toml)


@pytest.fixture(scope="module")
def matched() -> Fig9Matched:
    return fig9_matched()  # x 1 Hz, y √2 Hz, 8 periods, noise off; 200 and 400 Hz


@pytest.mark.mutate(
    only=1.5, reason="a ceiling (RBF below the PID): our error halved still meets it"
)
def test_fig9_rbf_below_pid_at_200_hz_with_45_deg(matched: Fig9Matched, scaled) -> None:
    i = matched.bandwidths_hz.index(200.0)
    pid, rbf = matched.final("PID")[i], scaled(matched.final("RBF")[i])
    # measured: PID 182-192 nm over the 8 periods (190 last), RBF 256 -> 137 nm (learning)
    assert 150.0 < pid < 230.0, matched.table()
    for c in ("PID", "RBF"):  # the design's 45° measured on the discrete loop (45.0)
        assert (
            matched.phase_margin_deg[c][i] >= paper.FIG_TARGETS["fig9_phase_margin_min_deg"] - 0.5
        ), matched.table()
    assert rbf / pid <= paper.FIG_TARGETS["fig9_rbf_over_pid_max"], matched.table()
    # it learns: the last period below the first
    assert matched.rms_nm["RBF"][i, -1] < 0.8 * matched.rms_nm["RBF"][i, 0], matched.table()


@pytest.mark.xfail(
    raises=AssertionError,
    strict=True,
    reason="issue 45: at 400 Hz the PID keeps 24-25 nm and the state-model RBF levels "
    "off at 73 nm (last of 8 periods; 196 in the first); its ideal, the oracle of the "
    "true §4.1 terms, gives 4 nm: the network's learning is slow, not its linear part",
)
def test_fig9_rbf_below_pid_at_400_hz(matched: Fig9Matched) -> None:
    i = matched.bandwidths_hz.index(400.0)
    assert matched.phase_margin_deg["RBF"][i] >= 44.5, matched.table()
    ratio = matched.final("RBF")[i] / matched.final("PID")[i]
    assert ratio <= paper.FIG_TARGETS["fig9_rbf_over_pid_max"], matched.table()


def test_reference_is_two_uncorrelated_sines_with_the_circle_stroke_and_offset() -> None:
    cfg = Fig9Config()
    ref = fig9_reference(cfg, DT)
    circle = ComparisonConfig()
    c, A = circle.offset_mm, circle.pattern.diameter_mm / 2
    P, V, Acc = ref.position, ref.velocity, ref.acceleration
    assert ref.period_samples == 10_000 and ref.periods == 8
    # at rest on the offset point before the ramp, like the circle's lead-in
    lead = round((circle.pattern.move_s + circle.pattern.pause_s) / DT)
    np.testing.assert_array_equal(P[:lead], c)
    np.testing.assert_array_equal(V[:lead], 0.0)
    run = slice(ref.start, None)
    t = np.arange(P.shape[0] - ref.start) * DT
    for a, f in enumerate((1.0, math.sqrt(2.0))):
        np.testing.assert_allclose(P[run, a], c + A * np.sin(2 * math.pi * f * t), atol=1e-15)
    # the circle's stroke per axis
    circ = pattern_reference(circle.pattern, DT)
    np.testing.assert_allclose(np.ptp(P[run], axis=0), np.ptp(circ.position, axis=0), rtol=1e-3)
    # derivatives agree with central differences (lead-in, ramp and run): O(dt²) error, but
    # for the acceleration at the ramp's two ends, where the jerk jumps (by up to
    # 60 A / ramp_s³ = 290 mm/s³: ~7e-3 mm/s² there)
    np.testing.assert_allclose(np.gradient(P, DT, axis=0)[1:-1], V[1:-1], rtol=0, atol=1e-5)
    smooth = np.ones(P.shape[0], bool)
    smooth[[0, lead - 1, lead, ref.start - 1, ref.start, -1]] = False
    np.testing.assert_allclose(np.gradient(V, DT, axis=0)[smooth], Acc[smooth], rtol=0, atol=1e-3)
    # no cross-correlation: over all lags below 0.1 here (measured 0.086), 1 on the circle
    assert _max_cross_correlation(P[run]) < 0.1
    circle_run = circ.position[circ.circle_slice(0)]
    assert _max_cross_correlation(circle_run) > 0.99


def _max_cross_correlation(p: np.ndarray) -> float:
    """Largest normalised cross-correlation of the two columns over all lags (circular)."""
    x, y = (p[:, i] - p[:, i].mean() for i in range(2))
    xc = np.fft.irfft(np.fft.rfft(x) * np.conj(np.fft.rfft(y)), n=x.size)
    return float(np.abs(xc).max() / math.sqrt(np.sum(x * x) * np.sum(y * y)))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frequencies_hz": (1.0, 1.0)}, r"frequencies_hz are equal \(1 Hz\)"),
        ({"frequencies_hz": (1.0,)}, "one frequency per axis"),
        ({"frequencies_hz": (-1.0, 2.0)}, r"frequencies_hz\[x\] must be positive"),
        ({"fit_s": 0.0}, "fit_s must be positive"),
        ({"circle": "circle"}, "circle must be a ComparisonConfig"),
    ],
)
def test_config_refuses_bad_values(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Fig9Config(**kwargs)


def test_an_x_period_of_no_whole_samples_is_refused() -> None:
    with pytest.raises(ValueError, match="whole"):
        fig9_reference(Fig9Config(frequencies_hz=(3.0, 4.0)), DT)
