"""Implicit Runge-Kutta time integrators, as objects a solver is handed.

A stiff solver (the slender-jet model of :mod:`microfab.process.inkjet.jet`, for one)
keeps its own state, grid and linear algebra, and asks an integrator for one step at a
time: ``integrator.step(problem, t, y, h)`` returns the new state (or a failure) and a
scaled error, and ``step_after_acceptance`` / ``step_after_rejection`` give the next step
size. The scheme (stages, embedded error estimate, Newton iteration, step-size control)
lives here; what is specific to the problem (its right-hand side, how it forms and
factors the Newton matrix ``I - γ h J``, algebraic constraints, its error norm) is
supplied through the `ImplicitProblem` protocol. `DenseProblem` implements it for small
dense systems ``y' = f(t, y)`` with a Jacobian.

Method
------
`SDIRK2` is the two-stage, stiffly accurate, L-stable singly diagonally implicit
Runge-Kutta method of Alexander (1977) with ``γ = 1 - 1/√2``::

    γ   | γ      0
    1   | 1 - γ  γ
    ----+-----------
        | 1 - γ  γ        (order 2, stiffly accurate: y_{n+1} = second stage)
        | 1/2    1/2      (embedded, order 1)

Each stage ``Y_i = base_i + γ h f(t + c_i h, Y_i)`` is solved by a simplified Newton
iteration with the matrix ``I - γ h J(t_n, y_n)`` factored once per step. The local error
estimate ``h (1/2 - γ) (k_1 - k_2)`` (``k_i`` the stage derivatives) is filtered through
the same matrix, ``(I - γ h J)^{-1} est``, which keeps it bounded for stiff components
(Hairer & Wanner, Solving ODEs II, §IV.8). The step size follows the first-order
estimate: ``h_new = h · clip(0.9 / √err, 0.2, 3)`` after an accepted step (``err <= 1``),
``h · max(0.2, 0.9 / √err)`` after a rejected one and ``h / 4`` after a Newton failure.

References
----------
R. Alexander, "Diagonally implicit Runge-Kutta methods for stiff O.D.E.'s", SIAM J. Numer.
Anal. 14 (1977) 1006. E. Hairer & G. Wanner, Solving Ordinary Differential Equations II,
2nd ed., Springer 1996, §IV.6 (SDIRK methods) and §IV.8 (error estimate, step control).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from microfab.core.validate import check_int

__all__ = [
    "SDIRK2",
    "ButcherTableau",
    "DenseProblem",
    "ImplicitIntegrator",
    "ImplicitProblem",
    "StepResult",
]


class ImplicitProblem(Protocol):
    """What an implicit Runge-Kutta step needs from a problem ``y' = f(t, y)``.

    ``y`` may have any shape (the jet keeps ``(nodes, 4)``); every method returns arrays
    of the shape of ``y``. The Newton matrix is ``M = I - γ h J`` with ``J = ∂f/∂y`` at
    the start of the step; rows that carry algebraic constraints (e.g. prescribed
    boundary values) may replace the differential residual by the constraint residual.
    """

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray | None:
        """``f(t, y)``, or None where it cannot be evaluated (e.g. a negative radius)."""
        ...

    def factor(self, t: float, y: np.ndarray, f: np.ndarray, gh: float) -> bool:
        """Form and factor ``M = I - gh J(t, y)``; ``f = f(t, y)`` is given. False: singular."""
        ...

    def residual(self, t: float, y: np.ndarray, base: np.ndarray, gh: float) -> np.ndarray | None:
        """Stage residual ``y - base - gh f(t, y)`` (constraint rows replaced), or None."""
        ...

    def solve(self, r: np.ndarray) -> np.ndarray | None:
        """``M^{-1} r`` with the factored matrix, or None if the solve fails."""
        ...

    def filter_error(self, est: np.ndarray) -> np.ndarray:
        """``M^{-1} est`` with the constraint rows of ``est`` zeroed first."""
        ...

    def norm(self, e: np.ndarray, y: np.ndarray) -> float:
        """Scaled size of a correction or error ``e`` at the state ``y`` (1: at tolerance)."""
        ...

    def admissible(self, y: np.ndarray) -> bool:
        """Whether a step result is acceptable apart from its error (e.g. node order)."""
        ...


@dataclass(frozen=True)
class StepResult:
    """Outcome of one integrator step.

    Attributes
    ----------
    y : numpy.ndarray or None
        State at ``t + h`` (shape of the input state), or None when the step failed (a
        right-hand side that could not be evaluated, a singular Newton matrix, a Newton
        iteration that diverged or did not converge, an inadmissible result).
    error : float
        Scaled local error estimate (accept if <= 1); ``inf`` for a failed step.
    """

    y: np.ndarray | None
    error: float

    @property
    def failed(self) -> bool:
        """True when no new state was produced."""
        return self.y is None


_FAILED = StepResult(None, math.inf)


class ImplicitIntegrator(Protocol):
    """An adaptive one-step integrator that a solver drives step by step."""

    @property
    def min_step(self) -> float:
        """Step size below which the solver should give up (time units of the problem)."""
        ...

    def step(self, problem: ImplicitProblem, t: float, y: np.ndarray, h: float) -> StepResult:
        """Advance ``y`` from ``t`` to ``t + h``."""
        ...

    def accepts(self, error: float) -> bool:
        """Whether a step with this scaled error is accepted."""
        ...

    def step_after_acceptance(self, h: float, error: float) -> float:
        """Next step size after an accepted step of size ``h``."""
        ...

    def step_after_rejection(self, h: float, error: float | None) -> float:
        """Retry step size after a rejected step (``error`` None: the step failed)."""
        ...


@dataclass(frozen=True)
class ButcherTableau:
    """Coefficients of an embedded Runge-Kutta pair.

    Attributes
    ----------
    a : numpy.ndarray
        Stage coefficients, shape (s, s).
    b : numpy.ndarray
        Weights of the solution, shape (s,).
    b_hat : numpy.ndarray
        Weights of the embedded, lower-order solution, shape (s,).
    c : numpy.ndarray
        Stage times as fractions of the step, shape (s,).
    """

    a: np.ndarray
    b: np.ndarray
    b_hat: np.ndarray
    c: np.ndarray


@dataclass(frozen=True, kw_only=True)
class SDIRK2:
    """Alexander's two-stage, L-stable SDIRK method with step-size control.

    Attributes
    ----------
    newton_max_iter : int
        Simplified-Newton iterations per stage before the step counts as failed, >= 1
        (default 10).
    newton_tol : float
        A stage has converged when the scaled size of the last Newton correction
        (`ImplicitProblem.norm`) is below this, > 0 (default 0.05).
    newton_divergence : float
        The iteration is abandoned when a correction grows by more than this factor over
        the previous one, > 1 (default 2).
    safety : float
        Safety factor of the step-size update, in (0, 1] (default 0.9).
    min_factor, max_factor : float
        Bounds of the step-size ratio after a step, ``0 < min_factor < 1 < max_factor``
        (defaults 0.2 and 3).
    failure_factor : float
        Step-size ratio after a failed step (Newton or right-hand side), in (0, 1)
        (default 0.25).
    error_floor : float
        Smallest error used in the update after an accepted step, > 0 (default 1e-10), so
        that an exact step still grows the step by at most ``max_factor``.
    min_step : float
        Step size below which a solver should stop (time units of the problem), > 0
        (default 1e-14).

    Examples
    --------
    One step of ``y' = -y`` from ``y = 1`` (exact: ``e^{-0.1} = 0.904837``):

    >>> import numpy as np
    >>> sdirk = SDIRK2()
    >>> problem = DenseProblem(lambda t, y: -y, lambda t, y: -np.eye(1), rtol=1e-2)
    >>> out = sdirk.step(problem, 0.0, np.array([1.0]), 0.1)
    >>> round(float(out.y[0]), 6), sdirk.accepts(out.error)
    (0.9048, True)
    """

    #: Diagonal coefficient γ = 1 - 1/√2 (Alexander 1977).
    gamma: ClassVar[float] = 1.0 - 1.0 / math.sqrt(2.0)
    #: Order of the solution.
    order: ClassVar[int] = 2
    #: Order of the embedded solution that the error estimate compares against.
    embedded_order: ClassVar[int] = 1

    newton_max_iter: int = 10
    newton_tol: float = 0.05
    newton_divergence: float = 2.0
    safety: float = 0.9
    min_factor: float = 0.2
    max_factor: float = 3.0
    failure_factor: float = 0.25
    error_floor: float = 1e-10
    min_step: float = 1e-14

    def __post_init__(self) -> None:
        check_int("newton_max_iter", self.newton_max_iter, 1)
        checks = (
            ("newton_tol", self.newton_tol > 0.0, "> 0"),
            ("newton_divergence", self.newton_divergence > 1.0, "> 1"),
            ("safety", 0.0 < self.safety <= 1.0, "in (0, 1]"),
            ("min_factor", 0.0 < self.min_factor < 1.0, "in (0, 1)"),
            ("max_factor", self.max_factor > 1.0, "> 1"),
            ("failure_factor", 0.0 < self.failure_factor < 1.0, "in (0, 1)"),
            ("error_floor", self.error_floor > 0.0, "> 0"),
            ("min_step", self.min_step > 0.0, "> 0"),
        )
        for name, ok, need in checks:
            value = getattr(self, name)
            if not (ok and math.isfinite(value)):
                raise ValueError(f"{name} must be finite and {need}, got {value!r}")

    @classmethod
    def tableau(cls) -> ButcherTableau:
        """The Butcher tableau with its embedded first-order weights (module docstring).

        Returns
        -------
        ButcherTableau
            ``a`` (2, 2), ``b``, ``b_hat`` and ``c`` (2,).
        """
        g = cls.gamma
        return ButcherTableau(
            a=np.array([[g, 0.0], [1.0 - g, g]]),
            b=np.array([1.0 - g, g]),
            b_hat=np.array([0.5, 0.5]),
            c=np.array([g, 1.0]),
        )

    def step(self, problem: ImplicitProblem, t: float, y: np.ndarray, h: float) -> StepResult:
        """One step from ``t`` to ``t + h``.

        Parameters
        ----------
        problem : ImplicitProblem
            Right-hand side, Newton matrix and error norm of the problem.
        t : float
            Time at the start of the step.
        y : numpy.ndarray
            State at ``t``, any shape; not modified.
        h : float
            Step size, > 0.

        Returns
        -------
        StepResult
            The state at ``t + h`` and the scaled, filtered error estimate, or a failure.
        """
        gamma = self.gamma
        f0 = problem.rhs(t, y)
        if f0 is None:
            return _FAILED
        gh = gamma * h
        if not problem.factor(t, y, f0, gh):
            return _FAILED
        y1 = self._solve_stage(problem, t + gh, y, y + gh * f0, gh)
        if y1 is None:
            return _FAILED
        k1 = (y1 - y) / gh
        base2 = y + (1.0 - gamma) * h * k1
        y2 = self._solve_stage(problem, t + h, base2, y + h * k1, gh)
        if y2 is None:
            return _FAILED
        k2 = (y2 - base2) / gh
        # h Σ (b_i - b̂_i) k_i with b - b̂ = (1/2 - γ, γ - 1/2)
        est = (h * (0.5 - gamma)) * (k1 - k2)
        err = problem.filter_error(est)
        if not problem.admissible(y2):
            return _FAILED
        return StepResult(y2, problem.norm(err, y2))

    def _solve_stage(
        self,
        problem: ImplicitProblem,
        ts: float,
        base: np.ndarray,
        guess: np.ndarray,
        gh: float,
    ) -> np.ndarray | None:
        """Simplified Newton for ``Y = base + gh f(ts, Y)`` from ``guess``."""
        yy = guess.copy()
        prev = math.inf
        for _ in range(self.newton_max_iter):
            res = problem.residual(ts, yy, base, gh)
            if res is None:
                return None
            delta = problem.solve(-res)
            if delta is None:
                return None
            yy += delta
            dn = problem.norm(delta, yy)
            if not math.isfinite(dn) or (dn > self.newton_divergence * prev and prev < math.inf):
                return None
            if dn < self.newton_tol:
                return yy
            prev = dn
        return None

    def accepts(self, error: float) -> bool:
        """Accept a step whose scaled error is at most 1 (a NaN error is rejected)."""
        return error <= 1.0

    def step_after_acceptance(self, h: float, error: float) -> float:
        """``h · min(max_factor, max(min_factor, safety / √max(error, error_floor)))``."""
        factor = self.safety / math.sqrt(max(error, self.error_floor))
        return h * min(self.max_factor, max(self.min_factor, factor))

    def step_after_rejection(self, h: float, error: float | None) -> float:
        """``h · failure_factor`` after a failure, else ``h · max(min_factor, safety / √error)``."""
        if error is None:
            return h * self.failure_factor
        return h * max(self.min_factor, self.safety / math.sqrt(error))


class DenseProblem:
    """`ImplicitProblem` for a small dense system ``y' = f(t, y)`` with a Jacobian.

    Parameters
    ----------
    f : callable
        ``f(t, y) -> dy/dt``, shape (n,) for a state of shape (n,).
    jac : callable
        ``jac(t, y) -> ∂f/∂y``, shape (n, n).
    rtol, atol : float, optional
        Tolerances of the error norm ``max |e_i| / (atol + rtol |y_i|)`` (defaults 1e-6
        and 1e-9).

    Examples
    --------
    >>> import numpy as np
    >>> p = DenseProblem(lambda t, y: -2.0 * y, lambda t, y: np.array([[-2.0]]))
    >>> p.rhs(0.0, np.array([1.0])).tolist()
    [-2.0]
    """

    def __init__(
        self,
        f: Callable[[float, np.ndarray], np.ndarray],
        jac: Callable[[float, np.ndarray], np.ndarray],
        *,
        rtol: float = 1e-6,
        atol: float = 1e-9,
    ) -> None:
        if not (rtol > 0.0 and atol > 0.0):
            raise ValueError(f"rtol and atol must be > 0, got {rtol} and {atol}")
        self.f = f
        self.jac = jac
        self.rtol = rtol
        self.atol = atol
        self._lu: tuple[np.ndarray, np.ndarray] | None = None

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray | None:
        """``f(t, y)``, None if not finite."""
        out = np.asarray(self.f(t, y), dtype=float)
        return out if np.all(np.isfinite(out)) else None

    def factor(self, t: float, y: np.ndarray, f: np.ndarray, gh: float) -> bool:
        """LU factors of ``I - gh J(t, y)``."""
        import scipy.linalg

        m = np.eye(y.size) - gh * np.asarray(self.jac(t, y), dtype=float)
        try:
            self._lu = scipy.linalg.lu_factor(m, check_finite=True)
        except (ValueError, np.linalg.LinAlgError):
            return False
        return bool(np.all(np.abs(np.diag(self._lu[0])) > 0.0))

    def residual(self, t: float, y: np.ndarray, base: np.ndarray, gh: float) -> np.ndarray | None:
        """``y - base - gh f(t, y)``."""
        fy = self.rhs(t, y)
        return None if fy is None else y - base - gh * fy

    def solve(self, r: np.ndarray) -> np.ndarray:
        """``M^{-1} r``."""
        import scipy.linalg

        if self._lu is None:
            raise RuntimeError("factor() must be called before solve()")
        return scipy.linalg.lu_solve(self._lu, r)

    def filter_error(self, est: np.ndarray) -> np.ndarray:
        """``M^{-1} est`` (no constraints)."""
        return self.solve(est)

    def norm(self, e: np.ndarray, y: np.ndarray) -> float:
        """``max |e_i| / (atol + rtol |y_i|)``."""
        return float(np.max(np.abs(e) / (self.atol + self.rtol * np.abs(y))))

    def admissible(self, y: np.ndarray) -> bool:
        """Every finite state is admissible."""
        return bool(np.all(np.isfinite(y)))
