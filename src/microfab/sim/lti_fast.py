"""Vectorised simulation of an all-LTI sampled feedback loop.

The loop of `microfab.sim.loop` (plant output read, noise added, error-feedback controller,
plant advanced) is linear when plant and controller are, so its closed-loop state-space
model is built once (`closed_loop_ss`) and simulated in blocks of ``L`` samples
("lifting"): within a block the outputs are ``O x_b + T u_b`` (observability matrix ``O``,
block-Toeplitz Markov matrix ``T``), and the state hops from block to block as
``x_{b+1} = A^L x_b + W u_b``. The two large products run for all blocks at once as BLAS
matrix products; only the short hop recursion is sequential (numba). The result is the
same recursion as the per-sample loop, re-associated, so both agree to round-off, and the
state is carried in physical coordinates between calls: successive calls behave as one
continuous run of the machine. The products run on one BLAS thread
(`microfab.core.threads.one_blas_thread`): they are small, and the result then does not
depend on the core count.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from microfab.core.arrays import readonly
from microfab.core.threads import one_blas_thread
from microfab.plants.lti import DiscreteLTI
from microfab.sim.result import SimResult

__all__ = ["BlockSimulator", "LTILoop", "closed_loop_ss"]


def closed_loop_ss(plant: DiscreteLTI, controller: DiscreteLTI) -> DiscreteLTI:
    """Closed-loop model of the error-feedback loop of `microfab.sim.loop.simulate`.

    Parameters
    ----------
    plant : DiscreteLTI
        Strictly proper plant, ``nu`` inputs and ``ny`` outputs.
    controller : DiscreteLTI
        Controller from the error ``r - (y + n)`` (``ny`` inputs) to commands (``nu``).

    Returns
    -------
    DiscreteLTI
        State ``[x_plant, x_controller]``; inputs ``[r (ny), n (ny)]``; outputs
        ``[y (ny), y + n (ny), u (nu)]``.
    """
    if np.any(plant.D != 0):
        raise ValueError("the plant must be strictly proper (D = 0)")
    Ap, Bp, Cp = plant.A, plant.B, plant.C
    Ac, Bc, Cc, Dc = controller.A, controller.B, controller.C, controller.D
    ny = plant.n_outputs
    if controller.n_inputs != ny or controller.n_outputs != plant.n_inputs:
        raise ValueError(
            f"controller must map {ny} errors to {plant.n_inputs} commands, "
            f"got {controller.n_inputs} -> {controller.n_outputs}"
        )
    nxc = Ac.shape[0]
    zeros_y = np.zeros((ny, nxc))
    A = np.block([[Ap - Bp @ Dc @ Cp, Bp @ Cc], [-Bc @ Cp, Ac]])
    B = np.block([[Bp @ Dc, -Bp @ Dc], [Bc, -Bc]])
    C = np.block([[Cp, zeros_y], [Cp, zeros_y], [-Dc @ Cp, Cc]])
    eye = np.eye(ny)
    D = np.block([[0 * eye, 0 * eye], [0 * eye, eye], [Dc, -Dc]])
    return DiscreteLTI(A, B, C, D, plant.dt)


@njit(cache=True)
def _hop(AL: np.ndarray, WU: np.ndarray, x0: np.ndarray, X: np.ndarray) -> None:
    """``X[:, 0] = x0``; ``X[:, b + 1] = AL @ X[:, b] + WU[:, b]``."""
    nx, nb = WU.shape
    for i in range(nx):
        X[i, 0] = x0[i]
    for b in range(nb):
        for i in range(nx):
            acc = WU[i, b]
            for j in range(nx):
                acc += AL[i, j] * X[j, b]
            X[i, b + 1] = acc


_Operators = tuple[
    list[np.ndarray],
    np.ndarray,
    np.ndarray,
    np.ndarray,
    dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]],
]


@functools.lru_cache(maxsize=64)
def _lifted_operators(sys: DiscreteLTI, L: int) -> _Operators:
    """``A^0..A^L``, ``O``, ``T``, ``W`` of `BlockSimulator` (read-only), and its row cache.

    Kept per model (an immutable `DiscreteLTI`, by identity) and block length, so that
    every simulator of one model, e.g. a new twin for each run, shares one set.
    """
    A, B, C, D = sys.A, sys.B, sys.C, sys.D
    nx, nu, ny = sys.n_states, sys.n_inputs, sys.n_outputs
    powers = [np.eye(nx)]
    for _ in range(L):
        powers.append(A @ powers[-1])
    # O: (L*ny, nx), rows k*ny:(k+1)*ny = C A^k
    obs = np.vstack([C @ powers[k] for k in range(L)])
    # Markov parameters h[0] = D, h[k] = C A^(k-1) B
    h = np.stack([D] + [C @ powers[k - 1] @ B for k in range(1, L)])  # (L, ny, nu)
    # T: block (i, j) = h[i - j] below the diagonal, 0 above
    lag = np.arange(L)[:, None] - np.arange(L)[None, :]
    blocks = np.where((lag >= 0)[:, :, None, None], h[np.clip(lag, 0, None)], 0.0)
    T = blocks.transpose(0, 2, 1, 3).reshape(L * ny, L * nu)
    # W: (nx, L*nu), block j = A^(L-1-j) B
    W = np.hstack([powers[L - 1 - j] @ B for j in range(L)])
    ro = [readonly(np.ascontiguousarray(m), dtype=None) for m in (*powers, obs, T, W)]
    return ro[: L + 1], ro[L + 1], ro[L + 2], ro[L + 3], {}


@functools.lru_cache(maxsize=64)
def _stable_closed_loop(plant: DiscreteLTI, controller: DiscreteLTI) -> DiscreteLTI:
    """`closed_loop_ss`, checked stable; kept per (plant, controller) pair, by identity."""
    cl = closed_loop_ss(plant, controller)
    if np.max(np.abs(cl.poles()), initial=0.0) >= 1.0:
        raise ValueError("the closed loop is unstable: a pole lies on or outside |z|=1")
    return cl


class BlockSimulator:
    """Simulate a `DiscreteLTI` in lifted blocks, carrying the state between calls.

    Parameters
    ----------
    sys : DiscreteLTI
        The model to simulate.
    block : int
        Block length ``L`` in samples (trades BLAS work ``~L`` per sample against the
        number of sequential hops ``n / L``).
    """

    def __init__(self, sys: DiscreteLTI, block: int = 32) -> None:
        if block < 1:
            raise ValueError(f"block must be >= 1 sample, got {block}")
        self.sys = sys
        self.L = block
        ops = _lifted_operators(sys, block)  # built once per model and block length
        self._powers, self._O, self._T, self._W, self._subsets = ops
        self.state = np.zeros(sys.n_states)

    def _rows(self, outputs: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """``O`` and ``T`` restricted to some outputs (cached with the operators)."""
        if outputs not in self._subsets:
            ny = self.sys.n_outputs
            rows = (np.arange(self.L)[:, None] * ny + np.array(outputs)[None, :]).ravel()
            self._subsets[outputs] = (
                readonly(np.ascontiguousarray(self._O[rows]), dtype=None),
                readonly(np.ascontiguousarray(self._T[rows]), dtype=None),
            )
        return self._subsets[outputs]

    def reset(self, state: np.ndarray | None = None) -> None:
        """Set the state (zero when ``None``)."""
        self.state = np.zeros(self.sys.n_states) if state is None else np.array(state, float)

    def run(self, u: np.ndarray, outputs: tuple[int, ...] | None = None) -> np.ndarray:
        """Advance by ``len(u)`` samples.

        Parameters
        ----------
        u : numpy.ndarray
            Inputs, shape (n_samples, n_inputs).
        outputs : tuple of int, optional
            Indices of the outputs to compute (all when ``None``); skipping outputs that
            are not needed saves most of the work.

        Returns
        -------
        numpy.ndarray
            Outputs, shape (n_samples, len(outputs)).
        """
        with one_blas_thread():  # small products: a thread team only waits (core.threads)
            return self._run(np.asarray(u, dtype=float), outputs)

    def _run(self, u: np.ndarray, outputs: tuple[int, ...] | None) -> np.ndarray:
        n, nu = u.shape
        if outputs is None:
            outputs = tuple(range(self.sys.n_outputs))
        obs, T = self._rows(outputs)
        ny, L = len(outputs), self.L
        nb, rest = divmod(n, L)
        y = np.empty((n, ny))
        x = self.state
        if nb:
            U, X = self._hops(u, nb, x)
            Y = obs @ X[:, :nb] + T @ U  # (L*ny, nb)
            y[: nb * L] = Y.T.reshape(nb * L, ny)
            x = X[:, nb].copy()
        if rest:
            ur = u[nb * L :].reshape(rest * nu)
            yr = obs[: rest * ny] @ x + T[: rest * ny, : rest * nu] @ ur
            y[nb * L :] = yr.reshape(rest, ny)
            x = self._tail(x, ur, rest, nu)
        self.state = x
        return y

    def advance(self, u: np.ndarray) -> None:
        """Advance by ``len(u)`` samples without computing outputs.

        The state reached is the one `run` reaches on the same inputs, to the bit (the
        same products in the same order), at a fraction of the work.

        Parameters
        ----------
        u : numpy.ndarray
            Inputs, shape (n_samples, n_inputs).
        """
        u = np.asarray(u, dtype=float)
        n, nu = u.shape
        nb, rest = divmod(n, self.L)
        x = self.state
        with one_blas_thread():
            if nb:
                _, X = self._hops(u, nb, x)
                x = X[:, nb].copy()
            if rest:
                x = self._tail(x, u[nb * self.L :].reshape(rest * nu), rest, nu)
        self.state = x

    def _hops(self, u: np.ndarray, nb: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Block inputs ``U`` (L*nu, nb) and the states at the block starts (nx, nb + 1)."""
        L, nu = self.L, u.shape[1]
        U = u[: nb * L].reshape(nb, L * nu).T  # (L*nu, nb), sample-major per block
        X = np.empty((x.size, nb + 1))
        _hop(self._powers[L], np.ascontiguousarray(self._W @ U), x, X)
        return U, X

    def _tail(self, x: np.ndarray, ur: np.ndarray, rest: int, nu: int) -> np.ndarray:
        """The state after a last, partial block of ``rest`` samples (inputs ``ur``)."""
        return self._powers[rest] @ x + self._W[:, (self.L - rest) * nu :] @ ur


