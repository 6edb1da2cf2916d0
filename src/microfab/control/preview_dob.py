"""Preview controller with disturbance observer, per axis (seed 004 §III-A, eqs. 2-4).

Plant of each axis (seed 004 eq. 2): ``M_n ẍ + F_l(x, ẋ, t) = K_fn i``, command ``i`` the
current reference (A), measurement the encoder position ``x_fb`` (m).

Law (per axis, both axes alike):

* desired acceleration, seed 004 eq. (3)::

      ẍ_d = K_a ẍ_ref + K_v (ẋ_ref − ẋ_fb) + K_p (x_ref − x_fb)

* current, seed 004 eq. (4) written as a disturbance observer (DOB)::

      î_d = Q(s) i − (M_n/K_fn) Q(s) s² x_fb,      Q(s) = g1 / (s² + g2 s + g1)
      i   = (M_n/K_fn) ẍ_d + î_d

  ``K_fn î_d`` estimates the load force ``F_l`` of eq. 2 (N, the force the motor must
  overcome): with the nominal plant, ``î_d = Q F_l / K_fn``. ``i`` stands on both sides of
  eq. 4; ``Q`` is strictly proper, so the estimate at sample ``k`` uses the currents up to
  ``k − 1`` only and the loop is not algebraic.

Discretisation at the sample time ``dt`` (python-control ``c2d``):

* ``Q`` acting on ``i``: **ZOH**. The current reference is held over the sample by the
  DAC, so the ZOH equivalent is exact for it, and it stays strictly proper.
* ``Q s²`` acting on ``x_fb`` (the encoder is never differentiated twice: ``Q s²`` is
  biproper, ``g1 s² / (s² + g2 s + g1)``): **Tustin**. Of ZOH, FOH and Tustin it is the
  one that keeps the DOB identity of the nominal ZOH plant best:
  ``|Q_zoh − (M_n/K_fn) F P_zoh|`` per A of current, with ``F`` the discretised
  ``Q s²`` and ``P_zoh`` the ZOH double integrator, is 7e-6 / 6e-4 at 10 / 100 Hz for
  Tustin, 8e-3 / 8e-3 for FOH and 9 / 0.9 for ZOH (10 kHz, ``Q`` at 500 Hz, ζ_q = 1,
  ``M_n/K_fn`` = 0.12 kg A/N): a ZOH ``Q s²`` sees the sampled position half a sample
  late and would estimate a large spurious disturbance from every acceleration.
* ``ẋ_fb``: the filtered differentiator of `microfab.control.velocity.VelocityEstimator`
  (Tustin). Its low-pass lags a moving stage by about ``2ζ_v/ω_v`` s, which eq. 3 would
  read as a velocity error ``(2ζ_v/ω_v) ẍ`` and turn into a tracking error of
  ``4 ζ ζ_v ẍ / (ω_c ω_v)`` (0.7 µm at 1 m/s², 50 Hz loop, 2 kHz filter, a fourteenth of
  what the acceleration feedforward removes). So by default (``match_velocity_filter``) the
  reference velocity passes through the same low-pass (Tustin) before the difference:
  ``K_v (L ẋ_ref − L ẋ)`` with ``L`` the filter, the velocity error seen through one
  filter. Set it off for eq. 3 literally.

Gains from bandwidths (seed 004 gives none; every default is assumed, see
`PreviewDOBConfig`): ``K_p = ω_c²``, ``K_v = 2 ζ ω_c``, ``g1 = ω_q²``, ``g2 = 2 ζ_q ω_q``,
``K_a = 1``. A config is refused when the DOB's natural frequency is not below the
Nyquist frequency, or when the nominal closed loop (``K_fn / (M_n s²)``, ZOH at ``dt``,
with this controller, all python-control) has a pole on or outside the unit circle.

Friction feedforward (not in the seed; off by default, ``friction_ff``): a model-based
current ``i_ff = s_F F(x_ref, ẋ_ref, z) / K_fn`` from a `microfab.plants.friction.StageFriction`
law per axis (``s_F`` = ``friction_ff_scale``), run on the reference: its LuGre bristle
state ``z`` moves by ``ẋ_ref dt`` a sample (`microfab.plants.friction.bristle_step`,
exact at constant speed), so the feedforward turns over at a reversal as the bristles of
a stage on the reference would. It enters eq. 4 as ``i = (M_n/K_fn) ẍ_d + î_d + i_ff``
with ``Q`` fed ``i − i_ff``: the DOB then estimates ``F_l − K_fn i_ff`` (what the model
leaves) instead of taking the feedforward's low-frequency part back out, and the plant
sees ``M_n ẍ_d − (1 − Q)(F_l − K_fn i_ff)``. The feedforward reads the reference only,
so the loop's linear model and margins (``x_fb`` to ``i``) are those without it.

Baselines: ``dob=False`` (preview without DOB), ``k_a=0`` and `PreviewDOBConfig.pd_only`
(``K_a = 0``, no DOB).

`PreviewDOB` is a `microfab.control.base.CompiledController`: measurement
``(x_fb, y_fb)`` in m, command ``(i_x, i_y)`` in A, the reference window carrying
position, velocity and acceleration (preview 1: the seed's "preview" is the time-based
spline's knowledge of the path, which reaches this controller as ``ẋ_ref``, ``ẍ_ref``).
Its kernel is split in two (`pdob_measure`, `pdob_command`) so that
`microfab.control.contour` can add its correction to ``ẍ_d`` between them.
`PreviewDOB.linear_model` gives one axis as a `DiscreteLTI` from
``[x_ref, ẋ_ref, ẍ_ref, x_fb]`` to ``i``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from microfab.control.base import CompiledController, ReferenceWindow
from microfab.control.preview_dob_model import (
    _HEAD,
    _NB,
    _NF,
    _NS,
    _P_EST,
    _P_F,
    _P_FF,
    _P_Q,
    _P_REF,
    _S_ACC,
    _S_DHAT,
    _S_EST,
    _S_F,
    _S_F_OUT,
    _S_IFF,
    _S_Q,
    _S_REF,
    _S_V,
    _S_VREF,
    _S_Z,
    PreviewDOBConfig,
    _axis_block,
    _model_from_block,
    axis_model,
    check_stable,
    nominal_closed_loop_poles,
)
from microfab.control.replay import replay_steps
from microfab.control.velocity import estimator_step
from microfab.plants.friction import bristle_step, friction_force
from microfab.plants.lti import DiscreteLTI

__all__ = [
    "PreviewDOB",
    "PreviewDOBAddOn",
    "PreviewDOBConfig",
    "PreviewDOBLog",
    "axis_model",
    "check_stable",
    "nominal_closed_loop_poles",
    "pdob_command",
    "pdob_measure",
    "preview_dob_step",
]


@njit(cache=True)
def pdob_measure(p: np.ndarray, x: np.ndarray, r: np.ndarray, ym: np.ndarray) -> None:
    """First half of a sample: the filters that read measurements and the reference.

    Advances, per axis, the velocity estimator on ``x_fb``, the reference velocity
    low-pass and the ``Q s²`` filter, and leaves ``v̂``, the (filtered) reference velocity
    and ``Q s² x_fb`` in the state's log slots. ``r``: the reference at this sample,
    shape (n_orders >= 3, n_axes). No allocation.
    """
    if r.shape[0] < 3:
        raise ValueError("PreviewDOB needs a reference with velocity and acceleration")
    na = int(p[0])
    for a in range(na):
        o = _HEAD + a * _NB
        s = a * _NS
        y = ym[a]
        x[s + _S_V] = estimator_step(p, o + _P_EST, x, s + _S_EST, y)
        if p[o + 6] != 0.0:
            x[s + _S_VREF] = estimator_step(p, o + _P_REF, x, s + _S_REF, r[1, a])
        else:
            x[s + _S_VREF] = r[1, a]
        x[s + _S_F_OUT] = estimator_step(p, o + _P_F, x, s + _S_F, y)


@njit(cache=True, inline="always")
def friction_feedforward(
    p: np.ndarray, x: np.ndarray, o: int, s: int, r: np.ndarray, a: int
) -> float:
    """The friction feedforward current of axis ``a`` (A), its bristle state advanced.

    The axis's friction law (block at ``p[o + _P_FF + 2:]``) at the reference position
    and velocity ``r[0, a]``, ``r[1, a]`` and the state's ``z``, times scale / ``K_fn``;
    ``z`` then moves by ``ẋ_ref dt`` (`microfab.plants.friction.bristle_step`, exact at a
    constant speed). 0 when the feedforward is off.
    """
    if p[o + _P_FF] == 0.0:
        return 0.0
    b = o + _P_FF + 2
    z = x[s + _S_Z]
    f, _zd, g = friction_force(p, b, r[0, a], r[1, a], z)
    dt = p[1]
    if p[b] != 0.0:  # friction on in the law (the bristle state exists)
        x[s + _S_Z] = bristle_step(p, b, z, r[1, a] * dt, g)
    return p[o + _P_FF + 1] * f


@njit(cache=True)
def pdob_command(
    p: np.ndarray, x: np.ndarray, r: np.ndarray, ym: np.ndarray, da: np.ndarray, u: np.ndarray
) -> None:
    """Second half of a sample: eq. 3 plus ``da`` (m/s², per axis), eq. 4, ``Q`` advanced.

    Writes the current ``u`` (A) per axis; logs ``î_d`` and ``ẍ_d``. No allocation.
    """
    na = int(p[0])
    for a in range(na):
        o = _HEAD + a * _NB
        s = a * _NS
        mk = p[o]
        acc = (
            p[o + 2] * r[2, a]
            + p[o + 3] * (x[s + _S_VREF] - x[s + _S_V])
            + p[o + 4] * (r[0, a] - ym[a])
            + da[a]
        )
        oq = o + _P_Q
        dob = p[o + 5] != 0.0
        dhat = 0.0
        if dob:
            dhat = p[oq + 6] * x[s + _S_Q] + p[oq + 7] * x[s + _S_Q + 1] - mk * x[s + _S_F_OUT]
        iff = friction_feedforward(p, x, o, s, r, a)
        i = mk * acc + dhat + iff
        u[a] = i
        if dob:  # Q sees the current less the feedforward: î_d estimates F_l − F_ff
            iq = i - iff
            q0 = p[oq] * x[s + _S_Q] + p[oq + 1] * x[s + _S_Q + 1] + p[oq + 4] * iq
            q1 = p[oq + 2] * x[s + _S_Q] + p[oq + 3] * x[s + _S_Q + 1] + p[oq + 5] * iq
            x[s + _S_Q] = q0
            x[s + _S_Q + 1] = q1
        x[s + _S_DHAT] = dhat
        x[s + _S_ACC] = acc
        x[s + _S_IFF] = iff


@njit(cache=True)
def preview_dob_step(
    p: np.ndarray, x: np.ndarray, ref: np.ndarray, k: int, ym: np.ndarray, u: np.ndarray
) -> None:
    """`CompiledController` kernel of `PreviewDOB`: `pdob_measure`, then `pdob_command`."""
    na = int(p[0])
    r = ref[k]
    pdob_measure(p, x, r, ym)
    n = p.shape[0]
    pdob_command(p, x, r, ym, p[n - na : n], u)  # the trailing zeros: no correction


@njit(cache=True)
def _record(p: np.ndarray, x: np.ndarray, row: np.ndarray) -> None:
    """`replay_steps` log of the state: ``K_fn î_d`` (N), then ``ẋ_fb`` (m/s), per axis."""
    na = int(p[0])
    for a in range(na):
        o = _HEAD + a * _NB
        s = a * _NS
        row[a] = p[o + 1] * x[s + _S_DHAT]
        row[na + a] = x[s + _S_V]


@dataclass(frozen=True, kw_only=True, eq=False)
class PreviewDOBLog:
    """Per-sample signals of a `PreviewDOB` run, replayed from its measurements.

    Attributes
    ----------
    command : numpy.ndarray
        Current references, A, shape (n, n_axes).
    disturbance : numpy.ndarray
        Estimated load force ``K_fn î_d`` used at each sample (``F_l`` of seed 004 eq. 2),
        N, shape (n, n_axes).
    velocity : numpy.ndarray
        Estimated velocity ``ẋ_fb``, m/s, shape (n, n_axes).
    final_state : numpy.ndarray
        Controller state after the last sample.
    """

    command: np.ndarray
    disturbance: np.ndarray
    velocity: np.ndarray
    final_state: np.ndarray


class PreviewDOB(CompiledController):
    """Per-axis preview controller with DOB, seed 004 eqs. 3-4 (module docstring).

    Parameters
    ----------
    config : PreviewDOBConfig
        Gains, nominal plant, filters.

    Notes
    -----
    ``params = [n_axes, dt, per axis (M_n/K_fn, K_fn, K_a, K_v, K_p, dob, match, 0,
    estimator(11), reference low-pass(11), Q s² (11), Q (11), friction feedforward (on,
    scale/K_fn, law block)), zeros(n_axes)]``, each
    filter ``[A(2x2), B(2), C(2), D, g(2)]`` with ``g`` its state at rest at input 1.
    State per axis (18): estimator ``[x0, x1, initialised]``, reference low-pass (3),
    ``Q s²`` filter (3) (each set to rest at its first input), ``Q`` (2, zero at rest),
    then the last sample's ``î_d`` (A), ``v̂`` (m/s), filtered ``ẋ_ref`` (m/s),
    ``Q s² x_fb`` (m/s²), ``ẍ_d`` (m/s²), then the friction feedforward's bristle
    deflection ``z`` (m, 0 at rest) and its last current ``i_ff`` (A).
    """

    kernel_step: Any = preview_dob_step

    def __init__(self, config: PreviewDOBConfig) -> None:
        if not isinstance(config, PreviewDOBConfig):
            raise TypeError(f"config must be a PreviewDOBConfig, got {type(config).__name__}")
        self.config = config
        self.dt = config.dt
        self.n_axes = config.n_axes
        self.n_inputs = self.n_axes
        self.n_outputs = self.n_axes
        self.preview = 1
        blocks = [_axis_block(config, a, config.k_p, config.k_v) for a in range(self.n_axes)]
        self.params = np.concatenate(
            [[float(self.n_axes), self.dt], *blocks, np.zeros(self.n_axes)]
        ).astype(np.float64)
        self.params.setflags(write=False)

    # ------------------------------------------------------------------ state machine
    def init(self) -> np.ndarray:
        """Every filter at rest (set at its first input), shape (18 n_axes,)."""
        return np.zeros(_NS * self.n_axes)

    def _block(self, a: int) -> np.ndarray:
        o = _HEAD + a * _NB
        return self.params[o : o + _NB]

    def step(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample in Python (the reference of the kernel); ``state`` is not modified."""
        if window.velocity is None or window.acceleration is None:
            raise ValueError(
                "PreviewDOB needs a reference with velocity and acceleration (give the "
                "simulator derivatives=(velocity, acceleration))"
            )
        x = np.array(state, dtype=np.float64, copy=True)
        ym = np.asarray(measurement, dtype=float)
        self.measure(x, window, ym)
        u = self.command(x, window, ym, np.zeros(self.n_axes))
        return u, x

    def measure(self, x: np.ndarray, window: ReferenceWindow, ym: np.ndarray) -> None:
        """`pdob_measure` in Python, on ``x`` in place (for composite controllers)."""
        est = self.config.estimator
        for a in range(self.n_axes):
            b = self._block(a)
            s = a * _NS
            y = float(ym[a])
            v, x[s : s + 3] = est.step(b[_P_EST : _P_EST + _NF], x[s : s + 3], y)
            x[s + _S_V] = v
            vr = float(window.velocity[0, a])  # type: ignore[index]
            if b[6] != 0.0:
                vr, x[s + 3 : s + 6] = est.step(b[_P_REF : _P_REF + _NF], x[s + 3 : s + 6], vr)
            x[s + _S_VREF] = vr
            f, x[s + 6 : s + 9] = est.step(b[_P_F : _P_F + _NF], x[s + 6 : s + 9], y)
            x[s + _S_F_OUT] = f

    def command(
        self, x: np.ndarray, window: ReferenceWindow, ym: np.ndarray, da: np.ndarray
    ) -> np.ndarray:
        """`pdob_command` in Python, on ``x`` in place; returns the currents (A)."""
        u = np.empty(self.n_axes)
        for a in range(self.n_axes):
            b = self._block(a)
            s = a * _NS
            mk = b[0]
            acc = (
                b[2] * float(window.acceleration[0, a])  # type: ignore[index]
                + b[3] * (x[s + _S_VREF] - x[s + _S_V])
                + b[4] * (float(window.position[0, a]) - float(ym[a]))
                + float(da[a])
            )
            q = b[_P_Q : _P_Q + _NF]
            sq = x[s + _S_Q : s + _S_Q + 2]
            dhat = 0.0
            if b[5] != 0.0:
                dhat = q[6] * sq[0] + q[7] * sq[1] - mk * x[s + _S_F_OUT]
            iff = 0.0
            if self.config.friction_ff:
                law = self.config.friction_ff[a]
                z = float(x[s + _S_Z])
                xr = float(window.position[0, a])
                vr = float(window.velocity[0, a])  # type: ignore[index]
                f, _zd, g = law.force(xr, vr, z)
                if law.friction:
                    x[s + _S_Z] = law.bristle(z, vr * self.dt, g)
                iff = self.config.friction_ff_scale * f / self.config.force_constant_n_per_a[a]
            i = mk * acc + dhat + iff
            if b[5] != 0.0:
                iq = i - iff
                x[s + _S_Q : s + _S_Q + 2] = (
                    q[0] * sq[0] + q[1] * sq[1] + q[4] * iq,
                    q[2] * sq[0] + q[3] * sq[1] + q[5] * iq,
                )
            x[s + _S_DHAT] = dhat
            x[s + _S_ACC] = acc
            x[s + _S_IFF] = iff
            u[a] = i
        return u

    # ------------------------------------------------------------------ read-outs
    def disturbance_estimate(self, state: np.ndarray) -> np.ndarray:
        """``K_fn î_d`` of the last sample per axis: the estimated ``F_l`` (eq. 2), N."""
        st = np.asarray(state, dtype=float)
        return np.array(
            [
                self.config.force_constant_n_per_a[a] * st[a * _NS + _S_DHAT]
                for a in range(self.n_axes)
            ]
        )

    def velocity_estimate(self, state: np.ndarray) -> np.ndarray:
        """``ẋ_fb`` of the last sample per axis, m/s."""
        st = np.asarray(state, dtype=float)
        return np.array([st[a * _NS + _S_V] for a in range(self.n_axes)])

    def acceleration_demand(self, state: np.ndarray) -> np.ndarray:
        """``ẍ_d`` of the last sample per axis (eq. 3 plus any correction), m/s²."""
        st = np.asarray(state, dtype=float)
        return np.array([st[a * _NS + _S_ACC] for a in range(self.n_axes)])

    def linear_model(self, axis: int = 0) -> DiscreteLTI:
        """Axis ``axis`` as a `DiscreteLTI` ``[x_ref, ẋ_ref, ẍ_ref, x_fb] -> i`` (A).

        The same numbers as the kernel, for inputs that start at zero (the kernel sets
        each filter to rest at its first input; from zero that is the zero state).
        """
        if not 0 <= axis < self.n_axes:
            raise ValueError(f"axis must lie in [0, {self.n_axes}), got {axis}")
        return _model_from_block(self._block(axis), self.dt)

    def replay(
        self, reference: np.ndarray, measured: np.ndarray, state: np.ndarray | None = None
    ) -> PreviewDOBLog:
        """Run the controller over recorded measurements and log its estimates.

        Parameters
        ----------
        reference : numpy.ndarray
            Stacked reference, shape (n, n_orders >= 3, n_axes) (position m, velocity
            m/s, acceleration m/s²; `microfab.sim.loop.reference_array`).
        measured : numpy.ndarray
            Positions the controller saw, m, shape (n, n_axes).
        state : numpy.ndarray, optional
            Starting state (default `init`).

        Returns
        -------
        PreviewDOBLog
        """
        ym = np.ascontiguousarray(measured, dtype=np.float64)
        R = np.ascontiguousarray(reference, dtype=np.float64)
        na = self.n_axes
        if ym.ndim != 2 or ym.shape[1] != na or not np.all(np.isfinite(ym)):
            raise ValueError(f"measured must be finite and shaped (n, {na}), got {ym.shape}")
        if R.ndim != 3 or R.shape[0] < ym.shape[0] or R.shape[1] < 3 or R.shape[2] != na:
            raise ValueError(
                f"reference must be shaped (n >= {ym.shape[0]}, n_orders >= 3, {na}), got {R.shape}"
            )
        x = self.init() if state is None else np.array(state, dtype=np.float64)
        u, log = replay_steps(preview_dob_step, self.params, x, R, ym, na, _record, 2 * na)
        return PreviewDOBLog(
            command=u,
            disturbance=np.ascontiguousarray(log[:, :na]),
            velocity=np.ascontiguousarray(log[:, na:]),
            final_state=x,
        )


