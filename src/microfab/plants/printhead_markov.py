"""ZOH Markov parameters of the printhead acoustics: the modal route and doubling.

:func:`.printhead.nozzle_flow` convolves the drive's voltage slope with the Markov
parameters ``g_i = c Φ^i Γ`` of the zero-order-hold discretisation of the diagonally
balanced acoustic model (`.printhead._balanced_model`). They come from the
eigen-decomposition of ``A`` (`_markov_modal`), or, where its eigenvectors are too
ill-conditioned, from the matrix exponential and repeated squaring (`_markov_doubling`).
Linear algebra on a given ``(A, b, c)``, apart from the model that builds it
(:mod:`.printhead`), which re-exports these names.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

__all__: list[str] = []

#: Largest eigenvector condition number for which the modal Markov parameters are used.
_MAX_MODAL_CONDITION = 1e6
#: Rows of the modal power table evaluated at once (bounds the memory to a few MB).
_MODAL_BLOCK = 2048


def _markov_modal(
    a_bal: np.ndarray, b_bal: np.ndarray, c_bal: np.ndarray, dt_s: float, n: int
) -> np.ndarray | None:
    """ZOH Markov parameters ``g_i = c Φ^i Γ`` from the eigen-decomposition of ``A``.

    With ``A = V Λ V⁻¹`` the ZOH model is ``Φ = V e^{Λ dt} V⁻¹`` and
    ``Γ = V diag((e^{λ dt} - 1) / λ) V⁻¹ b``, so ``g_i = Σ_m α_m μ_m^i`` with
    ``μ_m = e^{λ_m dt}``. Returns None when the eigenvectors are too ill-conditioned
    (near-defective ``A``) for this to be accurate.
    """
    lam, vec = np.linalg.eig(a_bal)
    try:
        inv = np.linalg.inv(vec)
    except np.linalg.LinAlgError:
        return None
    # 1-norm condition number (cheap: no SVD)
    condition = np.linalg.norm(vec, 1) * np.linalg.norm(inv, 1)
    if not condition < _MAX_MODAL_CONDITION:
        return None
    z = lam * dt_s
    small = np.abs(z) < 1e-8
    zoh_gain = np.where(small, dt_s * (1.0 + 0.5 * z), np.expm1(z) / np.where(small, 1.0, lam))
    alpha = (c_bal @ vec) * (inv @ b_bal) * zoh_gain
    block = min(n, _MODAL_BLOCK)
    powers = np.exp(np.arange(block)[:, None] * z[None, :])  # μ^j, j < block
    starts = np.arange(0, n, block)
    # μ^(i0 + j) = μ^i0 μ^j: one product per block of rows, the blocks side by side
    g = powers @ (alpha[:, None] * np.exp(z[:, None] * starts[None, :]))
    return g.real.T.reshape(-1)[:n]


def _markov_doubling(
    a_bal: np.ndarray, b_bal: np.ndarray, c_bal: np.ndarray, dt_s: float, n: int
) -> np.ndarray:
    """ZOH Markov parameters ``g_i = c Φ^i Γ`` by matrix exponential and doubling.

    ``Φ`` and ``Γ`` come from the exponential of the augmented matrix ``[[A, b], [0, 0]]
    dt``; the vectors ``Φ^i Γ`` are filled in blocks of doubling length (``Φ^m`` applied to
    the first ``m`` of them), so only ``log2(n)`` matrix products are needed. Used when
    ``A`` is too close to defective for the modal route.
    """
    nx = a_bal.shape[0]
    aug = np.zeros((nx + 1, nx + 1))
    aug[:nx, :nx] = a_bal * dt_s
    aug[:nx, nx] = b_bal * dt_s
    expo = scipy.linalg.expm(aug)
    rows = np.empty((n, nx))  # row i is (Φ^i Γ)ᵀ, kept C-contiguous
    rows[0] = expo[:nx, nx]
    power_t = np.ascontiguousarray(expo[:nx, :nx].T)  # (Φ^m)ᵀ
    m = 1
    while m < n:
        k = min(m, n - m)
        rows[m : m + k] = rows[:k] @ power_t
        m += k
        if m < n:
            power_t = power_t @ power_t
    return rows @ c_bal
