"""BlockNLP: derivatives assembled from per-block functions equal CasADi's own."""

from __future__ import annotations

import numpy as np
import pytest

ca = pytest.importorskip("casadi")

from microfab.optimize.blocks import Block, BlockNLP  # noqa: E402


def chain(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    v, p = ca.SX.sym("v", 2), ca.SX.sym("p", 1)
    rows = ca.Function("r", [v, p], [ca.vertcat(v[1] ** 2 - ca.sin(v[0]) * p, v[0] * v[1] ** 3)])
    cost = ca.Function("c", [v, p], [(v[0] - p) ** 2 + v[0] * v[1] ** 2])
    idx = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    idx[::2] = idx[::2, ::-1]  # local order against the global one: the triangle flips
    par = rng.normal(size=(n - 1, 1))
    return rows, cost, idx, par, rng


def test_derivatives_equal_the_flat_graph():
    n = 25
    rows, cost, idx, par, rng = chain(n)
    nlp = BlockNLP(n, [Block(rows, cost, idx, par)])
    x = ca.SX.sym("x", n)
    g, f = [], 0
    for k in range(n - 1):
        vv = ca.vertcat(x[int(idx[k, 0])], x[int(idx[k, 1])])
        g.append(rows(vv, par[k]))
        f += cost(vv, par[k])
    g = ca.vertcat(*g)
    lam, sig = ca.SX.sym("l", g.shape[0]), ca.SX.sym("s")
    hess = ca.triu(ca.hessian(sig * f + ca.dot(lam, g), x)[0])
    ref = ca.Function("ref", [x, lam, sig], [f, ca.gradient(f, x), g, ca.jacobian(g, x), hess])
    x0, l0 = rng.normal(size=n), rng.normal(size=g.shape[0])
    want = [np.array(ca.densify(w)) for w in ref(x0, l0, 0.7)]
    f_, grad = nlp.grad_f(x0, [])
    g_, jac = nlp.jac_g(x0, [])
    h_ = nlp.hess_lag(x0, [], 0.7, l0)
    got = [np.array(ca.densify(w)) for w in (f_, grad, g_, jac, h_)]
    for a, b in zip(got, want, strict=True):
        assert np.allclose(a, b, atol=1e-12)


def test_solves_like_the_flat_problem():
    n = 15
    rows, cost, idx, par, rng = chain(n, seed=3)
    nlp = BlockNLP(n, [Block(rows, cost, idx, par)])
    x0 = rng.normal(size=n)
    sol = nlp.solver({"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"})(
        x0=x0, lbg=-1, ubg=1
    )
    assert np.isfinite(float(sol["f"]))
    g = np.array(sol["g"]).ravel()
    assert np.all(np.abs(g) <= 1 + 1e-6)


def test_refusals():
    rows, cost, idx, par, _ = chain(6)
    with pytest.raises(ValueError, match="within the variables"):
        BlockNLP(3, [Block(rows, cost, idx, par)])
    bad = idx.copy()
    bad[0] = [1, 1]
    with pytest.raises(ValueError, match="twice"):
        BlockNLP(6, [Block(rows, cost, bad, par)])
