"""The per-axis networks of seed 002 (eq. 7) as a differentiable map of the 400 Hz input.

For the input ``r_0 … r_{M-1}`` (400 Hz, m) of a run that starts at rest on ``rest`` and
holds ``r_{M-1}`` after the end, the networks predict

``φ_i = f(r_{i-h}, …, r_{i-1})``, ``i = 1 … M + tail`` (eq. 7),

with ``r_j = rest`` for ``j < 0`` (the windows padded as `microfab.identify.ann_data.windows`
pads a run that starts at rest) and ``r_j = r_{M-1}`` for ``j ≥ M``. `NetworkMap.predict`
gives ``φ``; `NetworkMap.linearize` gives ``φ`` and its Jacobian ``∂φ/∂r`` as a sparse
matrix. Each ``φ_i`` depends only on its own window, so one backward pass of the sum of
the outputs over the batch of windows gives every row of the Jacobian (each row holds the
gradient of one output with respect to its ``h`` inputs); the rows are scattered into
the banded matrix by index arithmetic. The window's encoding (``extrapolated``,
``relative`` or ``absolute``), the scaling and the output's base are written in torch
from the model's own `WindowSpec` and `Scaling` (its position features too), in float64;
the networks run in float32 as trained. `NetworkMap.predict` equals `AnnModel.predict`
(``at="400hz"``) on the command whose 400 Hz samples are ``rest, …, rest, r_0, …`` (tested).

Threads: the calls run on ``threads`` torch threads (default 1), set on entry and
restored on exit. Inside stage 2, between CasADi's solves, two threads made the Jacobian
8-30x slower than one (issue 18: 0.15 s against 3.35 s for 7 Jacobians at M = 918 in
issue 34, 0.02 s each on one thread), the threads' pools contending with the solver's;
outside, the batches (M + tail windows of h inputs) are too small to gain from a second.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import scipy.sparse as sp

__all__ = ["NetworkMap"]


class NetworkMap:
    """``φ(r)`` and ``∂φ/∂r`` of an `microfab.identify.ann.AnnModel` (module docstring).

    Parameters
    ----------
    model : microfab.identify.ann.AnnModel
        Networks for both axes ("x", "y").
    tail : int
        Samples predicted after the end (the input held), default ``h``.
    threads : int or None
        Torch threads during `predict` and `linearize` (module docstring), >= 1; None
        leaves torch's count as it stands.
    """

    def __init__(self, model: Any, tail: int | None = None, threads: int | None = 1) -> None:
        import torch

        from microfab.identify.ann_data import AXES

        if tuple(model.axes) != AXES:
            raise ValueError(f"the networks must model both axes {AXES}, got {model.axes}")
        self.model = model
        self.spec = model.spec
        self.h = int(self.spec.h)
        self.tail = self.h if tail is None else int(tail)
        if self.tail < 0:
            raise ValueError(f"tail must be >= 0 samples, got {tail}")
        if threads is not None and (
            isinstance(threads, bool) or not isinstance(threads, int) or threads < 1
        ):
            raise ValueError(f"threads must be an integer >= 1 or None, got {threads!r}")
        self.threads = threads
        self._torch = torch
        self._scal = {}
        for a in AXES:
            s = model.scalings[a]
            self._scal[a] = tuple(torch.as_tensor(v, dtype=torch.float64) for v in
                                  (s.in_offset, s.in_scale, s.out_offset, s.out_scale))  # fmt: skip

    @contextmanager
    def _threads(self) -> Iterator[None]:
        """Torch on `threads` threads inside, the caller's count restored after."""
        torch = self._torch
        before = torch.get_num_threads()
        if self.threads is None:
            yield
            return
        if before != self.threads:
            torch.set_num_threads(self.threads)
        try:
            yield
        finally:
            if torch.get_num_threads() != before:
                torch.set_num_threads(before)

    # ------------------------------------------------------------------ windows
    def _series(self, r: np.ndarray, rest: np.ndarray) -> np.ndarray:
        r = np.asarray(r, dtype=float)
        rest = np.asarray(rest, dtype=float).reshape(2)
        if r.ndim != 2 or r.shape[1] != 2 or r.shape[0] < 1 or not np.all(np.isfinite(r)):
            raise ValueError(f"r must be a finite (M, 2) array with M >= 1, got {r.shape}")
        h, m = self.h, r.shape[0]
        return np.vstack([np.repeat(rest[None], h, axis=0), r,
                          np.repeat(r[-1:], self.tail, axis=0)])[1 : h + m + self.tail]  # fmt: skip

    def _encode(self, win: Any) -> tuple[Any, Any]:
        """Encoded windows (b, h) and base (b,) of one axis, torch float64."""
        enc = self.spec.encoding
        last = win[:, -1]
        if enc == "absolute":
            return win, self._torch.zeros_like(last)
        e = win - last[:, None]
        e = self._torch.cat([e[:, :-1], last[:, None]], dim=1)
        if enc == "extrapolated":
            return e, 2.0 * last - win[:, -2]
        return e, last

    def _features(self, win: Any) -> Any:
        """Position features of raw windows (b, h), torch float64 (`position_features`)."""
        from microfab.identify.ann_data import FEATURE_LAGS, FEATURE_WAVELENGTHS_M

        torch = self._torch
        pos = win[:, [-k for k in FEATURE_LAGS]]
        lam = torch.as_tensor(FEATURE_WAVELENGTHS_M, dtype=torch.float64)
        phase = (2.0 * np.pi) * pos[:, :, None] / lam
        return torch.cat([torch.sin(phase), torch.cos(phase)], dim=2).reshape(win.shape[0], -1)

    def _phi(self, wins: dict[str, Any], axis: str) -> Any:
        """Predicted position of ``axis`` for raw windows (torch float64, (b,))."""
        e_own, base = self._encode(wins[axis])
        read = (axis,) if self.spec.inputs == "own" else ("x", "y")
        parts = [e_own if a == axis else self._encode(wins[a])[0] for a in read]
        if self.spec.features == "position":
            parts += [self._features(wins[a]) for a in read]
        x = parts[0] if len(parts) == 1 else self._torch.cat(parts, dim=1)
        off, scale, out_off, out_scale = self._scal[axis]
        z = ((x - off) / scale).to(self._torch.float32)
        y = self.model.networks[axis](z)[:, 0].to(self._torch.float64)
        return y * out_scale + out_off + base

    def _windows(self, series: np.ndarray, grad: bool) -> dict[str, Any]:
        torch = self._torch
        out = {}
        for k, a in enumerate(("x", "y")):
            t = torch.as_tensor(np.ascontiguousarray(series[:, k]), dtype=torch.float64)
            w = t.unfold(0, self.h, 1).contiguous()
            if grad:
                w.requires_grad_(True)
            out[a] = w
        return out

    # ------------------------------------------------------------------ public
    def predict(self, r: np.ndarray, rest: np.ndarray) -> np.ndarray:
        """``φ_1 … φ_{M+tail}``, shape (M + tail, 2), m."""
        wins = self._windows(self._series(r, rest), grad=False)
        with self._threads(), self._torch.inference_mode():
            return np.column_stack([self._phi(wins, a).numpy() for a in ("x", "y")])

    def linearize(self, r: np.ndarray, rest: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        """``φ`` (M + tail, 2) and ``∂φ/∂r`` as CSR, shape (2 (M + tail), 2 M).

        Rows: ``φ_x`` then ``φ_y``; columns: ``r_x`` then ``r_y``.
        """
        with self._threads():
            return self._linearize(r, rest)

    def _linearize(self, r: np.ndarray, rest: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        m = np.asarray(r).shape[0]
        wins = self._windows(self._series(r, rest), grad=True)
        n_out = m + self.tail
        rows, cols, vals, phis = [], [], [], []
        # window row i (0-based, output i + 1) holds r_{i+1-h} … r_i
        idx = (np.arange(n_out)[:, None] + 1 - self.h) + np.arange(self.h)[None, :]
        keep = idx >= 0  # before the start: rest, a constant
        col = np.minimum(idx, m - 1)  # after the end: r_{M-1} held
        row = np.broadcast_to(np.arange(n_out)[:, None], idx.shape)
        for k, a in enumerate(("x", "y")):
            phi = self._phi(wins, a)
            g = self._torch.autograd.grad(phi.sum(), [wins["x"], wins["y"]],
                                          allow_unused=True)  # fmt: skip
            phis.append(phi.detach().numpy())
            for j, gj in enumerate(g):
                if gj is None:
                    continue
                gv = gj.numpy()
                rows.append(row[keep] + k * n_out)
                cols.append(col[keep] + j * m)
                vals.append(gv[keep])
        jac = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(2 * n_out, 2 * m),
        )
        jac.sum_duplicates()
        return np.column_stack(phis), jac
