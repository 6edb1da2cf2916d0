"""Whitened inputs of the networks' training, folded into the first layer (issue 46)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from microfab.identify.ann import AnnConfig, build_network  # noqa: E402
from microfab.identify.ann_data import Scaling, WindowSet, WindowSpec  # noqa: E402
from microfab.identify.ann_whiten import (  # noqa: E402
    fold,
    input_covariance,
    unfold,
    whitening,
)


def _runs(seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    u = np.cumsum(np.cumsum(rng.standard_normal((6000, 2)), axis=0), axis=0) * 1e-9
    u -= u[0]
    return [(u, 0.9 * u)]


def test_whitening_whitens_a_full_rank_covariance_and_inverts():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((6, 6))
    c = a @ a.T + 0.1 * np.eye(6)
    shrink = 1e-6  # the least allowed (WHITEN_LOW)
    w, w_inv = whitening(c, shrink)
    # float64 through LAPACK eigh: agreement to ~1e-12 relative measured; 1e-7 allows
    # any kernel while a wrong formula misses by order one. W whitens C plus its shrinkage.
    floor = shrink * np.trace(c) / 6
    np.testing.assert_allclose(w @ (c + floor * np.eye(6)) @ w, np.eye(6), atol=1e-7)
    np.testing.assert_allclose(w @ w_inv, np.eye(6), atol=1e-7)
    np.testing.assert_allclose(w, w.T, atol=1e-12)


def test_shrinkage_bounds_the_gain_of_an_unvisited_direction():
    c = np.diag([4.0, 2.0, 0.0])  # mean eigenvalue 2
    w, _ = whitening(c, 1e-2)
    # the empty direction: 1 / sqrt(0 + 0.01 * 2)
    assert w[2, 2] == pytest.approx(1.0 / np.sqrt(0.02), rel=1e-9)
    assert w[0, 0] == pytest.approx(1.0 / np.sqrt(4.02), rel=1e-9)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), 5e-324, 1e-9, 1.5])
def test_whitening_refuses_a_bad_shrinkage(bad):
    with pytest.raises(ValueError, match="whiten"):
        whitening(np.eye(3), bad)


def test_whitening_refuses_a_bad_matrix():
    with pytest.raises(ValueError, match="square"):
        whitening(np.ones((2, 3)), 1e-3)
    with pytest.raises(ValueError, match="finite"):
        whitening(np.array([[1.0, np.nan], [np.nan, 1.0]]), 1e-3)


@pytest.mark.parametrize("bad", [0.0, -1e-3, 2.0])
def test_config_refuses_a_bad_whiten(bad):
    with pytest.raises(ValueError, match="whiten"):
        AnnConfig(whiten=bad)


def test_fingerprint_of_an_unwhitened_training_is_as_before():
    assert "whiten" not in AnnConfig(whiten=None).fingerprint()
    assert AnnConfig().fingerprint()["whiten"] == 1e-3


def test_folded_network_reads_scaled_inputs_as_the_trained_one_read_whitened():
    spec = WindowSpec(h=20)
    ws = WindowSet(_runs(1), spec, (0, 5))
    scaling = ws.fit_scaling(0)
    cov = input_covariance(ws, 0, scaling)
    assert cov.shape == (20, 20)
    np.testing.assert_allclose(cov, cov.T)
    w, w_inv = whitening(cov, 1e-3)
    net = build_network(20, seed=3)
    x, _ = ws.batch(np.arange(0, len(ws), 7), 0)
    s = scaling.scale_inputs(x)
    with torch.no_grad():
        trained = net(torch.from_numpy(s @ w.astype(np.float32)))[:, 0].numpy()
        fold(net, w)
        folded = net(torch.from_numpy(s))[:, 0].numpy()
        unfold(net, w_inv)
        back = net(torch.from_numpy(s @ w.astype(np.float32)))[:, 0].numpy()
    # float32 products of order-one weights: differences of ~1e-5 of the output's spread
    # measured; 1e-3 keeps any kernel while a wrong fold differs by order one
    spread = float(np.std(trained))
    assert np.max(np.abs(folded - trained)) < 1e-3 * spread
    assert np.max(np.abs(back - trained)) < 1e-3 * spread


def test_covariance_strides_at_most_the_given_windows():
    spec = WindowSpec(h=20)
    ws = WindowSet(_runs(2), spec, (0,))
    scaling = ws.fit_scaling(1)
    few = input_covariance(ws, 1, scaling, most=50)
    every = input_covariance(ws, 1, scaling)
    assert few.shape == every.shape
    assert not np.allclose(few, every, rtol=1e-9)  # a subset, not all of them
    assert np.trace(every) == pytest.approx(20.0, rel=0.05)  # scaled: unit variance each
    _ = Scaling  # the type the covariance reads its inputs through


def test_shorter_epochs_sum_fewer_windows_but_never_too_few():
    from microfab.identify.ann_whiten import (
        COVARIANCE_WINDOWS,
        LEAST_COVARIANCE_WINDOWS,
        covariance_windows,
    )

    assert covariance_windows(None) == COVARIANCE_WINDOWS
    assert covariance_windows(262_144) == COVARIANCE_WINDOWS  # the job's epochs: as shipped
    assert covariance_windows(4096) == LEAST_COVARIANCE_WINDOWS
    assert covariance_windows(100_000) == 100_000
    assert covariance_windows(10**7) == COVARIANCE_WINDOWS
