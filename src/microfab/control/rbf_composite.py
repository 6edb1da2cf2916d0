"""An RBF network added to a linear feedback: ``u = u_lin + Ŵᵀh(z)`` (seed 001 §3.2, §4.1).

Seed 001 eq. 4 makes the network the whole command, ``u = Ŵᵀh(z)``, so the network has to
approximate the certainty-equivalence law eq. 6 in full, and that law holds a feedback
linear in ``s`` (``−(1/(εβ) + ...) s``) and the linear part of ``−(α + v)/β`` (``β_l``,
"obtained from (9)", §4.1). A Gaussian network reproduces a term linear in ``s`` only
over the range its centres cover in ``s``, and only with widths that span that range: on
the twin, the default rule of `microfab.control.rbf_network` gives widths of ~4 scaled
units against an orbit of diameter 2, every ``h_j`` stays between 0.6 and 0.97 over the
circle, and the network is one constant basis function whose adaptive law (eq. 5) is an
integrator on ``s`` (a PI controller, ``Γ Σh_j² ≈ 1 V/mm``): it has no phase to learn
in, and its error does not fall from period to period (`microfab.experiments.
seed001_nanomanipulator.study`).

`RBFPlusLinear` gives the linear part of eq. 6 to a linear controller known from eq. 9
(the seed's Fig. 8 baseline: the PID) and leaves the network the unknown remainder, the
§4.1 ``α`` and ``β`` terms, which are functions of the state along the contour. The
adaptive law is eq. 5 unchanged, on the same ``s``; with the linear part holding the
stage, the network's centres need no spread in ``s`` and its widths can follow the
spacing of the centres along the contour (``s_spread = 0``), so that each node learns its
own part of the period. With ``Ŵ = 0`` the controller is the linear one exactly: the
comparison of seed 001 Fig. 8 is then PID against PID + network, same linear part, same
bandwidth.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.control.rbf import RBFAdaptive
from microfab.control.velocity import (
    N_ESTIMATOR_PARAMS,
    N_ESTIMATOR_STATES,
    VelocityEstimator,
    estimator_step,
)
from microfab.core.compiled import is_kernel

__all__ = ["NonlinearityOracle", "RBFPlusLinear"]

_HDR = 3  # [n_linear_params, n_linear_state, n_axes]


@functools.cache
def _composite_class(linear_kernel: Any) -> type[RBFPlusLinear]:
    """The `RBFPlusLinear` subclass whose kernel calls ``linear_kernel`` then the RBF's."""
    from microfab.control.rbf import rbf_step

    @njit(cache=True)
    def composite_step(
        p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
    ) -> None:
        npl = int(p[0])
        nxl = int(p[1])
        na = int(p[2])
        pl = p[_HDR : _HDR + npl]
        pr = p[_HDR + npl :]
        scratch = x[:na]
        xl = x[na : na + nxl]
        xr = x[na + nxl :]
        linear_kernel(pl, xl, ref, k, ym, u)
        rbf_step(pr, xr, ref, k, ym, scratch)
        for a in range(na):
            u[a] += scratch[a]

    return type(
        f"RBFPlusLinear[{getattr(linear_kernel, '__name__', 'kernel')}]",
        (RBFPlusLinear,),
        {"kernel_step": composite_step, "__module__": __name__},
    )