class PreviewDOBAddOn(CompiledController):
    """Base of a controller that adds an acceleration correction to two `PreviewDOB` axes.

    The contour compensator (`microfab.control.contour`) and Koren's cross-coupled
    controller (`microfab.control.cross_coupled`) both keep ``head_states`` states of
    their own ahead of the inner controllers' state, let the inner controllers measure,
    compute a correction ``Δa`` (m/s², added to ``ẍ_d`` of eq. 3) and let them command.
    A subclass sets ``head_states`` and ``name``, calls `_setup` from ``__init__`` and
    uses `_begin` at the start of its Python ``step``.
    """

    head_states: int = 0
    name: str = "controller"

    def _setup(self, inner: PreviewDOBConfig, head: Any) -> None:
        """The inner controllers, sizes and ``params = [head, inner params]``."""
        self.inner = PreviewDOB(inner)
        self.dt = self.inner.dt
        self.n_axes = 2
        self.n_inputs = 2
        self.n_outputs = 2
        self.preview = 1
        self.params = np.concatenate([np.asarray(head, dtype=float), self.inner.params])
        self.params = self.params.astype(np.float64)
        self.params.setflags(write=False)

    def init(self) -> np.ndarray:
        """No correction yet, the inner controllers at rest."""
        return np.concatenate([np.zeros(self.head_states), self.inner.init()])

    def inner_state(self, state: np.ndarray) -> np.ndarray:
        """The inner `PreviewDOB`'s part of ``state`` (a view)."""
        return np.asarray(state)[self.head_states :]

    def _begin(
        self, state: np.ndarray, window: ReferenceWindow, measurement: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(state copy, measurement, inner state view)`` after the inner measurement."""
        if window.velocity is None or window.acceleration is None:
            raise ValueError(f"the {self.name} needs a reference with velocity and acceleration")
        x = np.array(state, dtype=np.float64, copy=True)
        ym = np.asarray(measurement, dtype=float)
        xin = x[self.head_states :]  # a view: the inner halves write into x
        self.inner.measure(xin, window, ym)
        return x, ym, xin
