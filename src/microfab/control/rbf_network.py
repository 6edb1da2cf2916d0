"""The RBF networks of seed 001 §3.2: settings, one axis's network, the default design rule.

`RBFConfig` holds the tunable settings of `microfab.control.rbf.RBFAdaptive` (seed 001
eqs. 2-5: ``l``, λ, Γ, σ, ε, the width rule, Ŵ(0), the velocity estimator); `RBFNetwork`
one axis's scaling of the input ``z = (x1, x2, x̄1, x̄2, s, v)``, Gaussian centres
``c_j``, widths ``b_j`` (eq. 2) and initial weights; `networks_for_reference` the
default design of both axes' networks from a reference (the rule of
`RBFAdaptive.for_reference`).

Scaling (ours): each component of ``z`` is shifted and divided by a scale,
``z̃_i = (z_i − o_i) / g_i``, so that one width rule fits all six; the centres and widths
live in these scaled units.

Defaults (assumed; the seed gives no λ, Γ, σ, ε, l, centres, widths or Ŵ(0)) were chosen
on the eq. 9 model (10 kHz, a 0.15 mm circle at 1 Hz, noise off): λ = 100/s,
Γ = 0.05 V/mm, width factor 2, centres spread ±1 in scaled ``s``, l = 25, σ = 1e-3,
Ŵ(0) = 0 give 0.8 µm RMS from the second period on; Γ = 0.2 (or λ = 300 with Γ = 0.1)
sets off a bounded oscillation of ~0.2 mm, so Γ keeps a factor of ~4 from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from microfab.control.velocity import VelocityEstimator
from microfab.core.validate import check_finite, check_int, check_nonnegative, check_positive

__all__ = ["N_AXES", "N_Z", "RBFConfig", "RBFNetwork", "networks_for_reference"]

N_Z = 6  # z = (x1, x2, x̄1, x̄2, s, v), seed 001 §3.2
N_AXES = 2


@dataclass(frozen=True, kw_only=True)
class RBFConfig:
    """Tunable settings of the RBF adaptive controller (both axes).

    Parameters
    ----------
    n_nodes : int
        Hidden nodes per axis, ``l`` of seed 001 eq. 2 (default 25, the issue's
        benchmark size; the seed gives none).
    lam : float
        λ of ``s = λe + ė``, 1/s (seed: λ > 0, no value; default 100/s assumed).
    gamma : float or tuple of float
        Adaptive gain Γ of eq. 5, scalar or its diagonal (one per node), V/mm
        (``dŴ/dt = −Γ h s`` with ``s`` in mm/s and ``Ŵ`` in V): > 0.
    sigma : float
        Leakage σ of eq. 5, mm/(V·s) (an unexcited weight decays at the rate ``Γσ``,
        1/s): > 0.
    eps : float
        ε of eq. 6, s (used by `microfab.control.certainty`): under the oracle law
        ``ṡ ≈ −s/ε``.
    width_factor : float
        Width rule of `RBFAdaptive.for_reference`: ``b_j`` = this times the mean distance
        from ``c_j`` to its two neighbouring centres (scaled units).
    s_spread : float
        Centres alternate between ``+s_spread`` and ``−s_spread`` in scaled ``s`` (so
        the network can make a command odd in ``s``, a feedback), >= 0.
    w0 : float
        Initial weight of every node, V (seed: Ŵ(0) not given; default 0).
    estimator : VelocityEstimator
        Velocity estimator on the measured positions.
    """

    n_nodes: int = 25
    lam: float = 100.0  # assumed: see the module docstring
    gamma: float | tuple[float, ...] = 0.05  # assumed
    sigma: float = 1e-3  # assumed
    eps: float = 2e-3  # assumed
    width_factor: float = 2.0  # assumed
    s_spread: float = 1.0  # assumed
    w0: float = 0.0  # assumed: the seed gives no Ŵ(0)
    estimator: VelocityEstimator = field(default_factory=VelocityEstimator)

    def __post_init__(self) -> None:
        check_int("n_nodes", self.n_nodes, 1, "nodes")
        check_positive("lam (λ of s = λe + ė)", self.lam, "1/s")
        if isinstance(self.gamma, tuple | list | np.ndarray):
            g = tuple(float(v) for v in self.gamma)
            if len(g) != self.n_nodes:
                raise ValueError(
                    f"gamma (Γ diagonal) must have n_nodes = {self.n_nodes} entries, got "
                    f"{len(g)}; give one per node or a scalar"
                )
            for j, v in enumerate(g):
                check_positive(f"gamma[{j}] (Γ)", v, "V/mm")
            object.__setattr__(self, "gamma", g)
        else:
            check_positive("gamma (Γ)", self.gamma, "V/mm")
        check_positive("sigma (σ)", self.sigma, "mm/(V·s)")
        check_positive("eps (ε)", self.eps, "s")
        check_positive("width_factor", self.width_factor, "")
        check_nonnegative("s_spread", self.s_spread, "(scaled s)")
        check_finite("w0 (initial weight)", self.w0, "V")
        if not isinstance(self.estimator, VelocityEstimator):
            raise ValueError(
                f"estimator must be a VelocityEstimator, got {type(self.estimator).__name__}"
            )

    def gamma_diagonal(self) -> np.ndarray:
        """Γ as its diagonal, shape (n_nodes,)."""
        g = self.gamma
        return np.array(g, float) if isinstance(g, tuple) else np.full(self.n_nodes, float(g))


def _array(name: str, value: Any, shape: tuple[int, ...], unit: str) -> np.ndarray:
    """``value`` as a finite float64 array of ``shape`` (``-1`` free), else ValueError."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers in {unit}, got {value!r}") from None
    if a.ndim != len(shape) or any(s not in (-1, t) for s, t in zip(shape, a.shape, strict=True)):
        dims = ["n" if s == -1 else str(s) for s in shape]
        want = "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"
        raise ValueError(f"{name} must be shaped {want}, got {a.shape}; fix its dimension")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} holds NaN or inf ({unit}); give finite values")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True, eq=False)
