"""Shared data of the identify tests: the seed's galvo model sampled as the twin would be.

Seed 003 part 2 (Buls et al.) §1: ``G(s) = 1.242e11 / (s^3 + 9517 s^2 + 5.773e7 s +
1.272e11)``, position command in bit to measured position in bit; §2: T = 10 µs. The
records are its ZOH discretisation (scipy here; the plant twin is built elsewhere) driven
by the default chirp, with seeded output noise of 0.3 bit rms (issue 16 §1, assumed).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from microfab.identify import Chirp, ChirpDesign

SEED_NUM = (1.242e11,)  # seed 003 part 2 §1
SEED_DEN = (1.0, 9517.0, 5.773e7, 1.272e11)  # seed 003 part 2 §1
DT = 1e-5  # seed 003 part 2 §2: "fs = 1e-5" (the sample period)
NOISE_RMS = 0.3  # issue 16 §1: assumed measurement noise, bit rms


def simulate(num, den, u: np.ndarray, *, noise_rms: float = 0.0, seed: int = 16) -> np.ndarray:
    """Output of the ZOH discretisation of ``num / den`` at ``DT`` for input ``u``, plus noise."""
    bd, ad, _ = scipy.signal.cont2discrete((num, den), DT, method="zoh")
    y = scipy.signal.lfilter(np.ravel(bd), ad, u)
    if noise_rms:
        y = y + noise_rms * np.random.default_rng(seed).standard_normal(u.size)
    return y


def zoh_response(num, den, f_hz: np.ndarray) -> np.ndarray:
    """Exact response of the ZOH discretisation at ``DT`` (python-control, state space)."""
    import control

    sysd = control.c2d(control.ss(control.tf(list(num), list(den))), DT, "zoh")
    return np.array([complex(control.evalfr(sysd, np.exp(2j * np.pi * f * DT))) for f in f_hz])


@pytest.fixture(scope="session")
def chirp() -> Chirp:
    """The default experiment: 10 Hz - 2 kHz, 100 bit, 1 s, 4 periods, first dropped."""
    return ChirpDesign().signal()


@pytest.fixture(scope="session")
def y_clean(chirp: Chirp) -> np.ndarray:
    """The seed model's output, no noise."""
    return simulate(SEED_NUM, SEED_DEN, chirp.input)


@pytest.fixture(scope="session")
def y_noisy(chirp: Chirp) -> np.ndarray:
    """The seed model's output with 0.3 bit rms seeded noise."""
    return simulate(SEED_NUM, SEED_DEN, chirp.input, noise_rms=NOISE_RMS)


@pytest.fixture(scope="session")
def simulate_zoh():
    """`simulate`: output of a ZOH-sampled model for an input (test files call it)."""
    return simulate


@pytest.fixture(scope="session")
def exact_zoh():
    """`zoh_response`: the exact ZOH frequency response by python-control."""
    return zoh_response
