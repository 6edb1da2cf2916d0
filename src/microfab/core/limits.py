"""Declared machine limits and the check every emitted command must pass."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from microfab.core.validate import check_positive

if TYPE_CHECKING:
    from microfab.trajectory.base import Trajectory

__all__ = ["AxisLimits", "LimitViolation", "MachineLimits", "check_command", "check_trajectory"]


class LimitViolation(ValueError):  # noqa: N818 - reads as a sentence: "raise LimitViolation"
    """A command would exceed a machine's declared position, velocity or acceleration."""


@dataclass(frozen=True, kw_only=True)
class AxisLimits:
    """Declared limits of one machine axis, in the command's unit.

    Parameters
    ----------
    position : float
        Largest allowed ``|command|`` (unit).
    velocity : float
        Largest allowed ``|d command / dt|`` (unit/s).
    acceleration : float
        Largest allowed ``|d² command / dt²|`` (unit/s²).
    unit : str
        Unit of the command, for messages.
    """

    position: float
    velocity: float
    acceleration: float
    unit: str = "V"

    def __post_init__(self) -> None:
        for name, val, suffix in (
            ("position", self.position, ""),
            ("velocity", self.velocity, "/s"),
            ("acceleration", self.acceleration, "/s^2"),
        ):
            if not (val > 0):
                raise ValueError(f"{name} limit must be positive, got {val} {self.unit}{suffix}")


def _power(dt: float, order: int) -> float:
    """``dt ** order`` as a float, inf where it overflows (a Python float raises there)."""
    with np.errstate(over="ignore"):
        return float(np.float64(dt) ** order)


def check_command(
    command: np.ndarray,
    dt: float,
    limits: Mapping[str, AxisLimits],
    axes: tuple[str, ...],
    periodic: bool = True,
) -> None:
    """Refuse a command that exceeds the declared limits.

    Velocity and acceleration are finite differences of the sampled command (wrapping
    around for a periodic command, which the machine repeats).

    Parameters
    ----------
    command : numpy.ndarray
        Command, shape (n_samples, n_axes).
    dt : float
        Sample time, s.
    limits : mapping of str to AxisLimits
        Limits per axis name; axes without an entry are refused.
    axes : tuple of str
        Axis names of the columns.
    periodic : bool
        Whether the command is one period of a repeated signal.

    Raises
    ------
    LimitViolation
        With the axis, the quantity, the peak value, the limit and the sample index.
    """
    cmd = np.asarray(command, dtype=float)
    if cmd.ndim == 1:
        cmd = cmd[:, None]
    if not np.all(np.isfinite(cmd)):
        raise LimitViolation("command holds NaN or inf; nothing was emitted")
    # all axes at once, one row each (reductions along contiguous rows are fast)
    X = np.ascontiguousarray(cmd.T)
    XE = np.concatenate([X[:, -2:], X, X[:, :2]], axis=1) if periodic else X
    with np.errstate(over="ignore"):  # an absurd dt gives inf, refused as beyond the limit
        D = np.diff(XE, axis=1)
        V = D / dt
        ACC = np.diff(D, axis=1) / _power(dt, 2)  # np.diff(XE, 2) is this second difference
    peaks = [np.argmax(np.abs(sig), axis=1) if sig.shape[1] else None for sig in (X, V, ACC)]
    for a, name in enumerate(axes):
        if name not in limits:
            raise LimitViolation(f"axis {name!r} has no declared limits; nothing was emitted")
        lim = limits[name]
        n = X.shape[1]
        pad = 2 if periodic else 0  # samples wrapped in front of a periodic command
        # v[k] runs from sample k - pad to k - pad + 1; acc[k] is centred on k - pad + 1
        for qty, sig, peak, bound, suffix, shift in (
            ("position", X[a], peaks[0], lim.position, "", 0),
            ("velocity", V[a], peaks[1], lim.velocity, "/s", -pad),
            ("acceleration", ACC[a], peaks[2], lim.acceleration, "/s^2", 1 - pad),
        ):
            if peak is None:
                continue
            k = int(peak[a])
            if abs(sig[k]) > bound:
                i = (k + shift) % n  # a sample of the command itself, in [0, n)
                raise LimitViolation(
                    f"axis {name}: {qty} {sig[k]:.4g} {lim.unit}{suffix} exceeds the declared "
                    f"limit {bound:.4g} {lim.unit}{suffix} at t = {i * dt:.6g} s (near "
                    f"sample {i}); nothing was emitted"
                )


