"""A HiGHS linear program kept between solves, for sequences of closely related LPs.

The planner of :mod:`microfab.trajectory.optimal` solves the same LP several times with
a few bounds changed (a verification round shrinks the limits where the spline
overshoots). :func:`scipy.optimize.linprog` builds and solves every one from scratch.
`HighsSession` instead keeps one HiGHS model:

* when a call brings the **same constraint matrix** (the same object) as the previous
  one, only the changed column bounds, row bounds and costs are passed and HiGHS
  continues from its last optimal basis (a *hot start*: usually a few simplex
  iterations);
* a new model may come with a **starting point** ``x0``; when it is the optimal vertex,
  HiGHS builds the optimal basis from it and certifies it without iterating (a guess that
  is not optimal only costs the time to discard it);
* a constraint matrix whose second half of rows is the negative of its first half
  (``-u <= A x <= u`` written as ``A_ub = [A; -A]``) is passed as ranged rows, half as
  many.

The answer is HiGHS's optimal vertex in every case. HiGHS is reached through the bindings
SciPy ships (``scipy.optimize._highspy``, SciPy >= 1.15) or the ``highspy`` package;
without either, `HighsSession.available` is false and the caller uses ``linprog``.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from scipy import sparse

from microfab.core.interrupt import interruptible

__all__ = ["HighsSession"]


@functools.cache
def _api() -> Any:
    """The module holding HiGHS's bindings (``_Highs``/``Highs``, ``HighsLp``, ...), or None."""
    try:
        from scipy.optimize._highspy import _core

        _core._Highs  # noqa: B018 - probe the class this module drives
        return _core
    except (ImportError, AttributeError):
        pass
    try:
        import highspy
    except ImportError:
        return None
    return highspy


