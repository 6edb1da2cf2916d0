"""Time-based cubic spline: one cubic per axis between consecutive time knots.

Seed 004 §III turns the points of a part drawing into motion with a *time-based spline*:
each axis is a piecewise cubic of time, written on piece ``n`` in the local time
``t ∈ [0, t_{n+1} - t_n]`` as (seed 004 eq. (1))::

    x_n(t)   = α_n t³ + β_n t² + γ_n t + δ_n
    ẋ_n(t)   = 3 α_n t² + 2 β_n t + γ_n
    ẍ_n(t)   = 6 α_n t + 2 β_n

and the jerk is the constant ``6 α_n`` on each piece. :class:`TimeSpline` holds the
knots and the four coefficient arrays, evaluates the spline and its derivatives, finds
their exact maxima (the velocity is a quadratic per piece, the acceleration linear, the
jerk constant) and samples it into a :class:`~microfab.trajectory.base.Trajectory`.

:meth:`TimeSpline.fit` builds the C² interpolating spline through given points at given
times with :class:`scipy.interpolate.CubicSpline` (boundary conditions ``"clamped"``,
``"natural"``, ``"periodic"``), or with :func:`scipy.interpolate.make_interp_spline`
for ``"rest"``: zero velocity *and* zero acceleration at both ends, which a jerk-limited
machine needs to start from and stop at rest (see :meth:`TimeSpline.fit`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator, make_interp_spline

from microfab.core.arrays import readonly
from microfab.core.validate import check_positive
from microfab.trajectory.base import MAX_SAMPLES, Trajectory

__all__ = ["SplineMaxima", "TimeSpline"]

_BCS = ("clamped", "natural", "periodic", "rest")


@dataclass(frozen=True, kw_only=True, eq=False)
class SplineMaxima:
    """Exact per-axis maxima of ``|velocity|``, ``|acceleration|`` and ``|jerk|``.

    Parameters
    ----------
    velocity, acceleration, jerk : numpy.ndarray, shape (n_axes,)
        Largest absolute value over the whole spline, m/s, m/s², m/s³.
    velocity_time, acceleration_time, jerk_time : numpy.ndarray, shape (n_axes,)
        Time at which it occurs, s (for the jerk, the start of the piece holding it).
    """

    velocity: np.ndarray
    velocity_time: np.ndarray
    acceleration: np.ndarray
    acceleration_time: np.ndarray
    jerk: np.ndarray
    jerk_time: np.ndarray


@dataclass(frozen=True, kw_only=True, eq=False)
class TimeSpline:
    """A piecewise cubic of time per axis (seed 004 eq. (1)).

    Parameters
    ----------
    knots : array_like, shape (K + 1,)
        Strictly increasing piece boundaries, s.
    alpha, beta, gamma, delta : array_like, shape (K, n_axes)
        Coefficients of ``x_n(t) = α_n t³ + β_n t² + γ_n t + δ_n`` on piece ``n`` with
        ``t`` counted from ``knots[n]``: m/s³, m/s², m/s, m.
    axes : tuple of str
        Axis names, ``("x", "y")`` by default.
    bc : str
        Boundary condition the spline was fitted with (informational).
    """

    knots: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    delta: np.ndarray
    axes: tuple[str, ...] = ("x", "y")
    bc: str = "clamped"
    meta: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        knots = np.array(self.knots, dtype=float)
        if knots.ndim != 1 or knots.size < 2:
            raise ValueError(f"knots must be a 1-D array of >= 2 times (s), got {knots.shape}")
        if not np.all(np.isfinite(knots)):
            raise ValueError("knots hold NaN or inf (s)")
        steps = np.diff(knots)
        if not np.all(steps > 0):
            k = int(np.argmin(steps))
            raise ValueError(
                f"knots must increase strictly; knot {k + 1} = {knots[k + 1]:.6g} s follows "
                f"{knots[k]:.6g} s"
            )
        shape = (knots.size - 1, len(self.axes))
        for name, unit in (("alpha", "m/s^3"), ("beta", "m/s^2"), ("gamma", "m/s"), ("delta", "m")):
            c = np.array(getattr(self, name), dtype=float)
            if c.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {c.shape}")
            if not np.all(np.isfinite(c)):
                raise ValueError(f"{name} holds NaN or inf ({unit})")
            object.__setattr__(self, name, readonly(c))
        object.__setattr__(self, "knots", readonly(knots))
        if self.bc not in _BCS:
            raise ValueError(f"bc must be one of {_BCS}, got {self.bc!r}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def fit(
        cls,
        t_knots: np.ndarray,
        points: np.ndarray,
        bc: str = "clamped",
        end_velocity: np.ndarray | None = None,
        axes: tuple[str, ...] | None = None,
        rest_breaks: tuple[float, float] | None = None,
    ) -> TimeSpline:
        """The C² cubic spline through ``points`` at times ``t_knots``.

        Parameters
        ----------
        t_knots : array_like, shape (K + 1,)
            Strictly increasing times, s.
        points : array_like, shape (K + 1, n_axes)
            Positions to pass through, m.
        bc : {"clamped", "natural", "periodic", "rest"}
            ``"clamped"``: prescribed end velocities (``end_velocity``, zero by default,
            i.e. start and stop at rest); ``"natural"``: zero end accelerations;
            ``"periodic"``: value, slope and curvature wrap around (the first and last
            points must agree); ``"rest"``: zero velocity and zero acceleration at both
            ends. Four end conditions are two more than a cubic interpolating spline
            has free, so ``"rest"`` adds one breakpoint in the middle of the first and of
            the last interval (the thirds of the only interval when K = 1, or
            ``rest_breaks``); the spline's :attr:`knots` then hold these two extra times,
            and all points are still interpolated.
        end_velocity : array_like, optional
            Only with ``"clamped"``: velocities at the start and end, shape (2, n_axes)
            or (n_axes,) for both, m/s. Zero by default.
        axes : tuple of str, optional
            Axis names; ``("x", "y")`` for two axes, ``("q0", ...)`` otherwise.
        rest_breaks : tuple of float, optional
            Only with ``"rest"``: the two extra breakpoints, s, strictly inside the first
            and the last interval (e.g. where a jerk ramp ends); they must increase.

        Returns
        -------
        TimeSpline
        """
        t = np.array(t_knots, dtype=float)
        p = np.array(points, dtype=float)
        if p.ndim == 1:
            p = p[:, None]
        if t.ndim != 1 or t.size < 2:
            raise ValueError(f"t_knots must be a 1-D array of >= 2 times (s), got {t.shape}")
        if p.shape[0] != t.size:
            raise ValueError(f"points must have {t.size} rows (one per knot), got {p.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
            raise ValueError("t_knots (s) and points (m) must be finite")
        if not np.all(np.diff(t) > 0):
            raise ValueError("t_knots must increase strictly (s)")
        n_axes = p.shape[1]
        if axes is None:
            axes = ("x", "y") if n_axes == 2 else tuple(f"q{i}" for i in range(n_axes))
        if len(axes) != n_axes:
            raise ValueError(f"axes {axes} do not match {n_axes} point columns")
        if bc not in _BCS:
            raise ValueError(f"bc must be one of {_BCS}, got {bc!r}")
        if end_velocity is not None and bc != "clamped":
            raise ValueError(f"end_velocity (m/s) only applies to bc='clamped', not {bc!r}")
        if rest_breaks is not None and bc != "rest":
            raise ValueError(f"rest_breaks (s) only apply to bc='rest', not {bc!r}")

        if bc == "rest":
            return cls._fit_rest(t, p, tuple(axes), rest_breaks)
        if bc == "clamped":
            v = np.zeros((2, n_axes))
            if end_velocity is not None:
                v = np.broadcast_to(np.array(end_velocity, dtype=float), (2, n_axes)).copy()
                if not np.all(np.isfinite(v)):
                    raise ValueError(f"end_velocity must be finite (m/s), got {end_velocity!r}")
            cs = CubicSpline(t, p, axis=0, bc_type=((1, v[0]), (1, v[1])))
        elif bc == "natural":
            cs = CubicSpline(t, p, axis=0, bc_type="natural")
        else:
            scale = max(float(np.max(np.abs(p))), 1e-300)
            gap = float(np.max(np.abs(p[-1] - p[0])))
            if gap > 1e-9 * scale:
                raise ValueError(
                    f"bc='periodic' needs the last point equal to the first; they differ by "
                    f"{gap:.3g} m"
                )
            p = p.copy()
            p[-1] = p[0]
            cs = CubicSpline(t, p, axis=0, bc_type="periodic")
        c = np.asarray(cs.c)  # (4, K, n_axes), highest power first, local variable
        return cls(knots=t, alpha=c[0], beta=c[1], gamma=c[2], delta=c[3], axes=tuple(axes), bc=bc)

    @classmethod
    def _fit_rest(
        cls,
        t: np.ndarray,
        p: np.ndarray,
        axes: tuple[str, ...],
        rest_breaks: tuple[float, float] | None,
    ) -> TimeSpline:
        k = t.size - 1
        if rest_breaks is None:
            if k == 1:
                extra = (t[0] + (t[1] - t[0]) / 3.0, t[0] + 2.0 * (t[1] - t[0]) / 3.0)
            else:
                extra = (0.5 * (t[0] + t[1]), 0.5 * (t[-2] + t[-1]))
        else:
            extra = (float(rest_breaks[0]), float(rest_breaks[1]))
            if not (t[0] < extra[0] < t[1] and t[-2] < extra[1] < t[-1] and extra[0] < extra[1]):
                raise ValueError(
                    f"rest_breaks {extra} s must lie inside the first ({t[0]:.6g}, {t[1]:.6g}) "
                    f"and last ({t[-2]:.6g}, {t[-1]:.6g}) intervals, in order"
                )
        breaks = np.concatenate([[t[0], extra[0]], t[1:-1], [extra[1], t[-1]]])
        knot_vec = np.concatenate([[t[0]] * 3, breaks, [t[-1]] * 3])
        zero = np.zeros(p.shape[1])
        ends = [(1, zero), (2, zero)]
        b = make_interp_spline(t, p, k=3, t=knot_vec, bc_type=(ends, ends), axis=0)
        # coefficients from the derivatives at each piece's midpoint, shifted to its start
        h = np.diff(breaks)
        mid = breaks[:-1] + 0.5 * h
        d0, d1, d2, d3 = (b(mid, nu=m) for m in range(4))
        hh = (0.5 * h)[:, None]
        delta = d0 - d1 * hh + d2 * hh**2 / 2 - d3 * hh**3 / 6
        gamma = d1 - d2 * hh + d3 * hh**2 / 2
        beta = (d2 - d3 * hh) / 2
        alpha = d3 / 6
        return cls(
            knots=breaks, alpha=alpha, beta=beta, gamma=gamma, delta=delta, axes=axes, bc="rest"
        )

    @classmethod
    def concatenate(cls, splines: Sequence[TimeSpline]) -> TimeSpline:
        """Join splines end to end, each one's time shifted to start where the last ended.

        Parameters
        ----------
        splines : sequence of TimeSpline
            Pieces with the same axes; a spline's first point should equal the previous
            one's last (not checked beyond 1e-9 relative).

        Returns
        -------
        TimeSpline
        """
        if len(splines) == 0:
            raise ValueError("concatenate needs at least one spline")
        axes = splines[0].axes
        knots = [splines[0].knots]
        coef: list[list[np.ndarray]] = [[sp.alpha, sp.beta, sp.gamma, sp.delta] for sp in splines]
        t_end = float(splines[0].knots[-1])
        for prev, sp in pairwise(splines):
            if sp.axes != axes:
                raise ValueError(f"cannot join splines with axes {axes} and {sp.axes}")
            a, b = prev.evaluate(np.array([prev.knots[-1]]))[0], sp.delta[0]
            # relative to the size of the motion, not of the junction point (may be ~0)
            scale = max(float(np.max(np.abs(prev.delta))), float(np.max(np.abs(sp.delta))), 1e-300)
            if float(np.max(np.abs(a - b))) > 1e-9 * scale:
                raise ValueError(
                    f"splines do not join: end {a} m differs from the next start {b} m"
                )
            knots.append(sp.knots[1:] - sp.knots[0] + t_end)
            t_end = float(knots[-1][-1])
        bcs = {sp.bc for sp in splines}
        return cls(
            knots=np.concatenate(knots),
            alpha=np.concatenate([c[0] for c in coef]),
            beta=np.concatenate([c[1] for c in coef]),
            gamma=np.concatenate([c[2] for c in coef]),
            delta=np.concatenate([c[3] for c in coef]),
            axes=axes,
            bc="rest" if bcs == {"rest"} else "clamped",
        )

    # ------------------------------------------------------------------ evaluation
    @property
    def n_pieces(self) -> int:
        """Number of cubic pieces K."""
        return int(self.knots.size - 1)

    @property
    def duration(self) -> float:
        """``knots[-1] - knots[0]``, s."""
        return float(self.knots[-1] - self.knots[0])

    def piece_index(self, t: np.ndarray) -> np.ndarray:
        """Index of the piece holding each time (the right piece at a knot, the last at the end)."""
        tt = np.asarray(t, dtype=float)
        return np.clip(np.searchsorted(self.knots, tt, side="right") - 1, 0, self.n_pieces - 1)

    def evaluate(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Position or its ``order``-th time derivative at times ``t`` (seed 004 eq. (1)).

        Parameters
        ----------
        t : array_like, shape (n,)
            Times in ``[knots[0], knots[-1]]``, s (outside, the end pieces are extended).
        order : int
            0 position (m), 1 velocity (m/s), 2 acceleration (m/s²), 3 jerk (m/s³).

        Returns
        -------
        numpy.ndarray, shape (n, n_axes)
        """
        if order not in (0, 1, 2, 3):
            raise ValueError(f"order must be 0, 1, 2 or 3, got {order}")
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        i = self.piece_index(tt)
        tau = (tt - self.knots[i])[:, None]
        a, b, c, d = self.alpha[i], self.beta[i], self.gamma[i], self.delta[i]
        if order == 0:
            return ((a * tau + b) * tau + c) * tau + d
        if order == 1:
            return (3 * a * tau + 2 * b) * tau + c
        if order == 2:
            return 6 * a * tau + 2 * b
        return 6 * a + 0 * tau

    def piece_maxima(self) -> tuple[np.ndarray, ...]:
        """Exact maxima of |velocity|, |acceleration| and |jerk| on each piece.

        The velocity ``3αt² + 2βt + γ`` is extreme at the piece ends or at its vertex
        ``t = -β / (3α)`` when that lies inside; the acceleration ``6αt + 2β`` at the
        ends; the jerk ``6α`` is constant.

        Returns
        -------
        v, t_v, a, t_a, j, t_j : numpy.ndarray, shape (K, n_axes)
            Maxima (m/s, m/s², m/s³) and the absolute times where they occur, s.
        """
        h = np.diff(self.knots)[:, None]
        t0 = self.knots[:-1][:, None]
        a, b, c = self.alpha, self.beta, self.gamma
        v0 = np.abs(c)
        v1 = np.abs((3 * a * h + 2 * b) * h + c)
        with np.errstate(divide="ignore", invalid="ignore"):
            tv = np.where(a != 0, -b / (3 * a), -1.0)
            # vertex value 3a tv² + 2b tv + c with tv = -b / (3a) is c - b² / (3a)
            vertex = c - b * b / (3 * a)
        inside = (tv > 0) & (tv < h)
        vv = np.where(inside, np.abs(vertex), 0.0)
        stack = np.stack([v0, v1, vv])
        iv = np.argmax(stack, axis=0)
        v = np.take_along_axis(stack, iv[None], axis=0)[0]
        t_v = t0 + np.choose(
            iv, [np.zeros_like(a), np.broadcast_to(h, a.shape), np.where(inside, tv, 0.0)]
        )
        a0 = np.abs(2 * b)
        a1 = np.abs(6 * a * h + 2 * b)
        acc = np.maximum(a0, a1)
        t_a = t0 + np.where(a1 > a0, h, 0.0)
        jerk = np.abs(6 * a)
        t_j = t0 + 0 * a
        return v, t_v, acc, t_a, jerk, t_j

    def max_abs(self) -> SplineMaxima:
        """Exact per-axis maxima of |velocity|, |acceleration| and |jerk| over the spline."""
        v, t_v, a, t_a, j, t_j = self.piece_maxima()
        cols = np.arange(v.shape[1])
        iv, ia, ij = (np.argmax(x, axis=0) for x in (v, a, j))
        return SplineMaxima(
            velocity=readonly(v[iv, cols]),
            velocity_time=readonly(t_v[iv, cols]),
            acceleration=readonly(a[ia, cols]),
            acceleration_time=readonly(t_a[ia, cols]),
            jerk=readonly(j[ij, cols]),
            jerk_time=readonly(t_j[ij, cols]),
        )

    def scaled_time(self, factor: float) -> TimeSpline:
        """The same curve traversed ``factor`` times slower (time stretched by ``factor``).

        Velocity scales by ``1/factor``, acceleration by ``1/factor²``, jerk by
        ``1/factor³``.
        """
        f = check_positive("time scale factor", factor)
        return TimeSpline(
            knots=self.knots[0] + (self.knots - self.knots[0]) * f,
            alpha=self.alpha / f**3,
            beta=self.beta / f**2,
            gamma=self.gamma / f,
            delta=self.delta,
            axes=self.axes,
            bc=self.bc,
            meta=dict(self.meta),
        )

    # ------------------------------------------------------------------ sampling
    def sample(
        self,
        sample_rate_hz: float,
        s_knots: np.ndarray | None = None,
        s_times: np.ndarray | None = None,
    ) -> Trajectory:
        """Sample on a uniform time grid, with analytic velocity, acceleration and jerk.

        The samples are exactly ``dt = 1 / sample_rate_hz`` apart (a machine's controller runs
        at its own rate) from ``knots[0]`` until the first sample at or after the last
        knot, ``n = ceil(T * sample_rate_hz) + 1`` samples; a sample past the end holds the end
        point (the spline is evaluated at ``knots[-1]``), so the machine ends exactly on
        the last point. For ``bc="periodic"`` the trajectory is one period: ``n =
        round(T * sample_rate_hz)`` samples, ``dt = T / n`` (one period must span whole samples),
        the end (equal to the start) left out, and ``at_rest`` is ``False``.

        Parameters
        ----------
        sample_rate_hz : float
            Nominal sample rate, Hz.
        s_knots : array_like, optional
            Path progress (m) at ``s_times``, interpolated monotonically (PCHIP) onto the
            samples and stored as ``Trajectory.s``.
        s_times : array_like, optional
            Times of ``s_knots``, s; the spline's knots by default.

        Returns
        -------
        microfab.trajectory.base.Trajectory

        Raises
        ------
        ValueError
            A rate that is not positive and finite, or more than
            `~microfab.trajectory.base.MAX_SAMPLES` samples.
        """
        check_positive("sample_rate_hz", sample_rate_hz, "Hz")
        T = self.duration
        if not T * sample_rate_hz <= MAX_SAMPLES:
            raise ValueError(
                f"{T * sample_rate_hz:.3g} samples ({T:.3g} s at {sample_rate_hz:g} Hz) is more "
                f"than the {MAX_SAMPLES:,} a reference may hold: lower the sample rate"
            )
        periodic = self.bc == "periodic"
        if periodic:
            n = max(round(T * sample_rate_hz), 1)
            dt = T / n
            t = self.knots[0] + np.arange(n) * dt
        else:
            dt = 1.0 / sample_rate_hz
            n = max(int(np.ceil(T * sample_rate_hz * (1 - 1e-12))), 1) + 1
            t = np.minimum(self.knots[0] + np.arange(n) * dt, self.knots[-1])
        s = None
        if s_knots is not None:
            ts = self.knots if s_times is None else np.asarray(s_times, dtype=float)
            sk = np.asarray(s_knots, dtype=float)
            if sk.shape != ts.shape:
                raise ValueError(
                    f"s_knots must have shape {ts.shape} (one per time), got {sk.shape}"
                )
            s = PchipInterpolator(ts, sk)(t)
        # a non-periodic spline is checked as starting and ending at rest: one that does
        # not (e.g. bc="natural") is then rightly refused by check_trajectory
        at_rest = not periodic
        return Trajectory(
            dt=dt,
            position=self.evaluate(t, 0),
            velocity=self.evaluate(t, 1),
            acceleration=self.evaluate(t, 2),
            jerk=self.evaluate(t, 3),
            s=s,
            axes=self.axes,
            at_rest=at_rest,
            meta={
                "generator": "TimeSpline",
                "bc": self.bc,
                "sample_rate_hz": float(sample_rate_hz),
            },
        )
