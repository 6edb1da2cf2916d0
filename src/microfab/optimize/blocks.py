"""A block-structured NLP for CasADi + IPOPT whose derivatives are built per block.

A transcription such as stage 1's (eqs. 8-12) repeats one small set of rows at every
point, each row reading a few neighbouring variables. Handed to ``nlpsol`` as one flat SX
graph, CasADi differentiates the whole graph (the Jacobian and the Hessian of the
Lagrangian of ~7000 variables took 7 s at N = 1000, longer than IPOPT's solve); handed as
MX maps of the per-point functions, every evaluation of a derivative calls ~10³ small
functions (44 ms per Jacobian). Here each block type is differentiated *once*, as a small
SX function of its own variables, mapped over the blocks, and the global sparse
Jacobian, gradient and upper-triangular Hessian are assembled from the blocks' nonzeros by
one constant sparse matrix each (duplicates, where blocks share a variable, summed). The
three are given to ``nlpsol`` as ``grad_f``, ``jac_g`` and ``hess_lag``: building takes
well under a second and an evaluation costs about what the flat SX one does.

`Block`: one block type (its rows, its cost term, which global variables each block
reads, its constant parameters); `BlockNLP`: the blocks and the number of variables;
`BlockNLP.solver` the IPOPT solver. The row order of ``g`` is block type by block type,
then block by block, then row by row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

__all__ = ["Block", "BlockNLP", "casadi_dm", "casadi_sparsity"]


@dataclass(frozen=True, eq=False)
class Block:
    """One block type of a `BlockNLP`.

    Parameters
    ----------
    rows : casadi.Function
        SX function ``(v[V], p[P]) -> rows[R]`` of the block's local variables and
        parameters (``R`` may be 0 when the block only adds cost).
    cost : casadi.Function or None
        SX function ``(v[V], p[P]) -> scalar``, the block's term of the objective.
    index : numpy.ndarray
        Shape (n_blocks, V): the global variable of each local one (distinct per block).
    params : numpy.ndarray
        Shape (n_blocks, P), P ≥ 1 (pad with a zero column when there are none).
    """

    rows: Any
    cost: Any
    index: np.ndarray
    params: np.ndarray

    @property
    def n_blocks(self) -> int:
        """Number of blocks of this type."""
        return int(self.index.shape[0])

    @property
    def n_rows(self) -> int:
        """Rows per block ``R``."""
        return int(self.rows.size1_out(0))


def _assembly(target: np.ndarray, n_target: int) -> sp.csr_matrix:
    """Sparse 0/1 matrix summing source entry ``i`` into ``target[i]``."""
    n = target.shape[0]
    return sp.csr_matrix((np.ones(n), (target, np.arange(n))), shape=(n_target, n))


def casadi_sparsity(m: sp.spmatrix) -> Any:
    """The CasADi ``Sparsity`` of a SciPy sparse matrix (column-compressed, sorted)."""
    import casadi as ca

    c = sp.csc_matrix(m)
    c.sort_indices()
    return ca.Sparsity(c.shape[0], c.shape[1], c.indptr.tolist(), c.indices.tolist())


def casadi_dm(m: sp.spmatrix) -> Any:
    """A SciPy sparse matrix as a sparse CasADi ``DM`` (same nonzeros, same order)."""
    import casadi as ca

    c = sp.csc_matrix(m)
    c.sort_indices()
    return ca.DM(casadi_sparsity(c), c.data)


class BlockNLP:
    """``min f(x)  s.t.  lbg ≤ g(x) ≤ ubg, lbx ≤ x ≤ ubx`` made of `Block` s.

    Parameters
    ----------
    n_x : int
        Number of global variables.
    blocks : sequence of Block
        The block types.
    """

    def __init__(self, n_x: int, blocks: Sequence[Block]) -> None:
        import casadi as ca

        self.n_x = int(n_x)
        self.blocks = list(blocks)
        for b in self.blocks:
            idx = np.asarray(b.index)
            if idx.ndim != 2 or idx.min(initial=0) < 0 or idx.max(initial=0) >= self.n_x:
                raise ValueError("a block's index must be (n_blocks, V) within the variables")
            if any(len(set(r)) != len(r) for r in idx.tolist()):
                raise ValueError("a block reads one global variable twice")
        self.n_g = sum(b.n_blocks * b.n_rows for b in self.blocks)
        x = ca.MX.sym("x", self.n_x)
        p = ca.MX.sym("p", 0)
        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", self.n_g)
        f = ca.MX(0)
        g_parts = []
        grad_nz, grad_pos = [], []
        jac_nz, jac_r, jac_c = [], [], []
        hess_nz, hess_r, hess_c = [], [], []
        off = 0
        for b in self.blocks:
            idx = np.asarray(b.index, dtype=np.int64)
            nb, nv = idx.shape
            nr = b.n_rows
            v_sx = ca.SX.sym("v", nv)
            p_sx = ca.SX.sym("p", b.params.shape[1])
            rows = b.rows(v_sx, p_sx) if nr else ca.SX(0, 1)
            cost = b.cost(v_sx, p_sx) if b.cost is not None else ca.SX(0)
            v = ca.reshape(x[idx.ravel().tolist()], nv, nb)
            par = ca.DM(np.asarray(b.params, dtype=float).T)
            lam_sx = ca.SX.sym("lam", nr)
            sig_sx = ca.SX.sym("sigma")
            jac = ca.jacobian(rows, v_sx)
            grad = ca.gradient(cost, v_sx)
            hess = ca.triu(ca.hessian(sig_sx * cost + ca.dot(lam_sx, rows), v_sx)[0])

            # one function per use: an MX call evaluates all of a function's outputs
            def mapped(name: str, ins: list[Any], outs: list[Any], *args: Any) -> Any:
                return ca.Function(name, ins, outs).map(nb)(*args)  # noqa: B023

            lam_b = ca.reshape(lam_g[off : off + nb * nr], nr, nb) if nr else ca.MX(0, nb)
            out = [
                mapped("block_rows", [v_sx, p_sx], [rows], v, par),
                mapped("block_cost", [v_sx, p_sx], [cost], v, par),
                mapped("block_grad", [v_sx, p_sx], [grad], v, par),
                mapped("block_jac", [v_sx, p_sx], [jac], v, par),
                mapped("block_hess", [v_sx, p_sx, lam_sx, sig_sx], [hess], v, par, lam_b,
                       ca.repmat(lam_f, 1, nb)),
            ]  # fmt: skip
            if nr:
                g_parts.append(ca.vec(out[0]))
            f = f + ca.sum2(out[1])
            # gradient: dense (V,) per block
            grad_nz.append(ca.vec(out[2]))
            grad_pos.append(idx.ravel())
            # Jacobian: the block's nonzeros in CCS order, block after block
            jsp = jac.sparsity()
            jr, jc = (np.asarray(a, dtype=np.int64) for a in jsp.get_triplet())
            if jr.size:
                jac_nz.append(out[3].nz[:])
                ks = np.arange(nb)[:, None]
                jac_r.append((off + ks * nr + jr[None, :]).ravel())
                jac_c.append(idx[:, jc].ravel())
            hsp = hess.sparsity()
            hr, hc = (np.asarray(a, dtype=np.int64) for a in hsp.get_triplet())
            if hr.size:
                hess_nz.append(out[4].nz[:])
                gr, gc = idx[:, hr], idx[:, hc]
                hess_r.append(np.minimum(gr, gc).ravel())
                hess_c.append(np.maximum(gr, gc).ravel())
            off += nb * nr
        g = ca.vertcat(*g_parts) if g_parts else ca.MX(0, 1)
        self._f = f
        self._g = g
        # gradient
        pos = np.concatenate(grad_pos)
        grad = ca.mtimes(casadi_dm(_assembly(pos, self.n_x)), ca.vertcat(*grad_nz))
        # Jacobian
        jr_all, jc_all = np.concatenate(jac_r), np.concatenate(jac_c)
        jsp_g = ca.Sparsity.triplet(self.n_g, self.n_x, jr_all.tolist(), jc_all.tolist())
        jpos = _nz_positions(jsp_g, jr_all, jc_all)
        jac_vals = ca.mtimes(casadi_dm(_assembly(jpos, jsp_g.nnz())), ca.vertcat(*jac_nz))
        jac_g = ca.MX(jsp_g, jac_vals)
        # Hessian (upper triangle)
        hr_all, hc_all = np.concatenate(hess_r), np.concatenate(hess_c)
        hsp_g = ca.Sparsity.triplet(self.n_x, self.n_x, hr_all.tolist(), hc_all.tolist())
        hpos = _nz_positions(hsp_g, hr_all, hc_all)
        hess_vals = ca.mtimes(casadi_dm(_assembly(hpos, hsp_g.nnz())), ca.vertcat(*hess_nz))
        hess_g = ca.MX(hsp_g, hess_vals)
        self.grad_f = ca.Function("grad_f", [x, p], [f, grad], ["x", "p"], ["f", "grad_f_x"])
        self.jac_g = ca.Function("jac_g", [x, p], [g, jac_g], ["x", "p"], ["g", "jac_g_x"])
        self.hess_lag = ca.Function(
            "hess_lag", [x, p, lam_f, lam_g], [hess_g],
            ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"],
        )  # fmt: skip
        self._x = x

    def solver(self, options: dict[str, Any] | None = None) -> Any:
        """The IPOPT ``nlpsol`` with the assembled derivatives."""
        import casadi as ca

        opts = dict(options or {})
        opts.update(grad_f=self.grad_f, jac_g=self.jac_g, hess_lag=self.hess_lag)
        return ca.nlpsol("blocknlp", "ipopt", {"x": self._x, "f": self._f, "g": self._g}, opts)


def _nz_positions(sparsity: Any, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The nonzero index of each (row, col) in a CCS ``sparsity`` (vectorised)."""
    colind = np.asarray(sparsity.colind(), dtype=np.int64)
    row = np.asarray(sparsity.row(), dtype=np.int64)
    nr = sparsity.size1()
    # every nonzero's key col * nrow + row is sorted in CCS order
    nz_cols = np.repeat(np.arange(colind.size - 1), np.diff(colind))
    nz_keys = nz_cols * nr + row
    return np.searchsorted(nz_keys, cols * nr + rows)