def _paired(A: sparse.csr_matrix) -> bool:
    """Whether the rows are ``[B; -B]`` (each constraint given with both signs)."""
    m = A.shape[0]
    if m % 2:
        return False
    top, bottom = A[: m // 2], A[m // 2 :]
    return bool(top.shape == bottom.shape and (top + bottom).count_nonzero() == 0)


class HighsSession:
    """One HiGHS LP, solved again and again with changed bounds (see the module notes).

    Solves ``min c @ x`` subject to ``A_ub @ x <= b_ub`` and ``bounds[:, 0] <= x <=
    bounds[:, 1]``. Not thread-safe: use one session per thread.

    Parameters
    ----------
    time_limit : float, optional
        Wall-time limit per solve, s.
    """

    def __init__(self, time_limit: float | None = None) -> None:
        self.time_limit = time_limit
        self.broken = False  # set when the bindings misbehave: use linprog from then on
        self._highs: Any = None
        self._A: sparse.csr_matrix | None = None
        self._half = 0  # rows per sign when the rows are paired, else 0
        self._c = np.zeros(0)
        self._b = np.zeros(0)
        self._bounds = np.zeros((0, 2))

    def __getstate__(self) -> dict[str, Any]:
        """Pickle the settings only (the HiGHS model is rebuilt on the next solve)."""
        return {"time_limit": self.time_limit}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["time_limit"])  # type: ignore[misc]

    def holds(self, A_ub: sparse.csr_matrix) -> bool:
        """Whether ``A_ub`` is the constraint matrix of the model kept (the same object)."""
        return self._highs is not None and A_ub is self._A

    @property
    def available(self) -> bool:
        """Whether HiGHS's own bindings can be used (else use ``linprog``)."""
        return not self.broken and _api() is not None

    def solve(
        self,
        c: np.ndarray,
        A_ub: sparse.csr_matrix,
        b_ub: np.ndarray,
        bounds: np.ndarray,
        x0: np.ndarray | None = None,
    ) -> tuple[np.ndarray | None, str]:
        """Solve; ``(x, "")`` at the optimum, else ``(None, HiGHS's model status)``.

        Parameters
        ----------
        c : numpy.ndarray
            Costs, shape (n,).
        A_ub : scipy.sparse.csr_matrix
            Constraint matrix, shape (m, n); pass the same object again to hot-start.
        b_ub : numpy.ndarray
            Upper bounds of the rows, shape (m,).
        bounds : numpy.ndarray
            Lower and upper bound per variable, shape (n, 2).
        x0 : numpy.ndarray, optional
            A guess of the solution, used when the model is new.
        """
        api = _api()
        c = np.ascontiguousarray(c, dtype=float)
        b = np.ascontiguousarray(b_ub, dtype=float)
        bd = np.ascontiguousarray(bounds, dtype=float)
        if self.holds(A_ub):
            self._update(c, b, bd)
            status = self._run(api)
            if status != api.HighsModelStatus.kOptimal:  # start again without the basis
                self._highs.clearSolver()
                status = self._run(api)
        else:
            self._new_model(api, c, A_ub, b, bd)
            if x0 is not None and np.all(np.isfinite(x0)) and x0.shape == c.shape:
                sol = api.HighsSolution()
                sol.col_value = np.asarray(x0, dtype=float).tolist()
                sol.value_valid = True
                self._highs.setSolution(sol)
            status = self._run(api)
        self._c, self._b, self._bounds = c, b, bd
        if status != api.HighsModelStatus.kOptimal:
            self._A = None  # do not continue from a failed model
            return None, str(self._highs.modelStatusToString(status))
        x = np.array(self._highs.getSolution().col_value, dtype=float)
        if x.shape != c.shape or not np.all(np.isfinite(x)):
            self._A = None
            return None, "no finite solution"
        return x, ""

    # ----------------------------------------------------------------- internals
    def _run(self, api: Any) -> Any:
        # Ctrl-C: a KeyboardInterrupt, never an "interrupted" model status (highspy's own
        # ``run`` may catch it and return one; SciPy's bindings do not check for signals)
        interruptible(self._highs.run)
        return self._highs.getModelStatus()

    def _new_model(
        self, api: Any, c: np.ndarray, A_ub: sparse.csr_matrix, b: np.ndarray, bd: np.ndarray
    ) -> None:
        A = sparse.csr_matrix(A_ub)
        self._half = A.shape[0] // 2 if _paired(A) else 0
        rows = A[: self._half] if self._half else A
        lo, hi = self._row_bounds(b)
        Ac = sparse.csc_matrix(rows)
        Ac.sort_indices()
        lp = api.HighsLp()
        lp.num_col_, lp.num_row_ = Ac.shape[1], Ac.shape[0]
        lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = Ac.shape[1], Ac.shape[0]
        lp.a_matrix_.format_ = api.MatrixFormat.kColwise
        lp.a_matrix_.start_ = Ac.indptr
        lp.a_matrix_.index_ = Ac.indices
        lp.a_matrix_.value_ = Ac.data
        lp.col_cost_ = c
        lp.col_lower_ = bd[:, 0]
        lp.col_upper_ = bd[:, 1]
        lp.row_lower_ = lo
        lp.row_upper_ = hi
        h = getattr(api, "_Highs", None) or api.Highs
        self._highs = h()
        self._highs.setOptionValue("output_flag", False)
        if self.time_limit is not None:
            self._highs.setOptionValue("time_limit", float(self.time_limit))
        self._highs.passModel(lp)
        self._A = A_ub  # the caller's object: the next call is compared by identity

    def _row_bounds(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self._half:
            return -b[self._half :], b[: self._half]
        return np.full(b.size, -np.inf), b

    def _update(self, c: np.ndarray, b: np.ndarray, bd: np.ndarray) -> None:
        h = self._highs
        cols = np.flatnonzero(np.any(bd != self._bounds, axis=1))
        if cols.size:
            h.changeColsBounds(cols.size, cols.astype(np.int32), bd[cols, 0], bd[cols, 1])
        if self._half:
            changed = (b[: self._half] != self._b[: self._half]) | (
                b[self._half :] != self._b[self._half :]
            )
        else:
            changed = b != self._b
        lo, hi = self._row_bounds(b)
        for r in np.flatnonzero(changed).tolist():
            h.changeRowBounds(r, float(lo[r]), float(hi[r]))
        costs = np.flatnonzero(c != self._c)
        if costs.size:
            h.changeColsCost(costs.size, costs.astype(np.int32), c[costs])
