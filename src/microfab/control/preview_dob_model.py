"""Design half of `microfab.control.preview_dob`: settings, filters, linear model, check.

`PreviewDOBConfig` (seed 004 eqs. 3-4 gains from bandwidths, all assumed; refusals),
the packed parameter layout the kernels of `microfab.control.preview_dob` read, the
discretisation of the filters (ZOH ``Q`` on the current, Tustin ``Q s²`` on the
position, the velocity estimator and its matched low-pass; reasons in
`microfab.control.preview_dob`), one axis as a `DiscreteLTI` (`axis_model`) and the
poles of its nominal closed loop (`nominal_closed_loop_poles`, python-control), by which
a config is checked.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

import control
from microfab.control.velocity import VelocityEstimator
from microfab.core.validate import check_nonnegative, check_positive
from microfab.plants.friction import N_FRICTION, StageFriction
from microfab.plants.lti import DiscreteLTI, discretize

__all__ = ["PreviewDOBConfig", "axis_model", "check_stable", "nominal_closed_loop_poles"]

_HEAD = 2  # n_axes, spare
_NF = 11  # a 2-state filter in the layout of VelocityEstimator.discrete
# per-axis parameter block: M/K, K, K_a, K_v, K_p, dob, match, spare, then four filters,
# then the friction feedforward: on, scale / K_fn (1/(N/A)), the friction law's block
_P_EST, _P_REF, _P_F, _P_Q = 8, 8 + _NF, 8 + 2 * _NF, 8 + 3 * _NF
_P_FF = 8 + 4 * _NF
_NB = _P_FF + 2 + N_FRICTION
# per-axis state block: estimator(3), reference filter(3), Q s² filter(3), Q(2), logs,
# then the feedforward's bristle deflection z (m) and its last current i_ff (A)
_S_EST, _S_REF, _S_F, _S_Q = 0, 3, 6, 9
_S_DHAT, _S_V, _S_VREF, _S_F_OUT, _S_ACC = 11, 12, 13, 14, 15
_S_Z, _S_IFF = 16, 17
_NS = 18


def _check_axes_tuple(name: str, values: Sequence[float], unit: str) -> tuple[float, ...]:
    try:
        vals = tuple(values)
    except TypeError:
        raise ValueError(
            f"{name} must be a tuple with one value per axis, got {values!r}"
        ) from None
    if not vals:
        raise ValueError(f"{name} must hold at least one value (one per axis), got none")
    return tuple(check_positive(f"{name}[{i}]", v, unit) for i, v in enumerate(vals))


@dataclass(frozen=True, kw_only=True)
class PreviewDOBConfig:
    """Settings of `PreviewDOB` (seed 004 eqs. 3-4), validated.

    Parameters
    ----------
    mass_kg : tuple of float
        Nominal mass ``M_n`` per axis, kg (seed 004 eq. 2; the plant's, e.g. 1.2 kg for x
        carrying y, 0.6 kg for y, seed 004 Table I).
    force_constant_n_per_a : tuple of float
        Motor force constant ``K_fn`` per axis, N/A (seed 004 eq. 2; no value in the seed).
    dt : float
        Sample time, s (assumed 100 µs: the seed's dSPACE rate is not given).
    bandwidth_hz : float
        ``ω_c / 2π`` of ``K_p = ω_c²``, ``K_v = 2 ζ ω_c``, Hz (assumed 50 Hz: with the
        other defaults the nominal loop at the plant input keeps 17 dB / 55°, and 9 dB /
        35° with a 50 µs amplifier lag and the contour compensator's default gains added;
        100 Hz leaves the latter at 4 dB / 20°).
    damping : float
        ζ of the position loop (assumed 1: no overshoot of the error dynamics).
    dob_bandwidth_hz : float
        ``ω_q / 2π`` of ``Q``, Hz (assumed 500 Hz: ten times ω_c, a tenth of Nyquist);
        must lie below the Nyquist frequency ``1 / (2 dt)``.
    dob_damping : float
        ζ_q of ``Q`` (assumed 1: no overshoot of the estimate).
    k_a : float
        Acceleration feedforward gain ``K_a`` of eq. 3, >= 0 (seed: positive; 1 makes the
        feedforward exact for the nominal plant; 0 is allowed for the "K_a = 0" check).
    dob : bool
        Use the disturbance observer (eq. 4); False leaves ``i = (M_n/K_fn) ẍ_d``.
    match_velocity_filter : bool
        Pass ``ẋ_ref`` through the velocity estimator's low-pass (module docstring).
    estimator : VelocityEstimator
        Filtered differentiator for ``ẋ_fb`` (assumed 2 kHz, ζ = 1/√2: 40 ω_c, a fifth of
        the sample rate; 1 kHz costs 3 dB / 7° of the margins above).
    friction_ff : tuple of StageFriction
        Friction feedforward, one law per axis (`microfab.plants.friction`), or empty (the
        default: none, the seed's eqs. 3-4). Not in the seed: a model-based addition
        (`microfab.control.preview_dob`, "Friction feedforward").
    friction_ff_scale : float
        Multiplies the feedforward's force (the twins' ``disturbance_scale``), >= 0.

    Raises
    ------
    ValueError
        On a non-positive mass, force constant, bandwidth or damping, a negative ``k_a``,
        a DOB at or above the Nyquist frequency, or an unstable nominal closed loop; the
        message names the parameter, the value, its unit and the fix.
    """

    mass_kg: tuple[float, ...]
    force_constant_n_per_a: tuple[float, ...]
    dt: float = 1e-4  # assumed: 10 kHz
    bandwidth_hz: float = 50.0  # assumed, see Parameters
    damping: float = 1.0  # assumed
    dob_bandwidth_hz: float = 500.0  # assumed
    dob_damping: float = 1.0  # assumed
    k_a: float = 1.0  # assumed: exact feedforward for the nominal plant
    dob: bool = True
    match_velocity_filter: bool = True
    estimator: VelocityEstimator = field(
        default_factory=lambda: VelocityEstimator(bandwidth_hz=2000.0)  # assumed: 40 ω_c
    )
    friction_ff: tuple[StageFriction, ...] = ()
    friction_ff_scale: float = 1.0

    def __post_init__(self) -> None:
        m = _check_axes_tuple("mass_kg (nominal mass M_n)", self.mass_kg, "kg")
        k = _check_axes_tuple("force_constant_n_per_a (K_fn)", self.force_constant_n_per_a, "N/A")
        if len(m) != len(k):
            raise ValueError(
                f"mass_kg has {len(m)} axes but force_constant_n_per_a {len(k)}: give one "
                "value per axis in both"
            )
        object.__setattr__(self, "mass_kg", m)
        object.__setattr__(self, "force_constant_n_per_a", k)
        dt = check_positive("dt", self.dt, "s")
        nyq = 0.5 / dt
        check_positive("bandwidth_hz (ω_c/2π of K_p = ω_c², K_v = 2ζω_c)", self.bandwidth_hz, "Hz")
        if self.bandwidth_hz >= nyq:
            raise ValueError(
                f"bandwidth_hz must lie below the Nyquist frequency {nyq:g} Hz of dt = "
                f"{dt:g} s, got {self.bandwidth_hz:g} Hz; lower it"
            )
        check_positive("damping (ζ of the position loop)", self.damping)
        check_positive("dob_bandwidth_hz (ω_q/2π of Q)", self.dob_bandwidth_hz, "Hz")
        if self.dob_bandwidth_hz >= nyq:
            raise ValueError(
                f"dob_bandwidth_hz puts the DOB's poles at or above the Nyquist frequency "
                f"{nyq:g} Hz of dt = {dt:g} s: got {self.dob_bandwidth_hz:g} Hz; lower it "
                "(a few times bandwidth_hz, well below Nyquist)"
            )
        check_positive("dob_damping (ζ_q of Q)", self.dob_damping)
        check_nonnegative("k_a (K_a, acceleration feedforward gain)", self.k_a)
        for name in ("dob", "match_velocity_filter"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if not isinstance(self.estimator, VelocityEstimator):
            raise ValueError(
                f"estimator must be a VelocityEstimator, got {type(self.estimator).__name__}"
            )
        self.estimator.discrete(dt)  # refuses an estimator above Nyquist
        ff = tuple(self.friction_ff)
        if ff and len(ff) != len(m):
            raise ValueError(
                f"friction_ff has {len(ff)} laws for {len(m)} axes: give one per axis, or none"
            )
        for law in ff:
            if not isinstance(law, StageFriction):
                raise ValueError(
                    f"friction_ff must hold StageFriction laws, got {type(law).__name__}"
                )
        object.__setattr__(self, "friction_ff", ff)
        check_nonnegative("friction_ff_scale", self.friction_ff_scale)
        for a in range(len(m)):
            check_stable(self, a, self.k_p, self.k_v, "")

    @classmethod
    def pd_only(cls, **kwargs: Any) -> PreviewDOBConfig:
        """The "PD only" baseline: ``K_a = 0`` and no DOB (other settings as given)."""
        kwargs.setdefault("k_a", 0.0)
        kwargs.setdefault("dob", False)
        return cls(**kwargs)

    def with_(self, **changes: Any) -> PreviewDOBConfig:
        """A copy with some settings changed (validated again)."""
        return replace(self, **changes)

    @property
    def n_axes(self) -> int:
        """Number of axes."""
        return len(self.mass_kg)

    @property
    def k_p(self) -> float:
        """``K_p = ω_c²``, 1/s²."""
        return (2.0 * math.pi * self.bandwidth_hz) ** 2

    @property
    def k_v(self) -> float:
        """``K_v = 2 ζ ω_c``, 1/s."""
        return 2.0 * self.damping * 2.0 * math.pi * self.bandwidth_hz

    @property
    def g1(self) -> float:
        """``g1 = ω_q²`` of ``Q``, 1/s²."""
        return (2.0 * math.pi * self.dob_bandwidth_hz) ** 2

    @property
    def g2(self) -> float:
        """``g2 = 2 ζ_q ω_q`` of ``Q``, 1/s."""
        return 2.0 * self.dob_damping * 2.0 * math.pi * self.dob_bandwidth_hz


def _filter11(d: DiscreteLTI) -> np.ndarray:
    """A discrete 2-state SISO filter as ``[A(4), B(2), C(2), D, g(2)]`` (``g`` at rest)."""
    if d.n_states != 2:
        raise ValueError(f"expected a 2-state filter, got {d.n_states} states")
    g = np.linalg.solve(np.eye(2) - d.A, d.B[:, 0])
    return np.concatenate([d.A.ravel(), d.B[:, 0], d.C[0], d.D[0], g]).astype(np.float64)


@functools.cache
def _filters(
    dt: float, g1: float, g2: float, estimator: VelocityEstimator
) -> tuple[np.ndarray, ...]:
    """``(estimator, reference low-pass, Q s² (Tustin), Q (ZOH))`` in the 11-layout."""
    est = estimator.discrete(dt)
    w = 2.0 * math.pi * estimator.bandwidth_hz
    lp = control.tf([w * w], [1.0, 2.0 * estimator.damping * w, w * w])
    ref = _filter11(discretize(lp, dt, "tustin"))
    f = _filter11(discretize(control.tf([g1, 0.0, 0.0], [1.0, g2, g1]), dt, "tustin"))
    q = _filter11(discretize(control.tf([g1], [1.0, g2, g1]), dt, "zoh"))
    for arr in (est, ref, f, q):
        arr.setflags(write=False)
    return est, ref, f, q


def _axis_block(cfg: PreviewDOBConfig, a: int, k_p: float, k_v: float) -> np.ndarray:
    est, ref, f, q = _filters(cfg.dt, cfg.g1, cfg.g2, cfg.estimator)
    head = [
        cfg.mass_kg[a] / cfg.force_constant_n_per_a[a],
        cfg.force_constant_n_per_a[a],
        cfg.k_a,
        k_v,
        k_p,
        float(cfg.dob),
        float(cfg.match_velocity_filter),
        0.0,
    ]
    if cfg.friction_ff:
        ff = [
            1.0,
            cfg.friction_ff_scale / cfg.force_constant_n_per_a[a],
            *cfg.friction_ff[a].pack(),
        ]
    else:
        ff = [0.0] * (2 + N_FRICTION)
    return np.concatenate([head, est, ref, f, q, ff])


def _model_from_block(b: np.ndarray, dt: float) -> DiscreteLTI:
    """One axis's controller as a `DiscreteLTI`: ``[x_ref, ẋ_ref, ẍ_ref, x_fb] -> i``.

    States: estimator (2), reference low-pass (2), ``Q s²`` filter (2), ``Q`` (2); the
    arithmetic of `pdob_measure` and `pdob_command` from a state at rest.
    """
    mk, _k, ka, kv, kp, dob, match = b[:7]

    def parts(o: int) -> tuple[np.ndarray, ...]:
        f = b[o : o + _NF]
        return f[0:4].reshape(2, 2), f[4:6], f[6:8], f[8]

    Ae, Be, Ce, De = parts(_P_EST)
    Ar, Br, Cr, Dr = parts(_P_REF)
    Af, Bf, Cf, Df = parts(_P_F)
    Aq, Bq, Cq, _ = parts(_P_Q)
    A = np.zeros((8, 8))
    B = np.zeros((8, 4))
    # outputs before the command: v̂ = Ce se + De x_fb; v̄ = Cr sr + Dr ẋ_ref (or ẋ_ref)
    A[0:2, 0:2], B[0:2, 3] = Ae, Be
    if match:
        A[2:4, 2:4], B[2:4, 1] = Ar, Br
    A[4:6, 4:6], B[4:6, 3] = Af, Bf
    # i = C s + D u
    C = np.zeros((1, 8))
    D = np.zeros((1, 4))
    C[0, 0:2] = -mk * kv * Ce
    D[0, 3] = -mk * kv * De - mk * kp
    if match:
        C[0, 2:4] = mk * kv * Cr
        D[0, 1] = mk * kv * Dr
    else:
        D[0, 1] = mk * kv
    D[0, 0] = mk * kp
    D[0, 2] = mk * ka
    if dob:
        C[0, 4:6] = -mk * Cf
        D[0, 3] += -mk * Df
        C[0, 6:8] = Cq
        A[6:8, 6:8] = Aq
        A[6:8, :] += np.outer(Bq, C[0])
        B[6:8, :] = np.outer(Bq, D[0])
    return DiscreteLTI(A, B, C, D, dt, ("x_ref", "v_ref", "a_ref", "x_fb"), ("i",))


def axis_model(
    cfg: PreviewDOBConfig, axis: int, k_p: float | None = None, k_v: float | None = None
) -> DiscreteLTI:
    """The controller of one axis as a `DiscreteLTI` ``[x_ref, ẋ_ref, ẍ_ref, x_fb] -> i``.

    Parameters
    ----------
    cfg : PreviewDOBConfig
        The settings.
    axis : int
        Axis index.
    k_p, k_v : float, optional
        Position and velocity gains, 1/s² and 1/s, in place of the config's (the contour
        compensator checks the normal direction with its own gains added).

    Returns
    -------
    DiscreteLTI
        Inputs m, m/s, m/s², m; output A.
    """
    b = _axis_block(cfg, axis, cfg.k_p if k_p is None else k_p, cfg.k_v if k_v is None else k_v)
    return _model_from_block(b, cfg.dt)


def nominal_closed_loop_poles(
    cfg: PreviewDOBConfig, axis: int, k_p: float | None = None, k_v: float | None = None
) -> np.ndarray:
    """Poles of one axis's nominal closed loop (python-control).

    The plant is ``K_fn / (M_n s²)`` (current to position), ZOH at ``dt``; the controller
    is `axis_model`, its ``x_fb`` input fed back from the plant's output.

    Returns
    -------
    numpy.ndarray
        Complex discrete-time poles.
    """
    m, k = cfg.mass_kg[axis], cfg.force_constant_n_per_a[axis]
    plant = control.c2d(control.ss(control.tf([k], [m, 0.0, 0.0])), cfg.dt, method="zoh")
    c = axis_model(cfg, axis, k_p, k_v)
    ctrl = control.ss(c.A, c.B[:, 3:4], c.C, c.D[:, 3:4], cfg.dt)
    cl = control.feedback(plant, ctrl, sign=1)  # the controller carries its own minus sign
    return np.asarray(control.poles(cl))


def check_stable(cfg: PreviewDOBConfig, axis: int, k_p: float, k_v: float, what: str) -> None:
    """Refuse gains that leave axis ``axis``'s nominal closed loop unstable (`ValueError`)."""
    r = float(np.max(np.abs(nominal_closed_loop_poles(cfg, axis, k_p, k_v))))
    if not r < 1.0:
        raise ValueError(
            f"the nominal closed loop of axis {axis} (plant K_fn/(M_n s²), ZOH at dt = "
            f"{cfg.dt:g} s) is unstable{what}: largest pole magnitude {r:.6f} >= 1 with "
            f"bandwidth_hz = {cfg.bandwidth_hz:g} Hz, dob_bandwidth_hz = "
            f"{cfg.dob_bandwidth_hz:g} Hz, estimator {cfg.estimator.bandwidth_hz:g} Hz; "
            "lower the loop bandwidths or raise the estimator bandwidth"
        )