class LTILoop:
    """Multi-axis LTI feedback loop: independent plant/controller pairs, vectorised.

    Each pair is one closed loop (SISO or MIMO) that takes the next ``n_outputs`` columns of
    the reference and noise; the pairs are simulated independently, each in lifted blocks.

    Parameters
    ----------
    plants, controllers : sequence of DiscreteLTI
        One strictly proper plant and its error-feedback controller per pair (the
        controller maps the plant's ``n_outputs`` errors to its ``n_inputs`` commands).
    axes : tuple of str
        Names of the output columns, all pairs together.
    block : int
        Lifting block length in samples.

    Raises
    ------
    ValueError
        When the lists differ in length or are empty, sample times differ, or a closed
        loop is unstable.
    """

    def __init__(
        self,
        plants: list[DiscreteLTI],
        controllers: list[DiscreteLTI],
        axes: tuple[str, ...] = (),
        block: int = 32,
    ) -> None:
        if len(plants) != len(controllers) or not plants:
            raise ValueError("give one plant and one controller per axis")
        self.dt = plants[0].dt
        if any(abs(p.dt - self.dt) > 1e-12 * self.dt for p in plants):
            raise ValueError(
                f"all plants must share one sample time, got {[p.dt for p in plants]} s"
            )
        self.loops = []
        self._cols: list[slice] = []
        self._sizes: list[tuple[int, int]] = []
        start = 0
        for p, c in zip(plants, controllers, strict=True):
            self.loops.append(BlockSimulator(_stable_closed_loop(p, c), block))
            self._cols.append(slice(start, start + p.n_outputs))
            self._sizes.append((p.n_outputs, p.n_inputs))
            start += p.n_outputs
        self.n_outputs = start
        self.n_inputs = sum(nu for _, nu in self._sizes)
        if axes and len(axes) != start:
            raise ValueError(f"give {start} axis names (one per output), got {len(axes)}")
        self.axes = axes or tuple(f"a{i}" for i in range(start))

    def reset(self) -> None:
        """Return every loop to rest."""
        for lp in self.loops:
            lp.reset()

    def run(
        self,
        reference: np.ndarray,
        noise: np.ndarray | None = None,
        with_command: bool = True,
    ) -> SimResult:
        """Continue the run by ``len(reference)`` samples.

        Parameters
        ----------
        reference : numpy.ndarray
            Loop reference, shape (n_samples, n_outputs).
        noise : numpy.ndarray, optional
            Measurement noise, same shape.
        with_command : bool
            Also compute the actuator command (about half the work); when ``False`` the
            result's ``command`` is ``None``.
        """
        ref, nz = self._signals(reference, noise)
        ys, us = [], []
        with one_blas_thread():
            for lp, cols, (ny, nu) in zip(self.loops, self._cols, self._sizes, strict=True):
                sel = tuple(range(ny))
                if with_command:
                    sel += tuple(range(2 * ny, 2 * ny + nu))
                out = lp.run(np.column_stack([ref[:, cols], nz[:, cols]]), sel)
                ys.append(out[:, :ny])
                us.append(out[:, ny:])
        y = np.column_stack(ys)
        return SimResult(
            dt=self.dt,
            reference=ref,
            output=y,
            measured=y + nz,
            command=np.column_stack(us) if with_command else None,
            axes=self.axes,
            final_state=[lp.state.copy() for lp in self.loops],
        )

    def advance(self, reference: np.ndarray, noise: np.ndarray | None = None) -> None:
        """Continue the run by ``len(reference)`` samples, keeping only the final state.

        Every loop ends where `run` would leave it on the same signals, to the bit; no
        output is computed (a settling period, say).

        Parameters
        ----------
        reference : numpy.ndarray
            Loop reference, shape (n_samples, n_outputs).
        noise : numpy.ndarray, optional
            Measurement noise, same shape.
        """
        ref, nz = self._signals(reference, noise)
        with one_blas_thread():
            for lp, cols in zip(self.loops, self._cols, strict=True):
                lp.advance(np.column_stack([ref[:, cols], nz[:, cols]]))

    def _signals(
        self, reference: np.ndarray, noise: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Reference and noise as checked (n_samples, n_outputs) float arrays."""
        ref = np.asarray(reference, dtype=float)
        if ref.ndim == 1:
            ref = ref[:, None]
        if ref.shape[1] != self.n_outputs:
            raise ValueError(f"reference needs {self.n_outputs} columns, got {ref.shape[1]}")
        nz = np.zeros_like(ref) if noise is None else np.asarray(noise, dtype=float)
        if nz.shape != ref.shape:
            raise ValueError(f"noise must be shaped {ref.shape}, got {nz.shape}")
        return ref, nz