class RBFPlusLinear(CompiledController):
    """``u = u_lin + Ŵᵀh(z)``: a compiled linear feedback plus the RBF network (module notes).

    Parameters
    ----------
    linear : CompiledController
        The linear feedback (e.g. `microfab.control.pid.PID`), preview 1, 2 axes; its
        command in V.
    rbf : RBFAdaptive
        The network and its adaptive law (eq. 5), the same ``s`` and ``v``.

    Notes
    -----
    ``params = [n_linear_params, n_linear_state, 2, linear params, rbf params]``; state
    ``[network command scratch (2), linear state, rbf state]``.
    """

    kernel_step: Any = None  # set on the subclass made for each linear kernel

    def __new__(cls, linear: CompiledController, rbf: RBFAdaptive) -> RBFPlusLinear:
        """Instantiate the subclass made for ``type(linear).kernel_step``."""
        if cls is RBFPlusLinear:
            if not isinstance(linear, CompiledController):
                raise TypeError(
                    f"linear must be a CompiledController (PID, ...), got {type(linear).__name__}"
                )
            cls = _composite_class(type(linear).kernel_step)
        return super().__new__(cls)

    def __init__(self, linear: CompiledController, rbf: RBFAdaptive) -> None:
        if not isinstance(rbf, RBFAdaptive):
            raise TypeError(f"rbf must be an RBFAdaptive, got {type(rbf).__name__}")
        if int(linear.preview) != 1:
            raise ValueError(f"the linear controller must have preview 1, got {linear.preview}")
        self.linear = linear
        self.rbf = rbf
        self.preview = 1
        self.n_inputs = 2
        self.n_outputs = 2
        pl = linear.packed_params()
        self._nxl = int(np.asarray(linear.init()).size)
        self.params = np.concatenate(
            [np.array([pl.size, self._nxl, 2.0]), pl, rbf.packed_params()]
        ).astype(np.float64)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle as ``RBFPlusLinear(linear, rbf)`` (the subclass is made per process)."""
        return (RBFPlusLinear, (self.linear, self.rbf))

    def init(self) -> np.ndarray:
        """Both parts at rest (the network with its initial weights)."""
        return np.concatenate([np.zeros(2), self.linear.init(), self.rbf.init()])

    def rbf_state(self, state: np.ndarray) -> np.ndarray:
        """The network's part of ``state`` (a view)."""
        return state[2 + self._nxl :]

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python: ``(u_lin + Ŵᵀh, new state)``."""
        x = np.array(state, dtype=float)
        ul, xl = self.linear.step(x[2 : 2 + self._nxl], window, measurement)
        ur, xr = self.rbf.step(x[2 + self._nxl :], window, measurement)
        u = np.asarray(ul, dtype=float) + np.asarray(ur, dtype=float)
        x[:2] = ur
        x[2 : 2 + self._nxl] = xl
        x[2 + self._nxl :] = xr
        return u, x


_OHDR = 4 + N_ESTIMATOR_PARAMS  # [n_linear_params, n_linear_state, n_plant_params, 0, estimator]
_ONE = 2 * N_ESTIMATOR_STATES  # estimator states of both axes


@functools.cache
def _oracle_class(linear_kernel: Any, drift_and_gain: Any) -> type[NonlinearityOracle]:
    """The `NonlinearityOracle` subclass for one linear kernel and one plant function."""

    @njit(cache=True)
    def oracle_step(
        p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
    ) -> None:
        npl = int(p[0])
        nxl = int(p[1])
        npp = int(p[2])
        pl = p[_OHDR : _OHDR + npl]
        ptrue = p[_OHDR + npl : _OHDR + npl + npp]
        plin = p[_OHDR + npl + npp : _OHDR + npl + 2 * npp]
        st = x[:4]
        xl = x[4 + _ONE : 4 + _ONE + nxl]
        linear_kernel(pl, xl, ref, k, ym, u)
        st[0] = ym[0]
        st[1] = estimator_step(p, 4, x, 4, ym[0])
        st[2] = ym[1]
        st[3] = estimator_step(p, 4, x, 4 + N_ESTIMATOR_STATES, ym[1])
        for a in range(2):
            al, bl = drift_and_gain(plin, a, st)
            at, bt = drift_and_gain(ptrue, a, st)
            u[a] = (al - at) / bt + (bl / bt) * u[a]

    name = getattr(drift_and_gain, "__name__", "model")
    return type(
        f"NonlinearityOracle[{getattr(linear_kernel, '__name__', 'kernel')}, {name}]",
        (NonlinearityOracle,),
        {"kernel_step": oracle_step, "__module__": __name__},
    )


class NonlinearityOracle(CompiledController):
    """The network of `RBFPlusLinear` replaced by the true nonlinearity: the best it could do.

    With the plant ``ẍ = α(x) + β(x) u`` and its linear model ``ẍ = α_l(x) + β_l u``
    (seed 001 eq. 1 and eq. 9), the command

    ``u = (α_l − α)/β + (β_l/β) u_lin``

    makes the plant move as the linear model does under ``u_lin`` (the linear
    controller's command): the network's ideal output is ``u − u_lin``. ``α``, ``β`` are
    evaluated at the measured positions and the velocities of the RBF controller's
    filter (`microfab.control.velocity`), as the certainty-equivalence oracle does.

    Parameters
    ----------
    linear : CompiledController
        The linear part (as in `RBFPlusLinear`), preview 1, 2 axes.
    drift_and_gain : numba dispatcher
        ``(p, axis, x) -> (α, β)`` of the plant (mm/s², mm/(s² V)).
    plant_params, linear_params : numpy.ndarray
        The true twin's parameters and those of its linear model (same layout).
    estimator : VelocityEstimator
        Velocity filter (the RBF controller's).
    dt : float
        Sample time, s.
    """

    kernel_step: Any = None

    def __new__(
        cls, linear: CompiledController, drift_and_gain: Any, *args: Any, **kw: Any
    ) -> NonlinearityOracle:
        """Instantiate the subclass for ``linear``'s kernel and ``drift_and_gain``."""
        if cls is NonlinearityOracle:
            if not isinstance(linear, CompiledController):
                raise TypeError(
                    f"linear must be a CompiledController (PID, ...), got {type(linear).__name__}"
                )
            if not is_kernel(drift_and_gain):
                raise ValueError("drift_and_gain must be a numba @njit function (p, axis, x)")
            cls = _oracle_class(type(linear).kernel_step, drift_and_gain)
        return super().__new__(cls)

    def __init__(
        self,
        linear: CompiledController,
        drift_and_gain: Any,
        plant_params: np.ndarray,
        linear_params: np.ndarray,
        estimator: VelocityEstimator,
        dt: float,
    ) -> None:
        pt = np.ascontiguousarray(np.asarray(plant_params, dtype=np.float64).ravel())
        plin = np.ascontiguousarray(np.asarray(linear_params, dtype=np.float64).ravel())
        if pt.shape != plin.shape:
            raise ValueError(
                f"plant_params {pt.shape} and linear_params {plin.shape} must share a layout"
            )
        if int(linear.preview) != 1:
            raise ValueError(f"the linear controller must have preview 1, got {linear.preview}")
        self.linear = linear
        self.preview = 1
        self.n_inputs = 2
        self.n_outputs = 2
        self._nxl = int(np.asarray(linear.init()).size)
        pl = linear.packed_params()
        head = np.zeros(_OHDR)
        head[:3] = (pl.size, self._nxl, pt.size)
        head[4:] = estimator.discrete(dt)
        self.params = np.concatenate([head, pl, pt, plin]).astype(np.float64)
        self._args = (drift_and_gain, pt, plin, estimator, dt)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle as ``NonlinearityOracle(linear, ...)``."""
        return (NonlinearityOracle, (self.linear, *self._args))

    def init(self) -> np.ndarray:
        """State estimate (4), estimators not started, the linear part at rest."""
        return np.concatenate([np.zeros(4 + _ONE), self.linear.init()])

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference for the kernel): ``(u, new state)``."""
        drift, pt, plin, est, _ = self._args
        x = np.array(state, dtype=float)
        ym = np.asarray(measurement, dtype=float)
        ul, x[4 + _ONE :] = self.linear.step(x[4 + _ONE :], window, measurement)
        phi = self.params[4:_OHDR]
        for a in range(2):
            i0 = 4 + a * N_ESTIMATOR_STATES
            vel, x[i0 : i0 + N_ESTIMATOR_STATES] = est.step(
                phi, x[i0 : i0 + N_ESTIMATOR_STATES], float(ym[a])
            )
            x[2 * a], x[2 * a + 1] = ym[a], vel
        st = np.array(x[:4])
        u = np.empty(2)
        for a in range(2):
            al, bl = drift(plin, a, st)
            at, bt = drift(pt, a, st)
            u[a] = (al - at) / bt + (bl / bt) * float(ul[a])
        return u, x