class RBFNetwork:
    """One axis's network: scaling of ``z``, centres, widths, initial weights.

    Parameters
    ----------
    offset, scale : numpy.ndarray
        ``z̃ = (z − offset) / scale``, shape (6,) each, in the units of ``z``
        ``(mm, mm/s, mm, mm/s, mm/s, mm/s²)``; scale > 0.
    centres : numpy.ndarray
        ``c_j`` in scaled units, shape (l, 6).
    widths : numpy.ndarray
        ``b_j`` in scaled units, shape (l,), > 0.
    weights : numpy.ndarray
        ``Ŵ(0)``, V, shape (l,).
    """

    offset: np.ndarray
    scale: np.ndarray
    centres: np.ndarray
    widths: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset", _array("offset", self.offset, (N_Z,), "units of z"))
        scale = _array("scale", self.scale, (N_Z,), "units of z")
        if np.any(scale <= 0):
            raise ValueError(f"scale must be positive in every component, got {scale.tolist()}")
        object.__setattr__(self, "scale", scale)
        c = _array("centres", self.centres, (-1, N_Z), "scaled units")
        if c.shape[0] < 1:
            raise ValueError("centres must hold at least one node (shape (l >= 1, 6))")
        object.__setattr__(self, "centres", c)
        b = _array("widths (b_j)", self.widths, (c.shape[0],), "scaled units")
        if np.any(b <= 0):
            j = int(np.argmin(b))
            raise ValueError(
                f"widths b_j must be positive (seed 001 eq. 2), got b[{j}] = {b[j]:g}; "
                "give positive widths"
            )
        object.__setattr__(self, "widths", b)
        object.__setattr__(self, "weights", _array("weights", self.weights, (c.shape[0],), "V"))

    @property
    def n_nodes(self) -> int:
        """Number of nodes ``l``."""
        return int(self.centres.shape[0])

    def hidden(self, z: np.ndarray) -> np.ndarray:
        """``h(z)`` for unscaled inputs ``z``, shape (..., 6) -> (..., l)."""
        zs = (np.asarray(z, float) - self.offset) / self.scale
        d2 = ((zs[..., None, :] - self.centres) ** 2).sum(axis=-1)
        return np.exp(-d2 / (2.0 * self.widths**2))


def _stack_reference(
    reference: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray, n: int
) -> np.ndarray:
    """Reference as the loops stack it, shape (n, 3, 2), checked."""
    out = np.empty((n, 3, N_AXES))
    for d, (name, arr) in enumerate(
        (("reference", reference), ("velocity", velocity), ("acceleration", acceleration))
    ):
        a = np.asarray(arr, dtype=float)
        if a.shape != (n, N_AXES):
            raise ValueError(f"{name} must be shaped ({n}, 2) like the measurements, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} holds NaN or inf")
        out[:, d] = a
    return out


