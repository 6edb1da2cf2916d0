"""Whitened inputs for the per-axis networks' training, folded back into the first layer.

The seed's inputs (seed 002 §III-B: the last 500 ms of one axis's command at 400 Hz) are
200 samples of one smooth signal, nearly collinear: after the per-column `Scaling` the
covariance of the training windows has eigenvalues from about 175 down to 1e-12 (the
calibrated twin, 60 s of the networks' data). Adam's steps then crawl along the small
directions. The training therefore feeds the network ``W s``, where ``s`` is the scaled
window and ``W`` the ZCA whitening of the training windows,

    W = V diag(1 / sqrt(λ + ε λ̄)) Vᵀ,  C = V diag(λ) Vᵀ = E[s sᵀ] over the windows,

with the shrinkage ``ε`` relative to the mean eigenvalue λ̄ (`microfab.identify.ann.
AnnConfig.whiten`), so a direction the training data hardly visit is amplified at most
``1 / sqrt(ε)`` times. When the training ends, ``W`` is folded into the first layer
(``W₁ ← W₁ W``, in float64, stored as float32): the saved network is the seed's Fig. 5
network on the per-column scaled inputs, and nothing that reads a model changes.

Measured (the calibrated twin, 60 s of the networks' data, seed 0, batches of 16 384,
262 144 windows per epoch, learning rate 1e-3 decaying 0.95 per epoch), validation σ
x / y: without whitening 7.1 / 13.7 µm after 60 epochs (still falling); whitened with
ε = 1e-3, 5.19 / 9.81 µm at its best epoch (10 / 15), after which it over-fits (6.7 /
11.2 at 55) and early stopping keeps the best.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from microfab.identify.ann import check_whiten
from microfab.identify.ann_data import Scaling, WindowSet

__all__ = [
    "COVARIANCE_WINDOWS",
    "LEAST_COVARIANCE_WINDOWS",
    "covariance_windows",
    "fold",
    "input_covariance",
    "unfold",
    "whitening",
]

#: Most training windows the covariance is summed over (evenly strided, no random draw):
#: ample for a 200 x 200 matrix, and about a second on one thread (assumed). A training of
#: shorter epochs sums over one epoch's worth, at least `LEAST_COVARIANCE_WINDOWS`
#: (`covariance_windows`).
COVARIANCE_WINDOWS = 262_144
#: Fewest windows of the covariance when the training has fewer (assumed: 65 536, a few
#: hundred per input of 200).
LEAST_COVARIANCE_WINDOWS = 65_536

_CHUNK = 65_536


def covariance_windows(epoch_windows: int | None) -> int:
    """Windows the covariance sums over for epochs of ``epoch_windows`` (None: all).

    `COVARIANCE_WINDOWS`, or one epoch's worth when epochs are shorter, but at least
    `LEAST_COVARIANCE_WINDOWS`.
    """
    if epoch_windows is None:
        return COVARIANCE_WINDOWS
    return min(COVARIANCE_WINDOWS, max(int(epoch_windows), LEAST_COVARIANCE_WINDOWS))


def input_covariance(
    windows: WindowSet, axis: int, scaling: Scaling, *, most: int = COVARIANCE_WINDOWS
) -> np.ndarray:
    """``E[s sᵀ]`` of the scaled inputs ``s`` of ``windows`` for ``axis``.

    Parameters
    ----------
    windows : WindowSet
        The training windows.
    axis : int
        Index of the axis (0 x, 1 y).
    scaling : Scaling
        The per-column scaling the network reads its inputs through.
    most : int
        Most windows summed, evenly strided over all of them.

    Returns
    -------
    numpy.ndarray
        Shape (n_inputs, n_inputs), dimensionless, float64, symmetric.
    """
    n = len(windows)
    idx = np.unique(np.linspace(0, n - 1, min(n, most)).round().astype(np.int64))
    c = np.zeros((scaling.n_inputs, scaling.n_inputs))
    for i in range(0, idx.size, _CHUNK):
        x, _ = windows.batch(idx[i : i + _CHUNK], axis)
        s = scaling.scale_inputs(x).astype(np.float64)
        c += s.T @ s
    c /= idx.size
    return 0.5 * (c + c.T)


def whitening(covariance: np.ndarray, shrink: float) -> tuple[np.ndarray, np.ndarray]:
    """ZCA whitening of ``covariance`` with relative shrinkage, and its inverse.

    Parameters
    ----------
    covariance : numpy.ndarray
        Shape (n, n), symmetric, positive semi-definite.
    shrink : float
        ``ε``: added to every eigenvalue as a share of their mean (module docstring), in
        [`microfab.identify.ann.WHITEN_LOW`, 1].

    Returns
    -------
    (W, W_inv) : tuple of numpy.ndarray
        Each (n, n), float64, symmetric: ``W = V diag((λ + ε λ̄)^-1/2) Vᵀ`` and
        ``W_inv = V diag((λ + ε λ̄)^1/2) Vᵀ``.
    """
    check_whiten(shrink)
    c = np.asarray(covariance, dtype=np.float64)
    if c.ndim != 2 or c.shape[0] != c.shape[1] or not np.all(np.isfinite(c)):
        raise ValueError(f"covariance must be a finite square matrix, got shape {c.shape}")
    lam, v = np.linalg.eigh(0.5 * (c + c.T))
    lam = np.maximum(lam, 0.0)
    floor = shrink * max(float(lam.mean()), np.finfo(float).tiny)
    d = np.sqrt(lam + floor)
    return (v / d) @ v.T, (v * d) @ v.T


def _first_linear(net: nn.Module) -> nn.Linear:
    for m in net.modules():
        if isinstance(m, nn.Linear):
            return m
    raise ValueError("the network has no linear layer")


def fold(net: nn.Module, w: np.ndarray) -> None:
    """Make ``net`` read unwhitened inputs: first layer's weight ``← weight @ w`` (in place).

    The product is taken in float64 and stored in the layer's dtype.
    """
    _matmul_first(net, w)


def unfold(net: nn.Module, w_inv: np.ndarray) -> None:
    """Inverse of `fold` (``w_inv`` the whitening's inverse): a warm start's first layer."""
    _matmul_first(net, w_inv)


def _matmul_first(net: nn.Module, m: np.ndarray) -> None:
    lin = _first_linear(net)
    with torch.no_grad():
        w = lin.weight.detach().cpu().double().numpy() @ np.asarray(m, dtype=np.float64)
        lin.weight.copy_(torch.from_numpy(w).to(lin.weight.dtype))
