"""The Lagrangian jet on its current grid for one implicit step, as the integrator sees it.

:func:`.jet.run_jet` hands each time step to an integrator object
(:class:`microfab.sim.integrators.SDIRK2` by default) as a
`microfab.sim.integrators.ImplicitProblem`; this module supplies what is specific to the
jet: the right-hand side and the banded Jacobian from :mod:`.jet_kernels`, the Newton
matrix factored by LAPACK ``gbtrf``/``gbtrs``, the boundary values held as algebraic
constraints and the error norm that judges cell lengths relatively. It is apart from the
driver, which regrids, injects, splits and coalesces between the steps; the model is
described in :mod:`.jet`. Nothing here is public: `.jet.run_jet` is the way in.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.linalg import lapack

from microfab.process.inkjet import jet_kernels as jk
from microfab.process.inkjet.jet_bodies import Inflow, JetModel, Numerics, _State

__all__: list[str] = []


class _JetSystem:
    """Fluid parameters of the kernels, fixed for a run; hands out per-step problems."""

    def __init__(self, model: JetModel, numerics: Numerics, a_nozzle: float) -> None:
        self.nu = numerics
        self.a_nozzle = a_nozzle
        self.args = (
            a_nozzle,
            model.ohnesorge,
            model.polymer_modulus,
            1.0 / model.deborah if model.deborah > 0 else 0.0,
            0.0 if math.isinf(model.extensibility_l2) else 1.0 / model.extensibility_l2,
        )

    def at_step(
        self,
        st: _State,
        t: float,
        inflow: Inflow | None,
        w0_ref: float,
        u_ref: float,
        piston: bool,
    ) -> _JetStep:
        """The jet on its current grid, as an `ImplicitProblem` for one step from ``t``."""
        return _JetStep(self, st, t, inflow, w0_ref, u_ref, piston)


class _JetStep:
    """One step of the jet on a fixed grid, seen by the integrator (`ImplicitProblem`).

    The state ``y`` has shape (nodes, 4): position, velocity, and the conformation
    ``a_zz``, ``a_rr`` of the cell to the right of each node. The nozzle cell's volume
    follows the inflow over the step (unless the meniscus retracts as a piston), the end
    nodes of walls and the nozzle are algebraic constraints, and the Newton matrix is
    the banded ``I - gh J`` factored by LAPACK.
    """

    def __init__(
        self,
        system: _JetSystem,
        st: _State,
        t0: float,
        inflow: Inflow | None,
        w0_ref: float,
        u_ref: float,
        piston: bool,
    ) -> None:
        self.sys = system
        self.st = st
        self.t0 = t0
        self.inflow = inflow
        self.w0_ref = w0_ref
        self.u_ref = u_ref
        self.piston = piston
        self.alg_idx, self._alg_val = _algebraic(st, inflow, u_ref, piston)
        self._lu: np.ndarray | None = None
        self._piv: np.ndarray | None = None
        self._stage_t = math.nan
        self._stage_w = st.w
        self._stage_targets = np.zeros(0)

    def _w(self, t: float) -> np.ndarray:
        """Cell volumes at ``t``: the state's own at the start of the step."""
        if self.piston or t == self.t0:
            return self.st.w
        return _w_at(self.st, t, self.inflow, self.w0_ref, self.u_ref, self.sys.a_nozzle)

    def _stage(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if t != self._stage_t:
            self._stage_t = t
            self._stage_w = self._w(t)
            self._stage_targets = self._alg_val(t)
        return self._stage_w, self._stage_targets

    def _f(self, y: np.ndarray, w: np.ndarray, out: np.ndarray) -> bool:
        st = self.st
        return bool(jk.rhs(y, w, st.starts, st.bcl, st.bcr, *self.sys.args, out))

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray | None:
        out = np.empty_like(y)
        return out if self._f(y, self._w(t), out) else None

    def factor(self, t: float, y: np.ndarray, f: np.ndarray, gh: float) -> bool:
        st = self.st
        kl = jk.KL
        ab = np.empty((3 * kl + 1, y.size))
        jk.jacobian_banded(y, self._w(t), st.starts, st.bcl, st.bcr, *self.sys.args, f, ab)
        ab *= -gh
        ab[2 * kl, :] += 1.0
        lu, piv, info = lapack.dgbtrf(ab, kl, kl, overwrite_ab=1)
        if info != 0:
            return False
        self._lu, self._piv = lu, piv
        return True

    def residual(self, t: float, y: np.ndarray, base: np.ndarray, gh: float) -> np.ndarray | None:
        w, targets = self._stage(t)
        fy = np.empty_like(y)
        if not self._f(y, w, fy):
            return None
        res = y - base - gh * fy
        res_flat = res.ravel()
        res_flat[self.alg_idx] = y.ravel()[self.alg_idx] - targets
        return res

    def solve(self, r: np.ndarray) -> np.ndarray | None:
        kl = jk.KL
        delta, info = lapack.dgbtrs(self._lu, kl, kl, r.ravel(), self._piv)
        if info != 0:
            return None
        return delta.reshape(r.shape)

    def filter_error(self, est: np.ndarray) -> np.ndarray:
        kl = jk.KL
        est_flat = est.ravel()
        est_flat[self.alg_idx] = 0.0
        err, _ = lapack.dgbtrs(self._lu, kl, kl, est_flat, self._piv)
        return err.reshape(est.shape)

    def norm(self, e: np.ndarray, y: np.ndarray) -> float:
        nu = self.sys.nu
        return float(jk.error_norm(e, y, self.st.starts, nu.rtol, nu.atol))

    def admissible(self, y: np.ndarray) -> bool:
        return not np.any(np.diff(y[:, 0])[_inner_cells(self.st)] <= 0.0)


def _inner_cells(st: _State) -> np.ndarray:
    mask = np.ones(st.y.shape[0] - 1, dtype=bool)
    mask[st.starts[1:-1] - 1] = False
    return mask


def _w_at(
    st: _State,
    t: float,
    inflow: Inflow | None,
    w0_ref: float,
    u_ref: float,
    a_nozzle: float,
) -> np.ndarray:
    if inflow is None or st.bcl.size == 0 or st.bcl[0] != jk.BC_NOZZLE:
        return st.w
    w = st.w.copy()
    w[0] = w0_ref + a_nozzle * (inflow.displacement(t) - u_ref)
    return w


def _algebraic(
    st: _State, inflow: Inflow | None, u_ref: float, piston: bool
) -> tuple[np.ndarray, Callable[[float], np.ndarray]]:
    idx: list[int] = []
    const: list[float] = []
    nozzle_pos = -1
    for b in range(st.starts.size - 1):
        k0, k1 = int(st.starts[b]), int(st.starts[b + 1])
        if st.bcl[b] != jk.BC_TIP:
            idx += [4 * k0, 4 * k0 + 1]
            const += [st.y[k0, 0], 0.0]
            if st.bcl[b] == jk.BC_NOZZLE:
                nozzle_pos = len(idx) - 2
        if st.bcr[b] != jk.BC_TIP:
            idx += [4 * (k1 - 1), 4 * (k1 - 1) + 1]
            const += [st.y[k1 - 1, 0], 0.0]
    base = np.array(const)

    def values(ts: float) -> np.ndarray:
        if nozzle_pos < 0 or inflow is None:
            return base
        out = base.copy()
        out[nozzle_pos + 1] = inflow.velocity(ts)
        if piston:
            out[nozzle_pos] = base[nozzle_pos] + inflow.displacement(ts) - u_ref
        return out

    return np.array(idx, dtype=np.int64), values