def networks_for_reference(
    position: np.ndarray,
    velocity: np.ndarray,
    acceleration: np.ndarray,
    config: RBFConfig | None = None,
    *,
    closed: bool = True,
) -> tuple[RBFNetwork, RBFNetwork]:
    """The x and y networks with centres, widths and scaling from a reference (default rule).

    Rule (ours; the seed gives no centres, widths or scaling): for axis ``a`` (other
    axis ``b``) the reference's own ``z`` is ``z_r = (r_a, ṙ_a, r_b, ṙ_b, 0, −r̈_a)``
    (on the reference ``s = 0`` and ``v = −r̈``).

    * Scaling: ``offset`` is the mid-range of each component over the reference.
      Every scale is the deviation that moves ``s`` as much as a position error of
      the axis's half-range ``A`` would (with ``V`` the velocity half-range):
      positions ``A`` (the other axis: its own), velocities and ``s`` ``λA + V``,
      ``v`` ``λ(λA + V)`` plus the half-range of ``r̈``. The velocities so weigh
      little against the positions (a stage at rest on the contour is near the
      centres, and the network is active from the start), and the network stays
      active over errors as large as the motion. A scale that comes out 0 (an axis
      at rest) is set to 1 (mm, mm/s, mm/s²).
    * Centres: ``z_r`` at ``l`` samples equally spaced in time over the given
      reference (pass one period of a closed contour), scaled; their ``s``
      component alternates ``±s_spread`` (centres all at ``s = 0`` make every
      ``h_j`` even in ``s``, and the network could then give no feedback: on eq. 9
      it never left the start).
    * Widths: ``b_j`` = ``width_factor`` times the mean distance from ``c_j`` to its
      two neighbours (the last and first are neighbours when ``closed``); a width
      that comes out 0 (repeated centres) takes the largest other width, or 1.
    * Weights: ``Ŵ(0) = w0`` for every node.

    With ``s_spread > 0`` the alternation enters the gap between neighbours (``2 s_spread``
    in scaled ``s``) and dominates it: on seed 001's 0.15 mm circle the widths come out
    ~3.9 scaled units against an orbit of diameter 2, every ``h_j`` stays within
    [0.61, 0.97] along the circle, and the network acts as one constant basis function
    whose adaptive law is an integrator on ``s`` (no memory of the phase, no learning from
    period to period: `microfab.experiments.seed001_nanomanipulator.study`). With
    ``s_spread = 0`` the widths follow the spacing along the orbit (~0.5); the network
    then needs a linear feedback beside it (`microfab.control.rbf_composite`).

    Parameters
    ----------
    position, velocity, acceleration : numpy.ndarray
        Reference, shape (n >= l, 2), mm, mm/s, mm/s².
    config : RBFConfig, optional
        Settings (default `RBFConfig()`).
    closed : bool
        Whether the reference is one period of a closed (repeated) contour.

    Returns
    -------
    tuple of RBFNetwork
        The x and y networks.
    """
    cfg = RBFConfig() if config is None else config
    if not isinstance(cfg, RBFConfig):
        raise ValueError(f"config must be an RBFConfig, got {type(cfg).__name__}")
    nl = cfg.n_nodes
    P = np.asarray(position, dtype=float)
    n = P.shape[0] if P.ndim == 2 else 0
    R = _stack_reference(P, velocity, acceleration, n)
    if n < nl:
        raise ValueError(f"the reference has {n} samples, fewer than n_nodes = {nl}")
    nets = []
    idx = (np.arange(nl) * n) // nl
    for a in range(N_AXES):
        b = 1 - a
        zr = np.column_stack(
            [R[:, 0, a], R[:, 1, a], R[:, 0, b], R[:, 1, b], np.zeros(n), -R[:, 2, a]]
        )
        lo, hi = zr.min(axis=0), zr.max(axis=0)
        offset = 0.5 * (lo + hi)
        scale = 0.5 * (hi - lo)
        sref = cfg.lam * scale[0] + scale[1]
        sref_b = cfg.lam * scale[2] + scale[3]
        scale[1], scale[3], scale[4] = sref, sref_b, sref
        scale[5] = cfg.lam * sref + scale[5]
        scale[scale <= 1e-12 * max(1.0, float(np.max(np.abs(zr))))] = 1.0
        c = (zr[idx] - offset) / scale
        c[:, 4] = cfg.s_spread * np.where(np.arange(nl) % 2 == 0, 1.0, -1.0)
        d = np.linalg.norm(np.diff(c, axis=0), axis=1)
        gap = np.linalg.norm(c[0] - c[-1]) if closed else (d[-1] if d.size else 0.0)
        nxt = np.append(d, gap)
        prv = np.insert(d, 0, gap if closed else (d[0] if d.size else 0.0))
        width = cfg.width_factor * 0.5 * (nxt + prv)
        if np.all(width <= 0):
            width[:] = 1.0
        width[width <= 0] = width.max()
        nets.append(
            RBFNetwork(
                offset=offset,
                scale=scale,
                centres=c,
                widths=width,
                weights=np.full(nl, cfg.w0),
            )
        )
    return nets[0], nets[1]