@dataclass(frozen=True, kw_only=True)
class MachineLimits:
    """Declared limits of a Cartesian machine, per axis, in SI units.

    Parameters
    ----------
    workspace : tuple of (float, float)
        ``(min, max)`` position per axis, m.
    velocity, acceleration : tuple of float
        Largest ``|v|`` (m/s) and ``|a|`` (m/s²) per axis.
    jerk : tuple of float, optional
        Largest ``|j|`` per axis, m/s³; ``inf`` (the default) where none is declared.
    axes : tuple of str
        Axis names.
    """

    workspace: tuple[tuple[float, float], ...]
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...]
    jerk: tuple[float, ...] | None = None
    axes: tuple[str, ...] = ("x", "y")

    def __post_init__(self) -> None:
        n = len(self.axes)
        jerk = self.jerk if self.jerk is not None else (float("inf"),) * n
        object.__setattr__(self, "jerk", tuple(float(j) for j in jerk))
        ws = tuple((float(lo), float(hi)) for lo, hi in self.workspace)
        object.__setattr__(self, "workspace", ws)
        object.__setattr__(self, "velocity", tuple(float(v) for v in self.velocity))
        object.__setattr__(self, "acceleration", tuple(float(v) for v in self.acceleration))
        for name, vals in (
            ("workspace", ws),
            ("velocity", self.velocity),
            ("acceleration", self.acceleration),
            ("jerk", self.jerk),
        ):
            if len(vals) != n:
                raise ValueError(f"{name} needs one entry per axis {self.axes}, got {vals}")
        for ax, (lo, hi) in zip(self.axes, ws, strict=True):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"workspace of axis {ax} must be min < max, got [{lo}, {hi}] m")
        for name, vals, unit in (
            ("velocity", self.velocity, "m/s"),
            ("acceleration", self.acceleration, "m/s^2"),
        ):
            for ax, v in zip(self.axes, vals, strict=True):
                check_positive(f"{name} limit of axis {ax}", v, unit)
        for ax, v in zip(self.axes, self.jerk, strict=True):
            if not v > 0:  # refuses NaN; inf is allowed: no jerk limit declared
                raise ValueError(f"jerk limit of axis {ax} must be positive, got {v} m/s^3")

    @classmethod
    def seed002_stage(cls) -> MachineLimits:
        """The ETEL DXL-LM325 stage's software limits (seed 002 Table I); no jerk limit."""
        return cls(
            workspace=((-0.19, 0.19), (-0.19, 0.19)),  # seed 002 Table I: [-0.19, 0.19]^2 m^2
            velocity=(1.5, 1.5),  # seed 002 Table I: 1.5 m/s
            acceleration=(40.0, 40.0),  # seed 002 Table I: 40 m/s^2
        )

    @classmethod
    def seed001_stage(cls) -> MachineLimits:
        """The XY flexure nanomanipulator of seed 001; no jerk limit.

        Travel from the seed; speed and acceleration are assumed (the seed gives none) and
        match ``velocity_limit_mm_s`` of ``data/nanomanipulator_twin.toml``.
        """
        return cls(
            workspace=((-1.5e-3, 1.5e-3), (-1.5e-3, 1.5e-3)),  # seed 001 §2: ±1.5 mm x ±1.5 mm
            # assumed: 40x the 0.47 mm/s of a 0.15 mm circle at 1 Hz (such a circle up to 40 Hz)
            velocity=(0.02, 0.02),
            # assumed: a 0.15 mm circle at 40 Hz needs (2 pi 40)^2 * 0.075 mm = 4.7 m/s^2
            acceleration=(5.0, 5.0),
        )

    @classmethod
    def seed004_stage(cls) -> MachineLimits:
        """The precise planar XY stage of seed 004 (laser micromachining); no jerk limit.

        Speed and acceleration from the seed; the travel is assumed (the seed gives none).
        """
        return cls(
            # assumed: ±25 mm per axis, a 50 mm stroke for a 0.6 kg direct-drive stage
            workspace=((-0.025, 0.025), (-0.025, 0.025)),
            velocity=(0.1, 0.1),  # seed 004 Table I: max. velocity 0.1 m/s
            acceleration=(5.0, 5.0),  # seed 004 Table I: max. acceleration 5 m/s^2
        )

    @classmethod
    def seed003_slm(cls) -> MachineLimits:
        """The SLM galvo scanner of seed 003 part 2 at the work plane; no jerk limit.

        All assumed (the seed gives no field or speed) and equal to ``data/galvo_slm.toml``
        (`microfab.plants.galvo_slm.GalvoSLMPlant.axis_limits` declares them in bit).
        """
        field = 32768 * 1.5e-6  # assumed: ±32768 bit of 1.5 µm, ±49.152 mm
        return cls(
            workspace=((-field, field), (-field, field)),
            velocity=(10.0, 10.0),  # assumed: twice the assumed 5 m/s jump speed
            # assumed: the velocity limit gained within one 10 µs tick (an RTC vector starts
            # at full speed; a 5 m/s jump from rest is 5e5 m/s^2 sampled)
            acceleration=(1.0e6, 1.0e6),
        )

    def with_jerk(self, jerk: float | tuple[float, ...]) -> MachineLimits:
        """A copy with the jerk limit replaced (one value for all axes, or per axis)."""
        j = (float(jerk),) * len(self.axes) if np.isscalar(jerk) else tuple(jerk)  # type: ignore[arg-type]
        return MachineLimits(
            workspace=self.workspace,
            velocity=self.velocity,
            acceleration=self.acceleration,
            jerk=j,
            axes=self.axes,
        )


