"""Exact planar curve segments: straight lines, circular arcs and polynomial curves.

Every segment maps a local arc length ``σ ∈ [0, length]`` to a point. Three kinds cover
all sources exactly:

- :class:`LineSegment` — DXF LINE, polyline edges, SVG ``L``;
- :class:`ArcSegment` — DXF ARC/CIRCLE, bulged polyline edges;
- :class:`CurveSegment` — a polynomial curve ``f(u), u ∈ [0, 1]`` held as Chebyshev
  coefficients. Bézier curves (fonts, SVG, DXF splines) convert to it exactly; any other
  smooth parametric curve (ellipse, spiral, Lissajous, rational spline) is approximated by
  adaptive Chebyshev interpolation to ~1e-13 relative (:meth:`CurveSegment.from_function`).

A curve's arc length is tabulated once with 16 panels of 10-point Gauss–Legendre
quadrature; the inverse ``u(σ)`` is found by Newton's method on that table (see
:mod:`microfab.geometry.path`, which evaluates many segments at once).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.polynomial import chebyshev as cheb

from microfab.core.validate import check_finite, check_positive

__all__ = [
    "ArcSegment",
    "CurveSegment",
    "LineSegment",
    "Segment",
    "bulge_arc_numbers",
    "segment_bbox",
    "segment_reach",
]

GL_X, GL_W = np.polynomial.legendre.leggauss(10)
N_PANELS = 16
_FIT_DEGREES = (8, 16, 32, 64)


def cheb_fit2(x: np.ndarray, vals: np.ndarray, deg: int) -> np.ndarray:
    """Chebyshev coefficients (deg + 1, 2) interpolating 2-D points ``vals`` at nodes ``x``."""
    return np.column_stack([cheb.chebfit(x, vals[:, 0], deg), cheb.chebfit(x, vals[:, 1], deg)])


def _vec2(p: object, name: str) -> np.ndarray:
    a = np.array(p, dtype=float)
    if a.shape != (2,):
        a = a.reshape(-1)
    if a.shape != (2,) or not (math.isfinite(a[0]) and math.isfinite(a[1])):
        raise ValueError(f"{name} must be a finite 2-vector (m), got {p!r}")
    a.flags.writeable = False
    return a


_MAX_SCALE = 1e150  # largest entry of an affine map: its square stays finite


def _affine(A: object, b: object) -> tuple[np.ndarray, np.ndarray]:
    Am = np.asarray(A, dtype=float).reshape(2, 2)
    bv = np.asarray(b, dtype=float).reshape(2)
    if not (np.all(np.isfinite(Am)) and np.all(np.isfinite(bv))):
        raise ValueError("transform must be finite")
    if np.max(np.abs(Am)) > _MAX_SCALE:  # A^T A, and the images, would overflow
        raise ValueError(
            f"transform overflows: it scales by up to {np.max(np.abs(Am)):.3g} "
            f"(at most {_MAX_SCALE:g})"
        )
    if abs(np.linalg.det(Am)) < 1e-300:
        raise ValueError("transform is singular")
    return Am, bv


@dataclass(frozen=True, eq=False)
class LineSegment:
    """A straight segment from ``p0`` to ``p1`` (m)."""

    p0: np.ndarray
    p1: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "p0", _vec2(self.p0, "p0"))
        object.__setattr__(self, "p1", _vec2(self.p1, "p1"))

    @classmethod
    def many(cls, coords: np.ndarray) -> list[LineSegment]:
        """Segments from rows ``x0, y0, x1, y1`` (m), made in one go (a drawing's lines).

        The end points are read-only views of one copy of ``coords``.

        Raises
        ------
        ValueError
            If a coordinate is not finite, or ``coords`` is not shaped (n, 4).
        """
        c = np.array(coords, dtype=float)
        if c.ndim != 2 or c.shape[1] != 4:
            raise ValueError(f"coords must be shaped (n, 4), got {c.shape}")
        if not np.all(np.isfinite(c)):
            i = int(np.flatnonzero(~np.all(np.isfinite(c), axis=1))[0])
            raise ValueError(f"line {i}: end points must be finite (m), got {c[i].tolist()}")
        c.flags.writeable = False
        new = cls._unchecked
        return [new(a, b) for a, b in zip(c[:, :2], c[:, 2:], strict=True)]

    @classmethod
    def _unchecked(cls, p0: np.ndarray, p1: np.ndarray) -> LineSegment:
        """A segment on end points that are already finite, read-only (2,) float arrays."""
        seg = object.__new__(cls)
        attrs = seg.__dict__  # frozen: set the fields as the dataclass' own __init__ would
        attrs["p0"] = p0
        attrs["p1"] = p1
        return seg

    @property
    def start(self) -> np.ndarray:
        """Start point, m."""
        return self.p0

    @property
    def end(self) -> np.ndarray:
        """End point, m."""
        return self.p1

    @cached_property
    def length(self) -> float:
        """Length, m."""
        return math.hypot(self.p1[0] - self.p0[0], self.p1[1] - self.p0[1])

    def reversed(self) -> LineSegment:
        """The same segment traversed backwards (sharing the read-only end points)."""
        return LineSegment._unchecked(self.p1, self.p0)

    def transformed(self, A: object, b: object = (0.0, 0.0)) -> LineSegment:
        """Image under ``p -> A p + b``."""
        Am, bv = _affine(A, b)
        return LineSegment(Am @ self.p0 + bv, Am @ self.p1 + bv)


@dataclass(frozen=True, eq=False)
class ArcSegment:
    """A circular arc.

    Parameters
    ----------
    center : array_like, shape (2,)
        Centre, m.
    radius : float
        Radius, m, positive.
    theta0 : float
        Angle of the start point from the centre, rad.
    sweep : float
        Signed swept angle, rad: positive counter-clockwise, ``|sweep| <= 2π``.
    """

    center: np.ndarray
    radius: float
    theta0: float
    sweep: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec2(self.center, "center"))
        r, s = check_positive("arc radius", self.radius, "m"), float(self.sweep)
        if not (np.isfinite(s) and s != 0 and abs(s) <= 2 * np.pi * (1 + 1e-12)):
            raise ValueError(f"arc sweep must be nonzero and within ±2π, got {self.sweep} rad")
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "sweep", s)
        object.__setattr__(self, "theta0", check_finite("arc theta0", self.theta0, "rad"))

    @classmethod
    def from_bulge(cls, p0: object, p1: object, bulge: float) -> ArcSegment:
        """Arc from ``p0`` to ``p1`` with a DXF bulge ``tan(sweep / 4)`` (positive: CCW)."""
        (ax, ay), (bx, by) = _vec2(p0, "p0").tolist(), _vec2(p1, "p1").tolist()
        return cls._from_bulge(ax, ay, bx, by, float(bulge))

    @classmethod
    def _from_bulge(cls, ax: float, ay: float, bx: float, by: float, bulge: float) -> ArcSegment:
        """`from_bulge` on end points that are finite floats."""
        if bulge == 0:
            raise ValueError("a bulge of 0 is a straight segment, not an arc")
        if not math.isfinite(bulge):
            raise ValueError(f"a bulge must be finite, got {bulge!r}")
        # coordinate by coordinate: the same operations as on 2-vectors, without their cost
        chx, chy = bx - ax, by - ay
        c = float(np.hypot(chx, chy))
        if c == 0:
            raise ValueError("a bulged segment needs distinct end points")
        sweep = float(4.0 * np.arctan(bulge))
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # checked below
            radius = float(c / (2.0 * abs(np.sin(sweep / 2.0))))
            # centre: from the chord midpoint along the left normal by the signed apothem
            apothem = float(c / 2.0 / np.tan(sweep / 2.0))
            cx = (ax + bx) / 2.0 + apothem * (-chy / c)
            cy = (ay + by) / 2.0 + apothem * (chx / c)
        if not (math.isfinite(radius) and math.isfinite(cx) and math.isfinite(cy)):
            raise ValueError(f"bulge {bulge!r} is too small for an arc: its radius overflows")
        theta0 = float(np.arctan2(ay - cy, ax - cx))
        return cls.from_numbers(cx, cy, radius, theta0, sweep)

    @classmethod
    def _many_checked(
        cls, center: np.ndarray, radius: np.ndarray, theta0: np.ndarray, sweep: np.ndarray
    ) -> list[ArcSegment]:
        """Arcs from rows of numbers that `from_numbers` accepts, made in one go.

        ``center`` (m, 2), m; ``radius``, ``theta0``, ``sweep`` (m,). The centres are
        read-only views of one copy of ``center``.
        """
        c = np.array(center, dtype=float).reshape(-1, 2)
        c.flags.writeable = False
        out = []
        new = object.__new__
        for cen, r, t0, sw in zip(c, radius.tolist(), theta0.tolist(), sweep.tolist(), strict=True):
            arc = new(cls)
            attrs = arc.__dict__  # checked as __post_init__ does: set the fields
            attrs["center"], attrs["radius"], attrs["theta0"], attrs["sweep"] = cen, r, t0, sw
            out.append(arc)
        return out

    @classmethod
    def from_numbers(
        cls, cx: float, cy: float, radius: float, theta0: float, sweep: float
    ) -> ArcSegment:
        """`ArcSegment((cx, cy), radius, theta0, sweep)` from plain numbers, checked alike.

        The fast way to make many arcs (a drawing's arcs and circles).
        """
        cx, cy, radius, theta0, sweep = (float(v) for v in (cx, cy, radius, theta0, sweep))
        ok = math.isfinite(cx) and math.isfinite(cy) and math.isfinite(radius) and radius > 0
        if not (ok and math.isfinite(theta0) and 0 < abs(sweep) <= 2 * np.pi * (1 + 1e-12)):
            return cls((cx, cy), radius, theta0, sweep)  # raises the constructor's error
        center = np.array((cx, cy))
        center.flags.writeable = False
        arc = object.__new__(cls)
        attrs = arc.__dict__  # checked as __post_init__ does: set the fields
        attrs["center"], attrs["radius"], attrs["theta0"], attrs["sweep"] = (
            center,
            radius,
            theta0,
            sweep,
        )
        return arc

    @cached_property
    def start(self) -> np.ndarray:
        """Start point, m."""
        return self.center + self.radius * np.array([np.cos(self.theta0), np.sin(self.theta0)])

    @cached_property
    def end(self) -> np.ndarray:
        """End point, m."""
        t = self.theta0 + self.sweep
        return self.center + self.radius * np.array([np.cos(t), np.sin(t)])

    @cached_property
    def length(self) -> float:
        """Length, m."""
        return self.radius * abs(self.sweep)

    def reversed(self) -> ArcSegment:
        """The same arc traversed backwards."""
        return ArcSegment(self.center, self.radius, self.theta0 + self.sweep, -self.sweep)

    def transformed(self, A: object, b: object = (0.0, 0.0)) -> ArcSegment | CurveSegment:
        """Image under ``p -> A p + b``; an arc stays an arc under a similarity.

        A non-uniform scale turns the arc into an elliptical arc, returned as a
        :class:`CurveSegment` (Chebyshev approximation, ~1e-13 relative).
        """
        parts = self.transformed_pieces(A, b)
        if len(parts) == 1:
            return parts[0]
        # keep one segment: refit the whole elliptic arc at the finest degree
        Am, bv = _affine(A, b)
        x = np.cos(np.pi * (np.arange(65) + 0.5) / 65)
        return CurveSegment(cheb_fit2(x, self._mapped(Am, bv)((x + 1) / 2), 64))

    def _mapped(self, Am: np.ndarray, bv: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        c, r, t0, sw = self.center, self.radius, self.theta0, self.sweep

        def f(u: np.ndarray) -> np.ndarray:
            t = t0 + u * sw
            p = c + r * np.column_stack([np.cos(t), np.sin(t)])
            return p @ Am.T + bv

        return f

    def transformed_pieces(
        self, A: object, b: object = (0.0, 0.0)
    ) -> list[ArcSegment] | list[CurveSegment]:
        """Image under ``p -> A p + b`` as one arc, or as elliptic curve pieces."""
        Am, bv = _affine(A, b)
        g = Am.T @ Am
        k2 = 0.5 * (g[0, 0] + g[1, 1])
        if abs(g[0, 0] - g[1, 1]) <= 1e-12 * k2 and abs(g[0, 1]) <= 1e-12 * k2:
            k = float(np.sqrt(k2))
            mirror = np.linalg.det(Am) < 0
            c = Am @ self.center + bv
            s0 = Am @ self.start + bv
            theta0 = float(np.arctan2(s0[1] - c[1], s0[0] - c[0]))
            return [ArcSegment(c, self.radius * k, theta0, -self.sweep if mirror else self.sweep)]
        return CurveSegment.from_function(self._mapped(Am, bv))


def bulge_arc_numbers(
    p0: np.ndarray, p1: np.ndarray, bulge: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The numbers of the arcs `ArcSegment.from_bulge` makes, many at once.

    The same operations as `ArcSegment.from_bulge`, element by element, so the same
    numbers to the bit.

    Parameters
    ----------
    p0, p1 : numpy.ndarray
        Start and end points, shape (m, 2), m.
    bulge : numpy.ndarray
        DXF bulges ``tan(sweep / 4)``, shape (m,).

    Returns
    -------
    center : numpy.ndarray
        Shape (m, 2), m.
    radius, theta0, sweep : numpy.ndarray
        Shape (m,): m, rad, rad.
    ok : numpy.ndarray of bool
        Shape (m,): where `ArcSegment.from_bulge` makes the arc (elsewhere it raises, and
        the numbers are meaningless).
    """
    ax, ay, bx, by = p0[:, 0], p0[:, 1], p1[:, 0], p1[:, 1]
    w = bulge
    chx, chy = bx - ax, by - ay
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # checked below
        c = np.hypot(chx, chy)
        sweep = 4.0 * np.arctan(w)
        radius = c / (2.0 * np.abs(np.sin(sweep / 2.0)))
        apothem = c / 2.0 / np.tan(sweep / 2.0)
        center = np.empty((w.size, 2))
        center[:, 0] = (ax + bx) / 2.0 + apothem * (-chy / c)
        center[:, 1] = (ay + by) / 2.0 + apothem * (chx / c)
        theta0 = np.arctan2(ay - center[:, 1], ax - center[:, 0])
        ok = (
            np.isfinite(p0).all(axis=1)
            & np.isfinite(p1).all(axis=1)
            & np.isfinite(w)
            & (w != 0)
            & (c != 0)
            & np.isfinite(radius)
            & (radius > 0)
            & np.isfinite(center).all(axis=1)
            & np.isfinite(theta0)
            & (sweep != 0)
            & (np.abs(sweep) <= 2 * np.pi * (1 + 1e-12))
        )
    return center, radius, theta0, sweep, ok


def _bezier_to_cheb(ctrl: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients on u ∈ [0, 1] (x = 2u − 1) of a Bézier curve.

    A degree-d polynomial is fixed by d + 1 values: interpolate at Chebyshev points
    (well conditioned), evaluating the Bézier curve in the Bernstein basis.
    """
    from math import comb

    d = ctrl.shape[0] - 1
    x = np.cos(np.pi * (np.arange(d + 1) + 0.5) / (d + 1))
    u = (x + 1.0) / 2.0
    k = np.arange(d + 1)
    binom = np.array([comb(d, int(i)) for i in k], dtype=float)
    bern = binom * u[:, None] ** k * (1.0 - u[:, None]) ** (d - k)
    vals = bern @ ctrl
    return cheb_fit2(x, vals, d)


@dataclass(frozen=True, eq=False)
class CurveSegment:
    """A polynomial curve ``f(u), u ∈ [0, 1]``, from ``f(0)`` to ``f(1)``.

    Parameters
    ----------
    coef : array_like, shape (degree + 1, 2)
        Chebyshev coefficients of x(u) and y(u) in the variable ``2u − 1``, m.
    """

    coef: np.ndarray

    def __post_init__(self) -> None:
        c = np.array(self.coef, dtype=float)
        if c.ndim != 2 or c.shape[1] != 2 or c.shape[0] < 2 or not np.all(np.isfinite(c)):
            raise ValueError(f"coef must be a finite (degree + 1, 2) array, got {c.shape}")
        c.setflags(write=False)
        object.__setattr__(self, "coef", c)

    @classmethod
    def from_bezier(cls, ctrl: object) -> CurveSegment:
        """Exact conversion of a Bézier curve with control points ``ctrl`` (d + 1, 2), m."""
        P = np.asarray(ctrl, dtype=float)
        if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] < 2 or not np.all(np.isfinite(P)):
            raise ValueError(f"Bézier control points must be finite (n >= 2, 2), got {P.shape}")
        return cls(_bezier_to_cheb(P))

    @classmethod
    def from_function(
        cls,
        f: Callable[[np.ndarray], np.ndarray],
        rtol: float = 1e-13,
        max_pieces: int = 4096,
    ) -> list[CurveSegment]:
        """Approximate a smooth curve ``f(u) -> (n, 2)`` on ``u ∈ [0, 1]``.

        Chebyshev interpolation of increasing degree (8 … 128) until the trailing
        coefficients fall below ``rtol`` times the curve's size; pieces that do not
        converge are halved. The pieces join with C∞ continuity up to ``rtol``.

        Returns
        -------
        list of CurveSegment
            Consecutive pieces covering ``[0, 1]``.
        """
        out: list[CurveSegment] = []
        stack = [(0.0, 1.0)]
        scale = float(np.max(np.abs(f(np.linspace(0.0, 1.0, 33))))) or 1.0
        while stack:
            a, b = stack.pop()
            if len(out) + len(stack) > max_pieces:
                raise ValueError("curve needs too many pieces; is it smooth on [0, 1]?")
            piece = _fit_piece(f, a, b, rtol * scale)
            if piece is None or not piece.quadrature_converged(rtol=max(rtol, 1e-13)):
                m = 0.5 * (a + b)
                stack.extend([(m, b), (a, m)])
            else:
                out.append(piece)
        # the stack pops the left half first, so pieces come out in order
        return out

    @property
    def degree(self) -> int:
        """Polynomial degree."""
        return int(self.coef.shape[0] - 1)

    def point(self, u: np.ndarray) -> np.ndarray:
        """``f(u)``, shape (n, 2)."""
        x = 2.0 * np.asarray(u, dtype=float) - 1.0
        with np.errstate(over="ignore", invalid="ignore"):  # absurd curves: inf, refused later
            return np.column_stack(
                [cheb.chebval(x, self.coef[:, 0]), cheb.chebval(x, self.coef[:, 1])]
            )

    @cached_property
    def derivative_coefs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Chebyshev coefficients of ``f'``, ``f''``, ``f'''`` with respect to u."""
        out = []
        c = self.coef
        for _ in range(3):
            with np.errstate(over="ignore", invalid="ignore"):  # inf: refused where used
                c = 2.0 * cheb.chebder(c, axis=0) if c.shape[0] > 1 else np.zeros((1, 2))
            out.append(c)
        return out[0], out[1], out[2]

    @cached_property
    def start(self) -> np.ndarray:
        """Start point, m."""
        return self.point(np.array([0.0]))[0]

    @cached_property
    def end(self) -> np.ndarray:
        """End point, m."""
        return self.point(np.array([1.0]))[0]

    def speed(self, u: np.ndarray) -> np.ndarray:
        """``|f'(u)|``, m per unit u."""
        d1 = self.derivative_coefs[0]
        x = 2.0 * np.asarray(u, dtype=float) - 1.0
        return np.hypot(cheb.chebval(x, d1[:, 0]), cheb.chebval(x, d1[:, 1]))

    @cached_property
    def length_table(self) -> np.ndarray:
        """Arc length at ``u = j / 16``, j = 0 … 16, m (Gauss–Legendre per panel)."""
        edges = np.linspace(0.0, 1.0, N_PANELS + 1)
        h = np.diff(edges)
        nodes = edges[:-1, None] + h[:, None] * (GL_X[None, :] + 1.0) / 2.0
        sp = self.speed(nodes.ravel()).reshape(nodes.shape)
        panel = (sp * GL_W[None, :]).sum(axis=1) * h / 2.0
        table = np.concatenate([[0.0], np.cumsum(panel)])
        table.setflags(write=False)
        return table

    @cached_property
    def length(self) -> float:
        """Length, m."""
        return float(self.length_table[-1])

    def quadrature_converged(self, rtol: float = 1e-13) -> bool:
        """Whether the 16-panel length table agrees with a 64-panel one to ``rtol``."""
        edges = np.linspace(0.0, 1.0, 4 * N_PANELS + 1)
        h = np.diff(edges)
        nodes = edges[:-1, None] + h[:, None] * (GL_X[None, :] + 1.0) / 2.0
        sp = self.speed(nodes.ravel()).reshape(nodes.shape)
        fine = np.cumsum((sp * GL_W[None, :]).sum(axis=1) * h / 2.0)[3::4]
        return bool(np.max(np.abs(fine - self.length_table[1:])) <= rtol * max(fine[-1], 1e-300))

    def reversed(self) -> CurveSegment:
        """The same curve traversed backwards (``u -> 1 − u``)."""
        sign = (-1.0) ** np.arange(self.coef.shape[0])
        return CurveSegment(self.coef * sign[:, None])

    def transformed(self, A: object, b: object = (0.0, 0.0)) -> CurveSegment:
        """Image under ``p -> A p + b`` (exact: the polynomial's coefficients transform)."""
        Am, bv = _affine(A, b)
        c = self.coef @ Am.T
        c[0] += bv
        return CurveSegment(c)


def _fit_piece(
    f: Callable[[np.ndarray], np.ndarray], a: float, b: float, atol: float
) -> CurveSegment | None:
    """Chebyshev interpolant of f on [a, b] with trailing coefficients below atol, or None."""
    for deg in _FIT_DEGREES:
        x = np.cos(np.pi * (np.arange(deg + 1) + 0.5) / (deg + 1))
        vals = np.asarray(f(a + (b - a) * (x + 1) / 2), dtype=float)
        if vals.shape != (deg + 1, 2) or not np.all(np.isfinite(vals)):
            raise ValueError("curve function must return finite (n, 2) points")
        coef = cheb_fit2(x, vals, deg)
        if np.max(np.abs(coef[-3:])) <= atol:
            keep = np.nonzero(np.max(np.abs(coef), axis=1) > 0.1 * atol)[0]
            n = max(int(keep[-1]) + 1 if keep.size else 2, 2)
            return CurveSegment(coef[:n])
    return None


Segment = LineSegment | ArcSegment | CurveSegment


#: Below this reach (m) a segment's length cannot overflow: a line's is at most 2√2 times
#: its reach, an arc's 2π(1 + 1e-12) times, a degree-d curve's at most 2√2 d² times
#: (Markov's bound on the derivative of a polynomial bounded by the reach on [-1, 1]), so
#: `segment_reach` does not compute it (a curve's length needs its quadrature).
_REACH_LENGTH_SAFE = 1e150


def segment_reach(seg: Segment) -> float:
    """An upper bound of ``max(|x|, |y|)`` over a segment, m; inf when not finite.

    Cheap (no sampling): the end points of a line, the centre plus the radius of an arc,
    the sum of the Chebyshev coefficients' magnitudes of a curve (``|T_k| <= 1``). Also
    inf when the segment's length is not finite, which only a reach beyond 1e150 m allows.
    """
    # plain floats: this runs once per DXF entity and per contour, keep it cheap
    if isinstance(seg, ArcSegment):
        cx, cy = seg.center.tolist()
        r = max(abs(cx), abs(cy)) + seg.radius
    elif isinstance(seg, CurveSegment):
        r = float(np.max(np.sum(np.abs(seg.coef), axis=0)))
    else:  # a line
        (a, b), (c, d) = seg.start.tolist(), seg.end.tolist()
        r = max(abs(a), abs(b), abs(c), abs(d))
    if r <= _REACH_LENGTH_SAFE:
        return r
    return r if math.isfinite(r) and math.isfinite(seg.length) else float("inf")


def segment_bbox(seg: Segment) -> tuple[float, float, float, float]:
    """Exact bounding box ``(xmin, ymin, xmax, ymax)`` of a segment, m.

    No sampling: the end points plus, for an arc, the axis crossings of the circle inside
    its sweep, and for a curve, the real roots of ``dx/du`` and ``dy/du`` in ``[0, 1]``
    (``numpy.polynomial.chebyshev.chebroots``).
    """
    pts = [seg.start, seg.end]
    if isinstance(seg, ArcSegment):
        lo, hi = sorted((seg.theta0, seg.theta0 + seg.sweep))
        k = np.arange(np.ceil(lo / (np.pi / 2)), np.floor(hi / (np.pi / 2)) + 1)
        t = k * np.pi / 2
        pts.append(seg.center + seg.radius * np.column_stack([np.cos(t), np.sin(t)]))
    elif isinstance(seg, CurveSegment):
        d1 = seg.derivative_coefs[0]
        for dim in range(2):
            c = cheb.chebtrim(d1[:, dim])
            if c.size < 2 or not np.all(np.isfinite(c)):
                continue
            roots = cheb.chebroots(c)
            x = roots.real[(np.abs(roots.imag) <= 1e-9) & (np.abs(roots.real) <= 1.0)]
            if x.size:
                pts.append(seg.point((x + 1.0) / 2.0))
    p = np.vstack([np.reshape(q, (-1, 2)) for q in pts])
    return (
        float(p[:, 0].min()),
        float(p[:, 1].min()),
        float(p[:, 0].max()),
        float(p[:, 1].max()),
    )
