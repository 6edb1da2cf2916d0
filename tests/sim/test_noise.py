"""The compiled noise draw gives NumPy's normals bit for bit and moves the generator alike."""

from __future__ import annotations

import numpy as np
import pytest

from microfab.machines.simulated import EncoderNoise
from microfab.sim.noise import scaled_normal


@pytest.mark.parametrize("seed", [0, 1, 2024])
def test_scaled_normal_is_numpys_draw_bit_for_bit(seed):
    """~1.5 M normals a seed: some 400 come from the ziggurat's tail, 18 000 its wedges."""
    scale = np.array([1e-3, 2.5e-4, 1.0])
    ours, numpys = np.random.default_rng(seed), np.random.default_rng(seed)
    for n in (0, 1, 7, 2500, 500_000):
        got = scaled_normal(ours, n, scale)
        want = numpys.standard_normal((n, scale.size)) * scale[None, :]
        assert got.shape == want.shape
        assert got.tobytes() == want.tobytes()
        assert ours.bit_generator.state == numpys.bit_generator.state


def test_scaled_normal_on_another_bit_generator():
    ours = np.random.Generator(np.random.Philox(7))
    numpys = np.random.Generator(np.random.Philox(7))
    got = scaled_normal(ours, 10_000, np.array([3.0]))
    assert got.tobytes() == (numpys.standard_normal((10_000, 1)) * 3.0).tobytes()


def test_encoder_noise_draws_the_documented_expression():
    noise = EncoderNoise(rms=(1e-3, 0.0), seed=5)
    a, b = np.random.default_rng(noise.seed), np.random.default_rng(noise.seed)
    got = noise.draw(a, 1000)
    want = b.standard_normal((1000, 2)) * np.asarray(noise.rms)[None, :]
    assert got.tobytes() == want.tobytes()
    assert np.all(got[:, 1] == 0.0)
