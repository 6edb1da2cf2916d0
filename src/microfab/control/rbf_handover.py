"""Bumpless hand-over to the RBF controller: initial weights that continue the last command.

Seed 001 leaves ``Ŵ(0)`` open (§3.2). Started from ``Ŵ(0) = 0`` in the middle of a job
(the stage held off-centre by another controller), the network of eq. 4 commands 0 V and
the stage falls back; started from weights that only reproduce the last command
(``Ŵ ∝ h``), the network's output is even in ``s`` around the centres (they alternate
``±s_spread``, `microfab.control.rbf.RBFAdaptive.for_reference`) and gives no feedback
until the adaptation builds it: on the seed 001 twin at rest that let the 50 Hz modes of
eq. 9 grow to 0.45 mm within 50 ms (measured, noise on and off). The hand-over weights
here satisfy, per axis, two linear conditions at the hand-over input ``z0``:

* ``Ŵᵀ h(z0) = u0``: the last command of the previous controller (bumpless);
* ``Ŵᵀ ∂h/∂s (z0) = −k_s``: a feedback on ``s = λe + ė`` (``e = x − r``) that adds the
  damping ratio ``ζ_h`` to the axis's eq. 9 mode, ``k_s = 2 ζ_h ω_n / K``
  (``P = K / (s² + a1 s + ω_n²)``);

and are the least-norm solution of the two (numpy ``lstsq``). After the hand-over the
adaptive law (eq. 5) runs as usual. ``ζ_h = 1`` (assumed: critical damping injected;
on the twin ``ζ_h = 1.6`` still held and ``ζ_h = 8`` diverged, measured).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from microfab.control.rbf import RBFAdaptive
from microfab.core.validate import check_positive

__all__ = ["feedback_gain", "handover"]

N_AXES = 2  # x and y, seed 001
_S = 4  # index of s in z = (x1, x2, x̄1, x̄2, s, v), seed 001 §3.2


def feedback_gain(numerator: float, stiffness: float, damping_ratio: float = 1.0) -> float:
    """``k_s = 2 ζ_h ω_n / K`` for ``P = K / (s² + a1 s + ω_n²)``, V/(mm/s).

    Parameters
    ----------
    numerator : float
        ``K`` of eq. 9, mm/(V s²), > 0.
    stiffness : float
        ``ω_n²`` of eq. 9, 1/s², > 0.
    damping_ratio : float
        Damping ratio ``ζ_h`` the feedback adds, > 0 (default 1, assumed: module notes).
    """
    k = check_positive("numerator (K of eq. 9)", numerator, "mm/(V s²)")
    w2 = check_positive("stiffness (a0 of eq. 9)", stiffness, "1/s²")
    z = check_positive("damping_ratio (handover)", damping_ratio, "")
    return 2.0 * z * float(np.sqrt(w2)) / k


def handover(
    rbf: RBFAdaptive,
    *,
    measured: np.ndarray,
    reference: np.ndarray,
    command: np.ndarray,
    gains: Sequence[float],
) -> RBFAdaptive:
    """The controller ``rbf`` with hand-over initial weights (module notes).

    Parameters
    ----------
    rbf : RBFAdaptive
        Centres, widths and scaling to keep (e.g. `RBFAdaptive.for_reference`).
    measured : numpy.ndarray
        Measured position at the hand-over, mm, shape (2,) (a short mean suppresses the
        encoder noise).
    reference : numpy.ndarray
        Reference position, velocity and acceleration at the hand-over, shape (3, 2), mm,
        mm/s, mm/s².
    command : numpy.ndarray
        Command of the previous controller to continue, V, shape (2,).
    gains : sequence of float
        ``k_s`` per axis, V/(mm/s) (`feedback_gain`), >= 0.

    Returns
    -------
    RBFAdaptive
        Same config and networks, new initial weights.

    Raises
    ------
    ValueError
        On non-finite inputs, or when ``z0`` lies so far from every centre that no
        weights of reasonable size can give the command (``max h < 1e-6``): fit the
        centres to a reference through the hand-over point.
    """
    ym = np.asarray(measured, dtype=float).reshape(N_AXES)
    ref = np.asarray(reference, dtype=float).reshape(3, N_AXES)
    u0 = np.asarray(command, dtype=float).reshape(N_AXES)
    ks = np.asarray(gains, dtype=float).reshape(N_AXES)
    for name, v in (("measured", ym), ("reference", ref), ("command", u0), ("gains", ks)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"handover {name} must be finite, got {v.tolist()}")
    if np.any(ks < 0):
        raise ValueError(f"handover gains k_s must be >= 0, got {ks.tolist()}")
    lam = rbf.config.lam
    nets = []
    for a, net in enumerate(rbf.networks):
        b = 1 - a
        # at rest: estimated velocities 0, so ė = −ṙ and v = λė − r̈ (seed 001 §3.2)
        edot = -ref[1, a]
        z0 = np.array(
            [ym[a], 0.0, ym[b], 0.0, lam * (ym[a] - ref[0, a]) + edot, lam * edot - ref[2, a]]
        )
        h = net.hidden(z0)
        if h.max() < 1e-6:
            raise ValueError(
                f"the {'xy'[a]} network is inactive at the hand-over point (max h = "
                f"{h.max():.1e}): fit its centres to a reference through that point"
            )
        zs = (z0[_S] - net.offset[_S]) / net.scale[_S]
        dh_ds = -h * (zs - net.centres[:, _S]) / net.widths**2 / net.scale[_S]
        w = np.linalg.lstsq(np.vstack([h, dh_ds]), np.array([u0[a], -ks[a]]), rcond=None)[0]
        nets.append(dataclasses.replace(net, weights=w))
    return RBFAdaptive(config=rbf.config, networks=nets, dt=rbf.dt)
