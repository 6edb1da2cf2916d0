"""Task-space contour error compensator on top of the axis controllers (seed 004 eqs. 5-15).

Seed 004 describes the task as a constraint ``φ(x, y) = 0`` (the contour, eq. 5) and a
tangential velocity ``v(t)`` (eq. 6); at the reference point, ``J = [∇φᵀ; ∇φ⊥ᵀ]`` (eqs. 7,
14, gradient normalised) maps the stage velocity to the normal and tangential velocities
(eq. 13, ``J v = [0, v(t)]``) and its derivative maps accelerations (eq. 15,
``J a + J̇ v``). Two misprints of the seed, read as follows: eq. 15 says "taking the
derivative of (15)" for the derivative of (13), whose right-hand side is then
``[0, v̇(t)]`` (the seed writes ``[0, v(t)]``); its ``[j̇]`` is ``J̇``. The seed stops at "the
design of the controller is fairly simple after this point"; our law:

**Geometry from the reference.** The rows of the reference window carry ``r = (x, y)``,
``ṙ`` and ``r̈``; for a time-parametrised path the unit tangent, normal and signed
curvature follow exactly from them:

``t = ṙ / |ṙ|``,  ``n = t`` rotated by +90°,  ``κ = (ẋ ÿ − ẏ ẍ) / |ṙ|³``,

so ``J = [nᵀ; tᵀ]`` (orthonormal: ``J⁻¹ = Jᵀ``) and ``ṅ = −κ |ṙ| t``, ``ṫ = κ |ṙ| n``.

**Contour error.** ``ε = nᵀ (p − p_d)`` (``p`` measured, ``p_d`` reference): the normal
component of the tracking error, the first-order contour error at the reference point.
Its derivative is exact for the moving frame,

``ε̇ = nᵀ (v − ṙ) + κ |ṙ| tᵀ (p_d − p)``,

with ``v − ṙ`` the filtered velocity error of the axis controllers (the estimated
velocity against the reference velocity through the same low-pass,
`microfab.control.preview_dob`).

**Correction.** Eq. 15 solved for the acceleration is ``a = J⁻¹ (a* − J̇ v)``, with
``a* = [a*_n, a*_t]`` the accelerations that enforce the two rows of eq. 13. With ``v =
ṙ`` and ``a* = [0, v̇]`` this is the reference acceleration ``r̈`` itself (the normal
acceleration the path needs, ``κ |ṙ|² n``, is ``−J⁻¹ J̇ ṙ``), which the axis controllers
already apply through ``K_a ẍ_ref`` (eq. 3). What remains, added to ``ẍ_d`` of eq. 3
before eq. 4 turns it into current, is

``Δa = n a*_n + t a*_t − J⁻¹ J̇ (v − ṙ)``,

* row 1 of eq. 13 (``v_φ = 0``, on the contour): ``a*_n = −k_vc ε̇ − k_pc ε``;
* row 2 (``v_φ⊥ = v(t)``, the tangential speed): ``a*_t = −k_vt e_vt`` with ``e_vt =
  tᵀ(v − ṙ) = v_φ⊥ − v(t)`` (a speed requirement: no tangential position term);
* ``−J⁻¹ J̇ (v − ṙ) = κ|ṙ| (n tᵀ − t nᵀ)(v − ṙ)``: the part of eq. 15's ``J̇ v`` that the
  reference does not hold, with ``v − ṙ`` the filtered velocity error. It is first order
  in the error with the path's turn rate ``Ω = κ|ṙ|`` as gain: in the path frame it
  cancels the ``−Ω² e`` that the frame's rotation adds to the error's acceleration.

The two rows and the ``J̇`` term matter when the path turns at a rate near the axis
loop's bandwidth (``Ω`` against ``ω_c``, `microfab.experiments.seed004_laser.fig7`): the
axis loops' position gain then nearly cancels against ``Ω²`` in the path frame and the
normal and tangential errors are held together by ``K_v Ω``; a normal-only correction
moves the error into the tangential direction, whence it returns (the 30 µm circle at
10 mm/s: 333 against 314 rad/s, 1112 → 1253 nm normal-only; 1112 → 249 nm with both rows
and the ``J̇`` term). ``tangential=False`` and ``rotation=False`` leave them out (the
normal-only law, for that comparison).

Under exact tracking ``ε``, ``ε̇`` and ``v − ṙ`` vanish and so does the correction (up
to the velocity filters' discretisation: on a sampled circle the Tustin differentiator
reads the speed ``(ωT)²/12`` high, which the tangential row sees).

**At rest and at corners** the tangent is undefined. The correction is weighted by
``w``: its target is 0 below ``min_speed_m_s``, 1 above twice it, a smoothstep between,
and ``w`` follows the target down at once but rises at most ``dt / fade_in_s`` a sample.
A path that stops at a corner (the constant-speed planner stops there) drops the
correction as it comes to rest (the errors of the old direction, which the correction
has kept small, are all it acted on), turns its normal while at rest, and
takes the correction in along the new normal over ``fade_in_s`` on the way out, even
when the reference leaves the speed band within a sample (1 m/s² does): the errors that
the stop left along the new normal (the old direction's settling) are not kicked at
once. The axis controllers hold both directions throughout. A path that turns at speed
is a curve of high curvature, handled as any curve.

Gains (assumed; the seed gives none): ``k_pc = ω_cc²``, ``k_vc = 2 ζ_c ω_cc`` with
``ω_cc / 2π`` = 100 Hz (twice the axis loop's default) and ``ζ_c`` = 1; ``k_vt = k_vc``
(assumed: the same speed gain along the path as across it); ``fade_in_s`` = 2 ms (a fifth
of the contour loop's period). A config is refused when the axis loop with the normal
gains added (``K_p + k_pc``, ``K_v + k_vc``: a normal along an axis) or with the
tangential one (``K_v + k_vt``: a tangent along an axis) is unstable on the nominal plant
(the ``J̇`` term's gain ``Ω`` varies along the path and is not in that check).

`ContourCompensator` wraps a `microfab.control.preview_dob.PreviewDOB` (composition):
its kernel calls the inner controller's two halves (`pdob_measure`, `pdob_command`)
with the correction in between. The inner kernel is always the PreviewDOB's, so it is
called directly rather than bound per inner kernel as `microfab.control.repetitive`
must for any inner controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import ReferenceWindow
from microfab.control.preview_dob import (
    PreviewDOBAddOn,
    PreviewDOBConfig,
    check_stable,
    pdob_command,
    pdob_measure,
)
from microfab.control.preview_dob_model import _NS
from microfab.control.preview_dob_model import _S_V as _S_V_IN
from microfab.control.preview_dob_model import _S_VREF as _S_VREF_IN
from microfab.core.validate import check_positive

__all__ = [
    "ContourCompensator",
    "ContourConfig",
    "contour_step",
    "path_frame",
    "speed_weight",
]

# offsets in the inner controller's state (see PreviewDOB): v̂ and filtered ẋ_ref per axis
_NS_IN, _S_V, _S_VREF = _NS, _S_V_IN, _S_VREF_IN
_HDR = 6  # k_pc, k_vc, min speed, dt / fade-in time, k_vt, J̇ term on
_XS = 6  # state: Δa (2), ε, ε̇, w, spare


@dataclass(frozen=True, kw_only=True)
class ContourConfig:
    """Settings of the contour compensator (seed 004 eqs. 5-15), validated.

    Parameters
    ----------
    inner : PreviewDOBConfig
        The two axis controllers (x, y) the correction sits on.
    bandwidth_hz : float
        ``ω_cc / 2π`` of ``k_pc = ω_cc²``, ``k_vc = 2 ζ_c ω_cc``, Hz (assumed 100 Hz:
        twice the axis loop's default).
    damping : float
        ``ζ_c`` (assumed 1).
    min_speed_m_s : float
        Reference speed below which the correction is off, m/s; full above twice it
        (assumed 0.1 mm/s: a hundredth of the seed's 10 mm/s, Fig. 7).
    fade_in_s : float
        Shortest time over which the correction's weight rises from 0 to 1, s (assumed
        2 ms); at least one sample.
    tangential : bool
        Enforce row 2 of eq. 13 (the tangential speed, gain ``k_vt = k_vc``); default on.
    rotation : bool
        Apply the ``J̇ (v − ṙ)`` part of eq. 15; default on.

    Raises
    ------
    ValueError
        On an inner config without two axes, non-positive gains or speed, or an axis
        loop that is unstable with the normal gains added.
    """

    inner: PreviewDOBConfig
    bandwidth_hz: float = 100.0  # assumed
    damping: float = 1.0  # assumed
    min_speed_m_s: float = 1e-4  # assumed
    fade_in_s: float = 2e-3  # assumed
    tangential: bool = True  # seed 004 eq. 13, row 2
    rotation: bool = True  # seed 004 eq. 15, J̇ v

    def __post_init__(self) -> None:
        check_addon_config(self, "contour compensator", "contour loop")
        check_positive("fade_in_s", self.fade_in_s, "s")
        if self.fade_in_s < self.inner.dt:
            raise ValueError(
                f"fade_in_s must be at least one sample (dt = {self.inner.dt:g} s), got "
                f"{self.fade_in_s:g} s; raise it"
            )
        for name in ("tangential", "rotation"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        check_normal_gains(self.inner, self.k_pc, self.k_vc, "contour compensator")
        if self.tangential:
            check_normal_gains(self.inner, 0.0, self.k_vt, "contour compensator's tangential row")

    @property
    def k_pc(self) -> float:
        """``k_pc = ω_cc²``, 1/s²."""
        return (2.0 * math.pi * self.bandwidth_hz) ** 2

    @property
    def k_vc(self) -> float:
        """``k_vc = 2 ζ_c ω_cc``, 1/s."""
        return 2.0 * self.damping * 2.0 * math.pi * self.bandwidth_hz

    @property
    def k_vt(self) -> float:
        """``k_vt`` of the tangential row, 1/s (``k_vc``; 0 with ``tangential`` off)."""
        return self.k_vc if self.tangential else 0.0


def check_addon_config(cfg: Any, what: str, loop: str) -> None:
    """The checks a `PreviewDOBAddOn` config shares: two inner axes, positive gains.

    ``cfg`` has ``inner``, ``bandwidth_hz``, ``damping`` and ``min_speed_m_s``; ``what``
    names the controller and ``loop`` its loop in the messages.
    """
    if not isinstance(cfg.inner, PreviewDOBConfig):
        raise ValueError(f"inner must be a PreviewDOBConfig, got {type(cfg.inner).__name__}")
    if cfg.inner.n_axes != 2:
        raise ValueError(
            f"the {what} works on two axes (x, y); the inner config has {cfg.inner.n_axes}"
        )
    check_positive(f"bandwidth_hz (ω_cc/2π of the {loop})", cfg.bandwidth_hz, "Hz")
    check_positive(f"damping (ζ_c of the {loop})", cfg.damping)
    check_positive("min_speed_m_s", cfg.min_speed_m_s, "m/s")


def check_normal_gains(inner: PreviewDOBConfig, k_p: float, k_v: float, what: str) -> None:
    """Refuse normal gains that make an axis loop unstable (normal along that axis).

    Raises
    ------
    ValueError
        Naming the gains and the fix.
    """
    for a in range(inner.n_axes):
        try:
            check_stable(inner, a, inner.k_p + k_p, inner.k_v + k_v, f" with the {what}")
        except ValueError as err:
            raise ValueError(
                f"{err}; the {what} adds {k_p:.4g} 1/s² and {k_v:.4g} 1/s in the normal "
                "direction: lower its bandwidth_hz"
            ) from None


@njit(cache=True, inline="always")
def speed_weight(speed: float, v_min: float) -> float:
    """Weight of the correction: 0 below ``v_min``, 1 above ``2 v_min``, smoothstep between."""
    s = (speed - v_min) / v_min
    if s <= 0.0:
        return 0.0
    if s >= 1.0:
        return 1.0
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True, inline="always")
def path_frame(vx: float, vy: float, ax: float, ay: float) -> tuple[float, float, float, float]:
    """``(speed, t_x, t_y, κ|ṙ|)`` from the reference velocity and acceleration.

    ``κ|ṙ| = (ẋÿ − ẏẍ)/|ṙ|²`` (1/s); the caller checks that the speed is not zero.
    """
    sp2 = vx * vx + vy * vy
    sp = math.sqrt(sp2)
    return sp, vx / sp, vy / sp, (vx * ay - vy * ax) / sp2


@njit(cache=True)
def contour_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """Kernel of `ContourCompensator`: inner measure, normal correction, inner command."""
    pin = p[_HDR:]
    xin = x[_XS:]
    r = ref[k]
    pdob_measure(pin, xin, r, ym)
    vx = r[1, 0]
    vy = r[1, 1]
    w = min(speed_weight(math.sqrt(vx * vx + vy * vy), p[2]), x[4] + p[3])
    eps = 0.0
    epsd = 0.0
    x[0] = 0.0
    x[1] = 0.0
    if w > 0.0:
        _sp, tx, ty, ks = path_frame(vx, vy, r[2, 0], r[2, 1])
        nx = -ty
        ny = tx
        ex = r[0, 0] - ym[0]
        ey = r[0, 1] - ym[1]
        evx = xin[_S_VREF] - xin[_S_V]
        evy = xin[_NS_IN + _S_VREF] - xin[_NS_IN + _S_V]
        eps = -(nx * ex + ny * ey)
        evn = -(nx * evx + ny * evy)  # nᵀ(v − ṙ)
        evt = -(tx * evx + ty * evy)  # tᵀ(v − ṙ) = v_φ⊥ − v(t)
        epsd = evn + ks * (tx * ex + ty * ey)
        an = -p[1] * epsd - p[0] * eps + p[5] * ks * evt
        at = -p[4] * evt - p[5] * ks * evn
        x[0] = w * (an * nx + at * tx)
        x[1] = w * (an * ny + at * ty)
    x[2] = eps
    x[3] = epsd
    x[4] = w
    pdob_command(pin, xin, r, ym, x[0:2], u)


class ContourCompensator(PreviewDOBAddOn):
    """`PreviewDOB` on both axes plus the normal contour correction (module docstring).

    Parameters
    ----------
    config : ContourConfig
        Inner controllers and contour gains.

    Notes
    -----
    ``params = [k_pc, k_vc, min speed, dt / fade_in_s, k_vt, J̇ on, inner params]``;
    state ``[Δa_x,
    Δa_y (m/s²), ε (m), ε̇ (m/s), w, 0, inner state]`` (the correction terms of the last
    sample).
    Measurement ``(x, y)`` m, command ``(i_x, i_y)`` A; the reference window must carry
    velocity and acceleration.
    """

    kernel_step: Any = contour_step

    head_states = _XS
    name = "contour compensator"

    def __init__(self, config: ContourConfig) -> None:
        if not isinstance(config, ContourConfig):
            raise TypeError(f"config must be a ContourConfig, got {type(config).__name__}")
        self.config = config
        self._setup(
            config.inner,
            [
                config.k_pc,
                config.k_vc,
                config.min_speed_m_s,
                config.inner.dt / config.fade_in_s,
                config.k_vt,
                float(config.rotation),
            ],
        )

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference of the kernel); ``state`` is not modified."""
        x, ym, xin = self._begin(state, window, measurement)
        cfg = self.config
        vx, vy = float(window.velocity[0, 0]), float(window.velocity[0, 1])
        ax, ay = float(window.acceleration[0, 0]), float(window.acceleration[0, 1])
        sp = math.sqrt(vx * vx + vy * vy)
        s = (sp - cfg.min_speed_m_s) / cfg.min_speed_m_s
        target = 0.0 if s <= 0.0 else 1.0 if s >= 1.0 else s * s * (3.0 - 2.0 * s)
        w = min(target, x[4] + self.params[3])
        eps = epsd = 0.0
        da = np.zeros(2)
        if w > 0.0:
            sp2 = vx * vx + vy * vy
            tx, ty = vx / sp, vy / sp
            ks = (vx * ay - vy * ax) / sp2
            nx, ny = -ty, tx
            ex = float(window.position[0, 0]) - float(ym[0])
            ey = float(window.position[0, 1]) - float(ym[1])
            evx = xin[_S_VREF] - xin[_S_V]
            evy = xin[_NS_IN + _S_VREF] - xin[_NS_IN + _S_V]
            eps = -(nx * ex + ny * ey)
            evn = -(nx * evx + ny * evy)
            evt = -(tx * evx + ty * evy)
            epsd = evn + ks * (tx * ex + ty * ey)
            pr = self.params
            an = -pr[1] * epsd - pr[0] * eps + pr[5] * ks * evt
            at = -pr[4] * evt - pr[5] * ks * evn
            da[:] = (w * (an * nx + at * tx), w * (an * ny + at * ty))
        x[0:2] = da
        x[2], x[3], x[4] = eps, epsd, w
        u = self.inner.command(xin, window, ym, da)
        return u, x

    def contour_error(self, state: np.ndarray) -> float:
        """``ε`` of the last sample, m (0 where the correction was off)."""
        return float(np.asarray(state)[2])

    def correction(self, state: np.ndarray) -> np.ndarray:
        """``Δa`` added to ``ẍ_d`` at the last sample, m/s², shape (2,)."""
        return np.array(np.asarray(state)[0:2])
