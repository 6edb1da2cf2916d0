"""NetworkMap: the networks as a differentiable map of the 400 Hz input (eq. 7)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

from microfab.optimize.ann_torch import NetworkMap


@pytest.fixture(params=["seed inputs", "position features"])
def networks(request, tiny_models, tiny_feature_model):
    return tiny_models[1] if request.param == "seed inputs" else tiny_feature_model


def test_predict_equals_the_model_on_the_matching_command(networks):
    model = networks
    nm = NetworkMap(model, tail=30)
    rng = np.random.default_rng(0)
    rest = np.array([1e-3, -2e-3])
    m = 120
    r = rest + np.cumsum(np.cumsum(rng.normal(size=(m, 2)) * 2e-6, axis=0), axis=0)
    phi = nm.predict(r, rest)
    assert phi.shape == (m + 30, 2)
    lead = 5
    cmd400 = np.vstack([np.repeat(rest[None], lead, axis=0), r, np.repeat(r[-1:], 250, axis=0)])
    ref = model.predict(np.repeat(cmd400, 25, axis=0), at="400hz", offset=0)
    # the same networks on the same windows (batched differently: float32 rounding, < 1 nm)
    assert np.allclose(ref[lead + 1 : lead + 1 + m + 30], phi, rtol=0, atol=1e-9)


def test_jacobian_matches_autograd_of_the_whole_map(networks):
    """The scattered band equals torch's dense Jacobian of r -> φ built independently."""
    import torch

    model = networks
    tail, m = 10, 40
    nm = NetworkMap(model, tail=tail)
    rng = np.random.default_rng(1)
    rest = np.array([2e-4, -1e-4])
    r = rest + np.cumsum(rng.normal(size=(m, 2)) * 2e-5, axis=0)
    phi, jac = nm.linearize(r, rest)
    assert np.array_equal(phi, nm.predict(r, rest))
    assert jac.shape == (2 * (m + tail), 2 * m)
    h = nm.h

    def full(rt):  # (2, m) -> (2 (m + tail),), the series built in torch
        rows = []
        for k, _a in enumerate(("x", "y")):
            pre = torch.full((h - 1,), float(rest[k]), dtype=torch.float64)
            post = rt[k, -1].repeat(tail)
            rows.append(torch.cat([pre, rt[k], post]))
        wins = {a: rows[k].unfold(0, h, 1) for k, a in enumerate(("x", "y"))}
        return torch.cat([nm._phi(wins, "x"), nm._phi(wins, "y")])

    dense = torch.autograd.functional.jacobian(full, torch.tensor(r.T.copy()))
    dense = dense.reshape(2 * (m + tail), 2 * m).numpy()
    assert np.allclose(jac.toarray(), dense, rtol=1e-12, atol=1e-12)
    # causal and per axis ("own" inputs): output i reads r_0 … r_{i-1} of its own axis
    assert np.all(dense[: m + tail, m:] == 0) and np.all(dense[m + tail :, :m] == 0)
    assert np.all(np.triu(dense[:m, :m], 1) == 0)


def test_jacobian_agrees_with_finite_differences(tiny_models):
    _, model = tiny_models
    nm = NetworkMap(model, tail=0)
    rng = np.random.default_rng(2)
    m = 50
    r = np.cumsum(rng.normal(size=(m, 2)) * 2e-5, axis=0)
    _, jac = nm.linearize(r, np.zeros(2))
    for c in (3, 20, m + 7):
        e = np.zeros(2 * m)
        e[c] = 1e-7
        d = e.reshape(2, m).T
        fd = ((nm.predict(r + d, np.zeros(2)) - nm.predict(r - d, np.zeros(2))) / 2e-7).T.ravel()
        col = jac[:, c].toarray().ravel()
        # float32 networks with LeakyReLU kinks: a difference that straddles a kink is
        # off; the others agree to 1 %
        ok = np.abs(fd - col) <= 1e-2 * max(1.0, np.abs(col).max())
        assert ok.mean() >= 0.95


def test_refusals(tiny_models):
    _, model = tiny_models
    nm = NetworkMap(model)
    with pytest.raises(ValueError, match="finite"):
        nm.predict(np.full((5, 2), np.nan), np.zeros(2))
    with pytest.raises(ValueError, match="tail"):
        NetworkMap(model, tail=-1)


def test_threads_are_set_inside_and_restored(tiny_models):
    """One torch thread inside `predict` / `linearize` (issue 34), the caller's after."""
    import torch

    _, model = tiny_models
    rng = np.random.default_rng(2)
    rest = np.array([1e-4, 2e-4])
    r = rest + np.cumsum(rng.normal(size=(60, 2)) * 1e-5, axis=0)
    before = torch.get_num_threads()
    seen = []
    net = model.networks["x"]
    hook = net.register_forward_pre_hook(lambda *_: seen.append(torch.get_num_threads()))
    try:
        torch.set_num_threads(2)
        one = NetworkMap(model, tail=5)
        phi1, jac1 = one.linearize(r, rest)
        assert torch.get_num_threads() == 2 and set(seen) == {1}
        seen.clear()
        mine = NetworkMap(model, tail=5, threads=None)
        phi2, jac2 = mine.linearize(r, rest)
        assert set(seen) == {2}
        # the same networks; float32 sums may split differently over two threads
        assert np.allclose(phi1, phi2, rtol=0, atol=1e-9)
        assert np.allclose(jac1.toarray(), jac2.toarray(), rtol=1e-5, atol=1e-6)
        assert np.array_equal(one.predict(r, rest), phi1)
    finally:
        hook.remove()
        torch.set_num_threads(before)
    with pytest.raises(ValueError, match="threads must be"):
        NetworkMap(model, threads=0)
