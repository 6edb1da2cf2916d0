"""The convex subproblem of stage 2 (`microfab.optimize.stage2`) as a sparse QP.

Variables, all in µm: the step ``δ`` (2M: x then y), the linearised residuals
``e = φ + J δ - Ξ̄`` (2M), the tolerance slacks ``s`` (M, or 2M per axis), the slacks of
the output's speed and acceleration rows (2M each). Objective ``Σ e² + w Σ s + W (Σ σ)``:
the Hessian is diagonal; ``J`` appears only in the equality rows ``e - J δ = φ - Ξ̄``.
Rows:

* tolerance, Euclidean: ``u_kᵀ e_i - s_i ≤ μ cos(π/8)`` for the 8 directions ``u_k`` at
  ``kπ/4`` (the octagon inscribed in the circle of radius ``μ + s_i``, so a step that
  meets it meets the circle); per axis: ``±e - s ≤ μ``;
* the output's speed and acceleration (14e, 14f) from rest: ``±Δ(e + Ξ̄) - σ ≤ v Δt``,
  ``±Δ²(e + Ξ̄) - σ ≤ a Δt²`` (``φ_0 = φ_{-1} = rest``);
* the command (hard): ``|Δ(r + δ)| ≤ dv``, ``|Δ²(r + δ)| ≤ d2`` over
  ``[rest, rest, r, r_{M-1}, r_{M-1}]`` (`microfab.optimize.command.input_bounds`);
* bounds: ``|δ| ≤`` the trust radius, ``e`` within the workspace, slacks ≥ 0.

The matrix keeps one sparsity pattern over the iterations (the Jacobian's band is fixed),
so the solver is built once and only the matrix's values change. The solver
(`Stage2Settings.qp`): PIQP (default; a sparse interior-point QP solver that CasADi ships as
a ``conic`` plugin, so no other package), or IPOPT on the QP as an NLP with constant
derivatives (the solver up to issue 34). Both solve the same QP to about 1e-4 µm in the
step; on the 20-epoch twin networks at M = 918 (band 37, 20 202 rows, 125 332 nonzeros)
PIQP took 0.25 s per QP against IPOPT's 2.6-3.0 s (`benchmarks/bench_optimize.py` prints
both). OSQP (also a CasADi plugin) met the tolerance rows only to 1e-2 µm at ``eps`` 1e-3
and took longer than PIQP at 1e-5; HiGHS's QP solver failed on these problems.
`Subproblem.project` is the nearest input within the command's bounds (a QP without the
networks), used to start.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse as sp

from microfab.core.interrupt import interruptible
from microfab.optimize.blocks import casadi_dm, casadi_sparsity

__all__ = ["Subproblem"]

_OCT = 8


def _out_diffs(m: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """First and second differences of ``[rest, rest, x_1 … x_m]``: (m, m) each.

    The rest parts are added separately.
    """
    d1 = sp.diags([1.0, -1.0], [0, -1], shape=(m, m), format="csr")
    d2 = sp.diags([1.0, -2.0, 1.0], [0, -1, -2], shape=(m, m), format="csr")
    return d1, d2


def _ipopt_qp(a: sp.csc_matrix, h_diag: np.ndarray, g: np.ndarray) -> Any:
    """IPOPT on ``min ½ xᵀ diag(h) x + gᵀ x  s.t.  lbg ≤ A x ≤ ubg``.

    A's nonzeros are a parameter: one build for every iteration; the Hessian and the
    Jacobian are constant within a solve.
    """
    import casadi as ca

    x = ca.MX.sym("x", a.shape[1])
    p = ca.MX.sym("p", a.nnz)
    f = 0.5 * ca.dot(ca.DM(h_diag), x * x) + ca.dot(ca.DM(g), x)
    cons = ca.densify(ca.mtimes(ca.MX(casadi_sparsity(a), p), x))
    opts = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.hessian_constant": "yes",
        "ipopt.jac_c_constant": "yes",
        "ipopt.jac_d_constant": "yes",
        "ipopt.mehrotra_algorithm": "yes",  # convex QP: IPOPT's predictor-corrector
        "ipopt.tol": 1e-7,
        "ipopt.max_iter": 500,
    }
    return ca.nlpsol("stage2_qp", "ipopt", {"x": x, "p": p, "f": f, "g": cons}, opts)


def _piqp_qp(a: sp.csc_matrix, h_diag: np.ndarray) -> Any:
    """PIQP (CasADi ``conic``) on ``min ½ xᵀ diag(h) x + gᵀ x  s.t.  lba ≤ A x ≤ uba``.

    Built once for A's sparsity pattern; each solve passes A's values.
    """
    import casadi as ca

    hs = sp.diags(h_diag, format="csc")
    return ca.conic("stage2_qp", "piqp",
                    {"h": casadi_sparsity(hs), "a": casadi_sparsity(a)},
                    {"error_on_fail": False, "piqp": {"verbose": False}})  # fmt: skip


class Subproblem:
    """The QP of one Gauss-Newton step, built once per problem (module docstring)."""

    def __init__(self, pb: Any, st: Any, cmd_ops: tuple[sp.csr_matrix, sp.csr_matrix],
                 rest_terms: list[tuple[np.ndarray, np.ndarray]]) -> None:  # fmt: skip
        import casadi as ca

        self.pb, self.st = pb, st
        m = pb.m
        self.m = m
        self.c1, self.c2 = cmd_ops
        self.rest_terms = rest_terms
        n_s = m if st.norm == "euclidean" else 2 * m
        self.sizes = {"d": 2 * m, "e": 2 * m, "s": n_s, "sv": 2 * m, "sa": 2 * m}
        off = np.cumsum([0, *self.sizes.values()])
        self.sl = {k: slice(int(off[i]), int(off[i + 1])) for i, k in enumerate(self.sizes)}
        self.n = int(off[-1])
        eye = sp.eye(m, format="csr")
        z = lambda r, c: sp.csr_matrix((r, c))  # noqa: E731
        # tolerance rows
        if st.norm == "euclidean":
            ang = np.arange(_OCT) * (2 * math.pi / _OCT)
            tol_e = sp.vstack([sp.hstack([math.cos(a) * eye, math.sin(a) * eye]) for a in ang])
            tol_s = sp.vstack([-eye] * _OCT)
            self.tol_ub = np.full(_OCT * m, pb.mu * math.cos(math.pi / _OCT))
        else:
            e2 = sp.eye(2 * m, format="csr")
            tol_e = sp.vstack([e2, -e2])
            tol_s = sp.vstack([-e2, -e2])
            self.tol_ub = np.full(4 * m, pb.mu)
        d1, d2 = _out_diffs(m)
        self.o1 = sp.block_diag([d1, d1], format="csr")
        self.o2 = sp.block_diag([d2, d2], format="csr")
        e2m = sp.eye(2 * m, format="csr")
        rows = {
            "tol": (tol_e, tol_s),
            "vel": sp.vstack([self.o1, -self.o1]),
            "acc": sp.vstack([self.o2, -self.o2]),
        }
        c1 = sp.block_diag([self.c1, self.c1], format="csr")
        c2 = sp.block_diag([self.c2, self.c2], format="csr")
        self.cmd1, self.cmd2 = c1, c2
        n_d, n_e, n_s_, n_v, n_a = self.sizes.values()
        blocks = [
            # equality: -J δ + e = φ - Ξ̄ (J's values filled per iteration)
            [None, e2m, z(2 * m, n_s_), z(2 * m, n_v), z(2 * m, n_a)],
            [z(tol_e.shape[0], n_d), tol_e, tol_s, z(tol_e.shape[0], n_v), z(tol_e.shape[0], n_a)],
            [z(4 * m, n_d), rows["vel"], z(4 * m, n_s_), sp.vstack([-e2m, -e2m]), z(4 * m, n_a)],
            [z(4 * m, n_d), rows["acc"], z(4 * m, n_s_), z(4 * m, n_v), sp.vstack([-e2m, -e2m])],
            [c1, z(c1.shape[0], n_e + n_s_ + n_v + n_a), None, None, None],
            [c2, z(c2.shape[0], n_e + n_s_ + n_v + n_a), None, None, None],
        ]
        self._blocks = blocks
        self._pattern: Any = None
        self._sparsity: Any = None
        self._solver: Any = None
        self._ca = ca
        h = np.zeros(self.n)
        h[self.sl["e"]] = 2.0
        h[self.sl["d"]] = 2e-6  # assumed: a tiny step penalty so the QP is strictly convex
        self.h_diag = h
        self.model_merit = math.nan

    # ------------------------------------------------------------------ assembly
    def _matrix(self, jac: sp.csr_matrix) -> sp.csc_matrix:
        b = [row[:] for row in self._blocks]
        b[0][0] = -jac
        rows = []
        for row in b:
            if row[2] is None:  # command rows: [c, zeros]
                rows.append(sp.hstack([row[0], row[1]], format="csr"))
            else:
                rows.append(sp.hstack(row, format="csr"))
        a = sp.vstack(rows, format="csc")
        a.sort_indices()
        return a

    def _cmd_bounds(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        pb = self.pb
        k1 = np.concatenate([t[0] for t in self.rest_terms])
        k2 = np.concatenate([t[1] for t in self.rest_terms])
        v1 = self.cmd1 @ r + k1
        v2 = self.cmd2 @ r + k2
        dv = np.repeat(pb.dv, self.c1.shape[0])
        d2 = np.repeat(pb.d2, self.c2.shape[0])
        return -dv - v1, dv - v1, -d2 - v2, d2 - v2

    def project(self, r0: np.ndarray) -> np.ndarray:
        """The input nearest to ``r0`` (2M, µm) within the command's bounds.

        Solved by PIQP, or by HiGHS with ``qp="ipopt"`` (the solvers before issue 34).
        """
        ca = self._ca
        a = sp.vstack([self.cmd1, self.cmd2], format="csc")
        h = sp.eye(r0.size, format="csc") * 2.0
        lo1, hi1, lo2, hi2 = self._cmd_bounds(r0)
        if np.all(lo1 <= 0) and np.all(hi1 >= 0) and np.all(lo2 <= 0) and np.all(hi2 >= 0):
            return r0.copy()
        # PIQP: 6 ms against HiGHS's 1.9 s at M = 918, the same input to 1e-10 µm
        pattern = {"h": casadi_sparsity(h), "a": casadi_sparsity(a)}
        args = {"h": casadi_dm(h), "g": np.zeros(r0.size), "a": casadi_dm(a),
                "lba": np.concatenate([lo1, lo2]), "uba": np.concatenate([hi1, hi2])}  # fmt: skip
        highs = {"highs": {"output_flag": False}, "error_on_fail": False}
        # a Ctrl-C inside a solver is a KeyboardInterrupt, not a failed solve
        if getattr(self.st, "qp", "piqp") == "ipopt":
            sol = interruptible(ca.conic("project", "highs", pattern, highs), **args)
        else:
            solver = ca.conic("project", "piqp", pattern,
                              {"piqp": {"verbose": False}, "error_on_fail": False})  # fmt: skip
            sol = interruptible(solver, **args)
            if not solver.stats().get("success", False):  # HiGHS, as before
                sol = interruptible(ca.conic("project", "highs", pattern, highs), **args)
        return r0 + np.asarray(sol["x"]).ravel()

    def _cost_vector(self) -> np.ndarray:
        g = np.zeros(self.n)
        g[self.sl["s"]] = self.st.penalty
        g[self.sl["sv"]] = self.st.limit_penalty
        g[self.sl["sa"]] = self.st.limit_penalty
        return g

    def solve(self, r: np.ndarray, phi: np.ndarray, jac: sp.csr_matrix,
              trust: float) -> np.ndarray | None:  # fmt: skip
        """The step ``δ`` (2M, µm), or None when the QP fails; sets `model_merit`.

        Ctrl-C during the solve raises KeyboardInterrupt (`microfab.core.interrupt`).
        """
        pb, st, m = self.pb, self.st, self.m
        a = self._matrix(jac)
        solver = getattr(st, "qp", "piqp")
        if self._solver is None:
            self._pattern = a
            self._sparsity = casadi_sparsity(a)
            if solver == "ipopt":
                self._solver = _ipopt_qp(a, self.h_diag, self._cost_vector())
            else:
                self._solver = _piqp_qp(a, self.h_diag)
                self._h = casadi_dm(sp.diags(self.h_diag, format="csc"))
        elif a.nnz != self._pattern.nnz or not (
            np.array_equal(a.indptr, self._pattern.indptr)
            and np.array_equal(a.indices, self._pattern.indices)
        ):
            raise RuntimeError("the Jacobian's sparsity changed between iterations")
        tgt = pb.tgt
        res = phi.ravel() - tgt
        rest = np.repeat(pb.rest, m)
        first = np.zeros(2 * m)
        first[0], first[m] = 1.0, 1.0  # Δφ_1 = φ_1 - rest
        second = np.zeros(2 * m)
        second[[0, m]], second[[1, m + 1]] = 1.0, -1.0  # φ_1 - 2 rest + rest; φ_2 - 2 φ_1 + rest
        t1 = self.o1 @ tgt - first * rest
        t2 = self.o2 @ tgt - second * rest
        lo1, hi1, lo2, hi2 = self._cmd_bounds(r)
        inf = np.inf
        lba = np.concatenate([res, np.full(self.tol_ub.size, -inf), np.full(8 * m, -inf),
                              lo1, lo2])  # fmt: skip
        uba = np.concatenate([res, self.tol_ub, pb.v_step - t1, pb.v_step + t1,
                              pb.a_step - t2, pb.a_step + t2, hi1, hi2])  # fmt: skip
        lbx = np.zeros(self.n)
        ubx = np.full(self.n, inf)
        lbx[self.sl["d"]], ubx[self.sl["d"]] = -trust, trust
        lbx[self.sl["e"]] = np.repeat(pb.ws[:, 0], m) - tgt
        ubx[self.sl["e"]] = np.repeat(pb.ws[:, 1], m) - tgt
        x0 = np.zeros(self.n)
        x0[self.sl["e"]] = res
        # a Ctrl-C inside the solver is a KeyboardInterrupt, never a failed QP (which ends
        # stage 2 as if it had stopped by itself)
        if solver == "ipopt":
            sol = interruptible(self._solver, p=a.data, lbg=lba, ubg=uba, lbx=lbx, ubx=ubx,
                                x0=x0)  # fmt: skip
        else:
            a_dm = self._ca.DM(self._sparsity, a.data)
            sol = interruptible(self._solver, h=self._h, g=self._cost_vector(), a=a_dm,
                                lba=lba, uba=uba, lbx=lbx, ubx=ubx, x0=x0)  # fmt: skip
        if not self._solver.stats().get("success", False):
            return None
        x = np.asarray(sol["x"]).ravel()
        e = x[self.sl["e"]]
        pen = (st.penalty * x[self.sl["s"]].sum()
               + st.limit_penalty * (x[self.sl["sv"]].sum() + x[self.sl["sa"]].sum()))  # fmt: skip
        self.model_merit = float(np.sum(e**2) + pen)
        return x[self.sl["d"]]