def _violation(axis: str, qty: str, value: float, bound: float, unit: str, t: float) -> str:
    return (
        f"axis {axis}: {qty} {value:.6g} {unit} at t = {t:.6g} s exceeds the limit "
        f"{bound:.6g} {unit}; nothing was emitted"
    )


def check_trajectory(traj: Trajectory, limits: MachineLimits, rtol: float = 1e-9) -> None:
    """Refuse a trajectory outside the workspace or above a velocity/acceleration/jerk limit.

    Two views are checked: the analytic derivatives the generator provides (if any) and
    the finite differences of the samples, which is what a machine sampling the
    positions sees. A trajectory marked ``at_rest`` is checked with the machine holding
    still before and after it; otherwise it is taken as one period and wrapped around.

    Parameters
    ----------
    traj : microfab.trajectory.base.Trajectory
        The trajectory.
    limits : MachineLimits
        Declared limits; the trajectory's axes must match ``limits.axes``.
    rtol : float
        Relative allowance for floating-point rounding.

    Raises
    ------
    LimitViolation
        Naming the axis, the quantity, the time, the value and the limit.
    """
    pos = np.asarray(traj.position, dtype=float)
    dt = float(traj.dt)
    axes = tuple(traj.axes)
    if axes != tuple(limits.axes):
        raise LimitViolation(f"trajectory axes {axes} do not match the limits' axes {limits.axes}")
    if not np.all(np.isfinite(pos)):
        raise LimitViolation("trajectory holds NaN or inf; nothing was emitted")
    n = pos.shape[0]
    t = np.arange(n) * dt
    at_rest = bool(getattr(traj, "at_rest", True))
    scale = float(np.max(np.abs(pos))) if n else 0.0
    eps = np.finfo(float).eps
    for k, ax in enumerate(axes):
        lo, hi = limits.workspace[k]
        x = pos[:, k]
        i_lo, i_hi = int(np.argmin(x)), int(np.argmax(x))
        if x[i_lo] < lo:
            raise LimitViolation(
                f"axis {ax}: position {x[i_lo]:.6g} m at t = {t[i_lo]:.6g} s is below the "
                f"workspace minimum {lo:.6g} m; nothing was emitted"
            )
        if x[i_hi] > hi:
            raise LimitViolation(
                f"axis {ax}: position {x[i_hi]:.6g} m at t = {t[i_hi]:.6g} s is above the "
                f"workspace maximum {hi:.6g} m; nothing was emitted"
            )
        bounds = (limits.velocity[k], limits.acceleration[k], limits.jerk[k])  # type: ignore[index]
        names = (("velocity", "m/s"), ("acceleration", "m/s^2"), ("jerk", "m/s^3"))
        # analytic derivatives from the generator
        for (qty, unit), bound, arr in zip(
            names,
            bounds,
            (traj.velocity, traj.acceleration, traj.jerk),
            strict=True,
        ):
            if arr is None or not np.isfinite(bound):
                continue
            sig = np.asarray(arr)[:, k]
            i = int(np.argmax(np.abs(sig)))
            if abs(sig[i]) > bound * (1 + rtol):
                raise LimitViolation(_violation(ax, qty, sig[i], bound, unit, t[i]))
        # finite differences of the samples (what the machine sees)
        pad = 3
        if at_rest:
            xe = np.concatenate([np.full(pad, x[0]), x, np.full(pad, x[-1])])
        else:
            xe = np.concatenate([x[-pad:], x, x[:pad]])
        te = (np.arange(xe.size) - pad) * dt
        for order, ((qty, unit), bound) in enumerate(zip(names, bounds, strict=True), start=1):
            if not np.isfinite(bound):
                continue
            d = np.diff(xe, order) / _power(dt, order)
            # rounding of the samples, amplified by the difference (2**order * eps * |x|)
            allow = bound * (1 + rtol) + 2**order * 4 * eps * scale / _power(dt, order)
            i = int(np.argmax(np.abs(d)))
            if abs(d[i]) > allow:
                tc = float(np.clip(te[i] + 0.5 * order * dt, 0.0, max(t[-1], 0.0)))
                raise LimitViolation(
                    _violation(ax, qty, d[i], bound, unit, tc).replace(
                        "exceeds", "(sampled) exceeds"
                    )
                )
