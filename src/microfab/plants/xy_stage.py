"""Digital twin of the black-box XY stage of seed 002 (§II-B, Table I, eq. (3)).

The seed treats a laser-cutting XY stage with its built-in 10 kHz loop as a black box
``γ = F(ρ) + v`` (eq. 3): the input ``ρ`` is the position set-point per axis, the output
``γ`` the encoder position, ``v`` a 2 µm rms noise. It gives only Table I (1.5 m/s,
40 m/s², workspace [−0.19, 0.19]² m, 10 kHz, 2 µm repeatability). `XYStagePlant` is our
stand-in for what is inside the box, *not* the ETEL stage: every other value is assumed in
``data/xy_stage_twin.toml`` with its reason. Input: the set-point per axis (m), one per
10 kHz sample, held; output: the measured (encoder) position per axis (m). Run it through
`microfab.sim.loop.simulate` with `microfab.control.setpoint.SetPoint` (the command is the
reference).

Inside, per sample (state machine, exact order of `kernel_update`):

1. **Set-point guard** (seed §II-B: "the machine enforces limits on the acceleration,
   velocity, and position of the input trajectory"): each axis's input is clipped to the
   workspace; if the step from the last guarded set-point ``g`` to it would exceed the
   speed or acceleration limit (Table I, with a 1e-9 relative slack for rounding), or
   would land on it at a speed from which the input's own speed is more than one step
   away (catching up), the guard moves ``g`` toward the input at the limits instead: the
   time-optimal approach to the input's motion without overshoot (speed ``v_r ± v_b``,
   ``v_b`` the speed from which steps of ``a dt`` stop exactly within the gap; each
   step's change of speed within ``a dt``). A command within Table I passes unchanged.
   The state counts the samples where the guard changed the input (any axis) and those
   where the input broke the workspace, speed or acceleration limit. **Read the counts
   after a run** with ``plant.guard_counts(result.final_state.plant)`` (a `GuardCounts`);
   `XYStagePlant.guard` applies the same guard to a whole command.
2. **Built-in controller** per axis (the user cannot change it): PID on the error
   ``e = g - y_enc`` (encoder, quantised) with a filtered derivative, plus feedforward
   ``m_ff g̈ + c_ff ġ`` (backward differences of the guarded set-point), the commanded
   force clipped at the motor limit (``saturation``; the integrator then holds when it
   would wind up). Gains: `XYStageParams.gains`, placed on the rigid moving mass so that
   the loop has a slow real pole at ``-1 / 20 ms`` (seed §III-B: the 500 ms input history
   is about 25 times the slowest mode) and a pair at 25 Hz, ζ 0.7 (assumed).
3. **Mechanics** (linear, both axes in one system, `XYStageParams.mechanics`): the motor
   force follows the command through a first-order lag (current loop, 1.5 kHz); x moves
   its own carriage and the whole y stage; y's carriage carries a head on a compliant
   mount (carriage resonance, 150 Hz, ζ 0.02, ``resonance``); 1 % of the y motor force
   reacts on the x carriage (``coupling``). The encoder reads each carriage.
4. **Disturbance forces** opposing each carriage, held over ``substeps`` sub-steps while
   the linear mechanics are exact over each (matrix exponential, ZOH):
   LuGre friction (``friction``): ``F = σ0 z + σ1 ż + σ2 v``,
   ``ż = v − σ0 |v| z / g(v)``, ``g = F_c + (F_s − F_c) exp(−(v / v_s)²)`` (Stribeck,
   pre-sliding); over a sub-step the bristle state is advanced exactly for its
   displacement ``Δx`` at the Stribeck level ``g`` of its start,
   ``z ← z_ss + (z − z_ss) exp(−σ0 |Δx| / g)``, ``z_ss = sign(Δx) g / σ0``, so the stiff
   bristles need no small steps; cogging at the motor pitch (``cogging``),
   ``A sin(2π x / p + φ)``; on y the cable carrier (``cable``),
   ``k (y − y_rest) + A_l sin(2π y / p_l + φ_l)``.

Encoder quantisation (10 nm, assumed; ``quantisation``) applies to the controller's
feedback and to the output. The 2 µm output noise (eq. 3) is not added here: `noise`
draws it (seeded) for the simulators, which add it to the output.

With `NONLINEAR` off, no force is held and each sample is one exact ZOH step of the
mechanics: the twin is then `XYStagePlant.linear_model` (the closed loop, ZOH, for legal
inputs) to rounding.

State (flat, 35): mechanics ``[x, vx, Fx, yc, vyc, yh, vyh, Fy]`` (m, m/s, N), bristle
``z`` per axis (m), controller ``[I, D, e_prev]`` per axis (N, N, m), guard
``[g, w, r_prev, v_prev]`` per axis (m, m/s, m, m/s), guard counts (4), the sample
counter, 8 scratch.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from microfab.core.limits import MachineLimits
from microfab.plants import xy_stage_params as _p
from microfab.plants.base import CompiledPlant, NoiseLevel, NoisyOutputs
from microfab.plants.lti import DiscreteLTI
from microfab.plants.xy_stage_kernels import (
    _G,
    _N_STATE,
    _S_COUNT,
    _S_CTRL,
    _S_GUARD,
    _S_K,
    _S_Z,
    _approach,
    kernel_output,
    kernel_update,
)
from microfab.plants.xy_stage_params import (
    AXES,
    MECH_FORCE,
    MECH_POS,
    MECH_VEL,
    N_MECH,
    NONLINEAR,
    SWITCHES,
    XYStageParams,
    load_params,
)

__all__ = [
    "AXES",
    "NONLINEAR",
    "SWITCHES",
    "GuardCounts",
    "XYStageParams",
    "XYStagePlant",
    "kernel_output",
    "kernel_update",
    "load_params",
    "xy_stage_twin",
]


@dataclass(frozen=True)
class GuardCounts:
    """What the set-point guard did over a run (read from a state by `guard_counts`).

    Attributes
    ----------
    limited : int
        Samples where the guard changed the input of at least one axis (the loop was
        given another set-point than the input; also while catching up after a jump).
    position, speed, acceleration : int
        Samples where the input of an axis lay outside the workspace, or its own speed
        or acceleration (backward differences of the input clipped to the workspace)
        exceeded Table I (a sample may count in several).
    samples : int
        Samples run since the state was made.
    """

    limited: int
    position: int
    speed: int
    acceleration: int
    samples: int


# --- the plant -----------------------------------------------------------------------------


class XYStagePlant(CompiledPlant, NoisyOutputs):
    """The black-box XY stage twin as a compiled plant: set-points (m) in, positions (m) out.

    Parameters
    ----------
    config : XYStageParams
        The twin's parameters.

    Attributes
    ----------
    config : XYStageParams
        The parameters.
    axes : tuple of str
        ``("x", "y")``.
    noise_level : NoiseLevel
        Output noise ``v`` of eq. (3) per axis, m (2 µm); `noise` draws it, seeded.

    Notes
    -----
    State: see the module docstring (shape (37,)). ``output`` and ``update`` are plain
    Python written from ``config`` (not from the packed kernels), for the Python loop and
    as the reference of the kernels; both agree to rounding. The guard's counts after a
    run: ``guard_counts(result.final_state.plant)``.
    """

    kernel_output: Any = kernel_output
    kernel_update: Any = kernel_update
    n_inputs = 2
    n_outputs = 2

    def __init__(self, config: XYStageParams) -> None:
        self.config = config
        self.axes = AXES
        self.noise_level = NoiseLevel((config.noise_rms_m,) * 2, "m")
        self.params = config.pack()
        self.params.setflags(write=False)
        self.dt = config.dt
        self._gains = config.gains()
        self._dfilt = config.derivative_filter()
        self._zoh_dt = config.discrete_mechanics(config.dt)
        self._zoh_h = config.discrete_mechanics(config.dt / config.substeps)

    # --- state ---------------------------------------------------------------------------

    def init(self) -> np.ndarray:
        """At rest at the origin (see `state_at`)."""
        return self.state_at((0.0, 0.0))

    def state_at(self, position_m: tuple[float, float]) -> np.ndarray:
        """At rest at ``position_m`` (m, per axis), set-point there, sample 0.

        The bristles are relaxed and the integrators and motor forces hold the static
        forces there (cogging, cable, and on x the reaction of y's force), so the stage
        stays put under a constant set-point.
        """
        c = self.config
        s = np.zeros(_N_STATE)
        pos = [float(position_m[0]), float(position_m[1])]
        lo, hi = c.workspace_m
        for a in range(2):
            if not lo <= pos[a] <= hi:
                raise ValueError(
                    f"position_m[{AXES[a]}] = {pos[a]} m lies outside the workspace "
                    f"[{lo}, {hi}] m; start inside it"
                )
            s[MECH_POS[a]] = pos[a]
            o = _S_GUARD + _G * a
            s[o], s[o + 2] = pos[a], pos[a]
        s[5] = pos[1]  # the head sits on the carriage
        fy = self._disturbance_py(s, 1)[0]
        fx = self._disturbance_py(s, 0)[0] + (c.reaction_coupling * fy if c.coupling else 0.0)
        for a, f in enumerate((fx, fy)):
            s[MECH_FORCE[a]] = f
            s[_S_CTRL + 3 * a] = f
        return s

    def output(self, state: np.ndarray) -> np.ndarray:
        """Encoder positions ``(x, y)``, m, shape (2,)."""
        return np.array([self._quantise_py(float(state[i])) for i in MECH_POS])

    def guard_counts(self, state: np.ndarray) -> GuardCounts:
        """What the set-point guard did since ``state``'s start (e.g. a run's final state)."""
        s = np.asarray(state)
        return GuardCounts(*(round(float(v)) for v in s[_S_COUNT : _S_K + 1]))

    def machine_limits(self) -> MachineLimits:
        """Table I as `microfab.core.limits.MachineLimits` (what the guard enforces)."""
        return self.config.machine_limits()

    def guard(
        self, command: np.ndarray, state: np.ndarray | None = None
    ) -> tuple[np.ndarray, GuardCounts]:
        """The guard alone over a command: ``(guarded set-points, counts)``.

        Parameters
        ----------
        command : numpy.ndarray
            Set-points, m, shape (n_samples, 2).
        state : numpy.ndarray, optional
            Where the guard starts (a twin state; default `init`).

        Returns
        -------
        guarded : numpy.ndarray
            What the built-in loop would be given, m, shape (n_samples, 2).
        counts : GuardCounts
            As `guard_counts` after a run of ``command`` from ``state``.
        """
        u = np.asarray(command, dtype=float)
        if u.ndim != 2 or u.shape[1] != 2 or not np.isfinite(u).all():
            raise ValueError(f"command must be finite, shaped (n_samples, 2), got {u.shape}")
        s = (self.init() if state is None else np.asarray(state, dtype=float)).copy()
        out = np.empty_like(u)
        for k in range(u.shape[0]):
            flags = [0, 0, 0, 0]
            for a in range(2):
                g, w, *fl = self._guard_py(s, a, float(u[k, a]))
                s[_S_GUARD + _G * a], s[_S_GUARD + _G * a + 1] = g, w
                out[k, a] = g
                flags = [f | x for f, x in zip(flags, fl, strict=True)]
            self._count_py(s, flags)
        return out, self.guard_counts(s)

    # --- Python reference of the kernels --------------------------------------------------

    def _quantise_py(self, x: float) -> float:
        c = self.config
        if c.quantisation:
            q = c.encoder_resolution_m
            return math.floor(x / q + 0.5) * q
        return x

    def _guard_py(self, s: np.ndarray, a: int, u: float) -> tuple[float, float, int, int, int, int]:
        c = self.config
        o = _S_GUARD + _G * a
        gp, wp, rp, vp = (float(v) for v in s[o : o + _G])
        dt, (lo, hi), vmax = self.dt, c.workspace_m, c.velocity_limit_m_s
        dv = c.acceleration_limit_m_s2 * dt
        tol = 1.0 + float(self.params[_p._H_TOL])
        r = min(max(u, lo), hi)
        vin = (r - rp) / dt
        flags = (int(r != u), int(abs(vin) > vmax * tol), int(abs(vin - vp) > dv * tol))
        wd = (r - gp) / dt
        vr = min(max(vin, -vmax), vmax)
        if abs(wd) <= vmax * tol and abs(wd - wp) <= dv * tol and abs(wd - vr) <= dv * tol:
            g, w = r, wd
        else:
            e = r - vr * dt - gp
            w = vr + math.copysign(_approach(abs(e), dt, dv), e)
            w = min(max(min(max(w, wp - dv), wp + dv), -vmax), vmax)
            g = gp + w * dt
            if not lo <= g <= hi:
                g = min(max(g, lo), hi)
                w = (g - gp) / dt
        s[o + 2], s[o + 3] = r, vin
        return g, w, int(g != u), *flags

    def _control_py(self, s: np.ndarray, a: int, g: float, w: float, wp: float) -> float:
        c = self.config
        gains = self._gains[a]
        ad, bd = self._dfilt
        o = _S_CTRL + 3 * a
        e = g - self._quantise_py(float(s[MECH_POS[a]]))
        i0 = float(s[o])
        ii = i0 + gains.ki * self.dt * e
        dd = ad * float(s[o + 1]) + gains.kd * bd * (e - float(s[o + 2]))
        f = gains.kp * e + ii + dd + c.feedforward_mass_kg[a] * ((w - wp) / self.dt)
        f += c.feedforward_viscous_n_s_per_m[a] * w
        fpk = c.peak_force_n[a]
        if c.saturation and abs(f) > fpk:
            f = math.copysign(fpk, f)
            if e * f > 0.0:
                ii = i0
        s[o], s[o + 1], s[o + 2] = ii, dd, e
        return f

    def _disturbance_py(self, s: np.ndarray, a: int) -> tuple[float, float]:
        """``(F, g)`` of carriage ``a`` (N): its `StageFriction` at the state ``s``."""
        law = self.config.friction_laws[a]
        f, _zd, g = law.force(float(s[MECH_POS[a]]), float(s[MECH_VEL[a]]), float(s[_S_Z + a]))
        return f, g

    @staticmethod
    def _count_py(s: np.ndarray, flags: list[int]) -> None:
        for i, f in enumerate(flags):
            s[_S_COUNT + i] += f
        s[_S_K] += 1.0

    def update(self, state: np.ndarray, command: np.ndarray) -> np.ndarray:
        """State one sample later (a new array): set-points ``command`` (m) held."""
        c = self.config
        s = np.array(state, dtype=float, copy=True)
        u = np.asarray(command, dtype=float)
        wp = [float(s[_S_GUARD + 1]), float(s[_S_GUARD + _G + 1])]
        guarded = [self._guard_py(s, a, float(u[a])) for a in range(2)]
        f = np.array([self._control_py(s, a, *guarded[a][:2], wp[a]) for a in range(2)])
        if c.any_disturbance():
            phi, gu, gd = self._zoh_h
            for _ in range(c.substeps):
                d, g = zip(*(self._disturbance_py(s, a) for a in range(2)), strict=True)
                before = s[list(MECH_POS)].copy()
                s[:N_MECH] = phi @ s[:N_MECH] + gu @ f + gd @ np.array(d)
                if c.friction:
                    for a in range(2):
                        dx = float(s[MECH_POS[a]] - before[a])
                        law = c.friction_laws[a]
                        s[_S_Z + a] = law.bristle(float(s[_S_Z + a]), dx, g[a])
        else:
            phi, gu, _gd = self._zoh_dt
            s[:N_MECH] = phi @ s[:N_MECH] + gu @ f
        flags = [0, 0, 0, 0]
        for a in range(2):
            s[_S_GUARD + _G * a], s[_S_GUARD + _G * a + 1] = guarded[a][:2]
            flags = [x | y for x, y in zip(flags, guarded[a][2:], strict=True)]
        self._count_py(s, flags)
        return s

    # --- linear model ----------------------------------------------------------------------

    def _linear_states(self) -> list[int]:
        """Twin state indices of `linear_model`'s states, in its order."""
        mech = [i for i in range(N_MECH) if self.config.resonance or i not in (5, 6)]
        ctrl = list(range(_S_CTRL, _S_CTRL + 6))
        guard = [_S_GUARD, _S_GUARD + 1, _S_GUARD + _G, _S_GUARD + _G + 1]
        return mech + ctrl + guard

    def linear_state(self, state: np.ndarray) -> np.ndarray:
        """The states of `linear_model` read from twin states: shape (n,) or (m, n)."""
        return np.array(np.asarray(state)[..., self._linear_states()])

    def linear_model(self) -> DiscreteLTI:
        """The closed loop (guard passing, PID + feedforward, mechanics) with `NONLINEAR` off.

        Exact ZOH at 10 kHz: the twin with friction, cogging, cable, saturation and
        quantisation off follows it to rounding for any command within Table I (the
        guard then passes it). Resonance and coupling are kept as the switches say.

        Returns
        -------
        DiscreteLTI
            Inputs: set-points ``(x, y)`` (m); outputs: carriage positions (m). States
            (`linear_state` reads them from a twin state): the mechanics
            ``[x, vx, Fx, yc, vyc, (yh, vyh,) Fy]``, ``[I, D, e_prev]`` per axis, ``[g, w]``
            per axis.
        """
        idx = self._linear_states()
        A, B, C = self.config.closed_loop()
        # the full layout holds the twin's states in its order (the guard without r_prev);
        # with the resonance off the head's states copy the carriage's and are left out
        full = list(range(N_MECH)) + list(range(_S_CTRL, _S_CTRL + 6))
        full += [_S_GUARD, _S_GUARD + 1, _S_GUARD + _G, _S_GUARD + _G + 1]
        sel = [full.index(i) for i in idx]
        return DiscreteLTI(
            A[np.ix_(sel, sel)],
            B[sel],
            C[:, sel],
            np.zeros((2, 2)),
            self.dt,
            input_names=("x", "y"),
            output_names=("x", "y"),
        )

    def continuous_poles(self) -> np.ndarray:
        """Poles of `linear_model` as continuous ones, ``ln(z) / dt`` (rad/s), slowest first.

        Poles at ``z = 0`` (the feedforward's memory) are left out.
        """
        z = self.linear_model().poles()
        z = z[np.abs(z) > 1e-12]
        s = np.log(z.astype(complex)) / self.dt
        return s[np.argsort(np.abs(s))]


def xy_stage_twin(
    path: str | os.PathLike[str] | None = None,
    *,
    params: XYStageParams | None = None,
    **changes: Any,
) -> XYStagePlant:
    """The XY stage twin from the data file, with validated ``changes``.

    Parameters
    ----------
    path : path-like, optional
        Another parameter file (default ``data/xy_stage_twin.toml``).
    params : XYStageParams, optional
        Parameters already read (then ``path`` is not read); the machine modules pass
        the ones they parsed once (`microfab.machines.twins`).
    **changes
        `XYStageParams` fields to replace (unknown names refused), e.g.
        ``**dict.fromkeys(NONLINEAR, False)`` for the linear twin.
    """
    cfg = load_params(path) if params is None else params
    return XYStagePlant(cfg.with_(**changes) if changes else cfg)
