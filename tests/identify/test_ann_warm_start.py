"""Warm start of the networks' training (seed 002 §III-C.2: a generation trained further)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

torch = pytest.importorskip("torch")

from microfab.identify.ann import AnnConfig, build_network  # noqa: E402
from microfab.identify.ann_data import WindowSpec  # noqa: E402
from microfab.identify.ann_train import (  # noqa: E402
    CheckpointMismatchError,
    init_digest,
    train_ann,
)

FS = 10_000.0


def lag_run(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A smooth random command from rest and a first-order lag's response (10 ms)."""
    rng = np.random.default_rng(seed)
    b, a = scipy.signal.butter(2, 3.0 / (FS / 2))
    u = np.cumsum(scipy.signal.lfilter(b, a, rng.standard_normal((n, 2)), axis=0), axis=0)
    u -= u[0]
    u *= 2e-3 / np.abs(u).max()
    ramp = np.clip(np.arange(n) / 2000.0, 0.0, 1.0)
    u *= (ramp**2 * (3 - 2 * ramp))[:, None]
    k = 1.0 / (0.01 * FS)
    return u, scipy.signal.lfilter([k], [1.0, k - 1.0], u, axis=0)


TRAIN = [lag_run(12_000, s) for s in range(3)]
MORE = [lag_run(12_000, s) for s in (20, 21)]
VAL = [lag_run(8_000, 10)]


def config(**kw) -> AnnConfig:
    base = dict(window=WindowSpec(h=20), batch_size=512, offsets=(0, 7, 13),
                learning_rate=2e-3, max_epochs=3, device="cpu", threads=1)  # fmt: skip
    return AnnConfig(**{**base, **kw})


def same(a, b) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return all(torch.equal(sa[k], sb[k]) for k in sa)


@pytest.fixture(scope="module")
def first():
    return train_ann(TRAIN, VAL, config(max_epochs=6))


def test_warm_start_starts_from_the_previous_weights(first):
    # a step far below float32 resolution: the weights cannot move, so what comes back
    # is what the training started from
    still = config(max_epochs=1, learning_rate=1e-30)
    warm = train_ann(TRAIN + MORE, VAL, still, init=first)
    # unwhitened, so that the cold start's network comes back as it was built (a
    # whitened one comes back with the whitening folded into its first layer)
    cold = train_ann(TRAIN + MORE, VAL, config(max_epochs=1, learning_rate=1e-30, whiten=None))
    for a in ("x", "y"):
        assert same(warm.networks[a], first.networks[a])
        assert warm.scalings[a] == first.scalings[a]  # the scaling is kept, not refitted
        assert same(cold.networks[a], build_network(20, seed=1000 * ("x", "y").index(a)))
        assert not same(cold.networks[a], first.networks[a])
    assert warm.info["init_digest"] == init_digest(first)


def test_warm_start_continues_where_the_previous_training_ended(first):
    warm = train_ann(TRAIN + MORE, VAL, config(max_epochs=2), init=first)
    cold = train_ann(TRAIN + MORE, VAL, config(max_epochs=2))
    for a in ("x", "y"):
        h_warm = warm.info["axes"][a]["history"]
        h_cold = cold.info["axes"][a]["history"]
        # the first epoch's training loss: the start is already trained (its validation
        # loss after one epoch may rise a little while Adam, restarted, takes its first
        # steps on the larger data: 0.034 -> 0.041 on y with whitened inputs)
        assert h_warm[0][0] < 0.2 * h_cold[0][0]
        best = warm.info["axes"][a]["best_val_loss"]
        assert best <= first.info["axes"][a]["best_val_loss"] * 1.0001  # never worse


def test_checkpoints_of_another_start_refused(first, tmp_path):
    other = train_ann(TRAIN, VAL, config(max_epochs=1, seed=3))
    d = tmp_path / "ck"
    train_ann(TRAIN + MORE, VAL, config(max_epochs=1), init=first, checkpoint_dir=d)
    with pytest.raises(CheckpointMismatchError, match="init_digest"):
        train_ann(TRAIN + MORE, VAL, config(max_epochs=2), init=other, checkpoint_dir=d)
    with pytest.raises(CheckpointMismatchError, match="init_digest"):
        train_ann(TRAIN + MORE, VAL, config(max_epochs=2), checkpoint_dir=d)  # a cold start
    resumed = train_ann(TRAIN + MORE, VAL, config(max_epochs=2), init=first, checkpoint_dir=d)
    assert resumed.info["axes"]["x"]["epochs"] == 2


def test_a_start_of_other_inputs_refused(first):
    with pytest.raises(ValueError, match="warm start needs the same inputs"):
        train_ann(TRAIN, VAL, config(window=WindowSpec(h=24)), init=first)
