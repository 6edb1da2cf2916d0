"""Discrete-time linear time-invariant (LTI) models.

`DiscreteLTI` is the one state-space container the simulators, the controllers and the
learning methods share. Continuous models are built with python-control and discretised
here (ZOH for plants, Tustin for controllers), so the rest of microfab never has to care
which library produced a model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg

import control
from microfab.core.validate import check_positive

__all__ = ["DiscreteLTI", "block_diag", "discretize", "freqresp_ss", "with_input_delay"]

_FREQ_CHUNK = 1024  # evaluation points per stacked solve in `freqresp_ss`


def freqresp_ss(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, z: np.ndarray
) -> np.ndarray:
    """Evaluate ``C (zI - A)^-1 B + D`` at many complex points.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        State-space matrices, shapes (nx, nx), (nx, nu), (ny, nx), (ny, nu).
    z : numpy.ndarray
        Complex evaluation points, shape (n_points,).

    Returns
    -------
    numpy.ndarray
        Complex responses, shape (n_points, ny, nu). Points on a pole give ``inf``.
    """
    z = np.atleast_1d(np.asarray(z, dtype=complex))
    nx = A.shape[0]
    if nx == 0:
        return np.broadcast_to(D.astype(complex), (z.size, *D.shape)).copy()
    # Modal form: one eigen-decomposition, then a cheap evaluation per point.
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) < 1e8:
        Bm = np.linalg.solve(V, B.astype(complex))
        Cm = C @ V
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / (z[:, None] - lam[None, :])
        out = np.einsum("yi,fi,iu->fyu", Cm, inv, Bm) + D[None, :, :]
        out[~np.isfinite(inv).all(axis=1)] = np.inf
        return out
    out = np.empty((z.size, C.shape[0], B.shape[1]), dtype=complex)
    eye = np.eye(nx)
    Bc = B.astype(complex)
    # stacked solves (one LAPACK call per point, as a loop would make), a chunk at a time
    for lo in range(0, z.size, _FREQ_CHUNK):
        zc = z[lo : lo + _FREQ_CHUNK]
        try:
            X = np.linalg.solve(zc[:, None, None] * eye - A, Bc)
        except np.linalg.LinAlgError:  # a point on a pole: solve point by point
            for i, zi in enumerate(zc, start=lo):
                try:
                    out[i] = C @ np.linalg.solve(zi * eye - A, B) + D
                except np.linalg.LinAlgError:
                    out[i] = np.inf
            continue
        out[lo : lo + zc.size] = C @ X + D
    return out


@dataclass(frozen=True, eq=False)
class DiscreteLTI:
    """A discrete-time state-space model ``x[k+1] = A x[k] + B u[k]``, ``y = C x + D u``.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        State-space matrices, shapes (nx, nx), (nx, nu), (ny, nx), (ny, nu).
    dt : float
        Sample time in seconds.
    input_names, output_names : tuple of str, optional
        Labels of the input and output channels.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    input_names: tuple[str, ...] = field(default=())
    output_names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        A = np.array(self.A, dtype=float, ndmin=2)
        B = np.array(self.B, dtype=float, ndmin=2)
        C = np.array(self.C, dtype=float, ndmin=2)
        D = np.array(self.D, dtype=float, ndmin=2)
        nx = A.shape[0] if A.size else 0
        if A.size == 0:
            A = np.zeros((0, 0))
            B = np.zeros((0, D.shape[1]))
            C = np.zeros((D.shape[0], 0))
        if A.shape != (nx, nx) or B.shape[0] != nx or C.shape[1] != nx:
            raise ValueError(
                f"state-space shapes do not match: A {A.shape}, B {B.shape}, C {C.shape}"
            )
        if D.shape != (C.shape[0], B.shape[1]):
            raise ValueError(f"D must have shape {(C.shape[0], B.shape[1])}, got {D.shape}")
        check_positive("dt", self.dt, "s")
        for name, m in zip("ABCD", (A, B, C, D), strict=True):
            if not np.all(np.isfinite(m)):
                raise ValueError(f"state-space matrix {name} holds NaN or inf")
            m.setflags(write=False)
            object.__setattr__(self, name, m)

    @property
    def n_states(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of outputs."""
        return self.C.shape[0]

    def frequency_response(self, freq_hz: np.ndarray) -> np.ndarray:
        """Complex frequency response at frequencies in Hz, shape (n_freq, ny, nu).

        Negative frequencies are allowed (they give the complex conjugate).
        """
        f = np.asarray(freq_hz, dtype=float)
        z = np.exp(2j * np.pi * f.ravel() * self.dt)
        return freqresp_ss(self.A, self.B, self.C, self.D, z)

    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` (discrete-time poles)."""
        return np.linalg.eigvals(self.A)

    def zeros(self, i_out: int = 0, i_in: int = 0) -> np.ndarray:
        """Finite transmission zeros of the channel ``i_in -> i_out``.

        Computed from the Rosenbrock system pencil, which stays accurate where root-finding
        on a polynomial of a 1 MHz model would not.
        """
        A, B, C, D = self.A, self.B[:, [i_in]], self.C[[i_out], :], self.D[[i_out]][:, [i_in]]
        nx = self.n_states
        if nx == 0:
            return np.zeros(0, dtype=complex)
        # Balance first: 1 MHz models mix entries from 1e-10 to 1e7, and the pencil's
        # eigenvalues lose several digits without it.
        _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
        A = A / scale[:, None] * scale[None, :]
        B = B / scale[:, None]
        C = C * scale[None, :]
        M = np.block([[A, B], [C, D]])
        N = np.zeros_like(M)
        N[:nx, :nx] = np.eye(nx)
        w = scipy.linalg.eigvals(M, N)
        return w[np.isfinite(w) & (np.abs(w) < 1e8)]

    def channel(self, i_out: int, i_in: int) -> DiscreteLTI:
        """The single-input single-output channel ``i_in -> i_out`` (states kept as they are)."""
        return DiscreteLTI(
            self.A, self.B[:, [i_in]], self.C[[i_out], :], self.D[[i_out]][:, [i_in]], self.dt
        )


def discretize(
    sys: control.LTI, dt: float, method: Literal["zoh", "tustin", "foh"] = "zoh"
) -> DiscreteLTI:
    """Discretise a continuous python-control model.

    Parameters
    ----------
    sys : control.TransferFunction or control.StateSpace
        Continuous-time model.
    dt : float
        Sample time in s.
    method : {"zoh", "tustin", "foh"}
        ZOH for plants driven by a DAC, Tustin for controllers.
    """
    check_positive("dt", dt, "s")
    ss = control.ss(sys)
    d = control.c2d(ss, dt, method=method)
    return DiscreteLTI(d.A, d.B, d.C, d.D, dt)


def block_diag(*systems: DiscreteLTI) -> DiscreteLTI:
    """Stack independent systems (e.g. the x and y axes) into one block-diagonal model."""
    if not systems:
        raise ValueError("block_diag needs at least one system")
    dt = systems[0].dt
    if any(abs(s.dt - dt) > 1e-15 * dt for s in systems):
        raise ValueError("block_diag: all systems must share the same dt")
    return DiscreteLTI(
        scipy.linalg.block_diag(*(s.A for s in systems)),
        scipy.linalg.block_diag(*(s.B for s in systems)),
        scipy.linalg.block_diag(*(s.C for s in systems)),
        scipy.linalg.block_diag(*(s.D for s in systems)),
        dt,
    )


def with_input_delay(sys: DiscreteLTI, n_samples: int) -> DiscreteLTI:
    """Append a pure delay of ``n_samples`` on every input (computation/DAC delay)."""
    if n_samples < 0:
        raise ValueError(f"delay must be >= 0 samples, got {n_samples}")
    if n_samples == 0:
        return sys
    nu = sys.n_inputs
    # delay line: n_samples*nu states
    nd = n_samples * nu
    Ad = np.zeros((nd, nd))
    Ad[nu:, :-nu] = np.eye(nd - nu)
    Bd = np.zeros((nd, nu))
    Bd[:nu] = np.eye(nu)
    Cd = np.zeros((nu, nd))
    Cd[:, -nu:] = np.eye(nu)
    nx = sys.n_states
    A = np.block([[sys.A, sys.B @ Cd], [np.zeros((nd, nx)), Ad]])
    B = np.vstack([np.zeros((nx, nu)), Bd])
    C = np.hstack([sys.C, sys.D @ Cd])
    D = np.zeros((sys.n_outputs, nu))
    return DiscreteLTI(A, B, C, D, sys.dt, sys.input_names, sys.output_names)
