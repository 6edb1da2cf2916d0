"""Parametric shapes as exact paths: rectangles, circles, polygons, spirals and more.

Lines and circular arcs are exact; the spiral, Lissajous, butterfly and ellipse are
Chebyshev-interpolated to ~1e-13 relative (:meth:`CurveSegment.from_function`). All
sizes are in metres, angles in radians. :data:`SHAPES` maps a name to its builder, for
the command line (``microfab path show circle:radius=0.01``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from microfab.core.validate import check_finite, check_in_range, check_positive
from microfab.geometry.path import Path
from microfab.geometry.segments import ArcSegment, CurveSegment, LineSegment, Segment

__all__ = [
    "MAX_LOBES",
    "MAX_SIDES",
    "MAX_TURNS",
    "SHAPES",
    "butterfly",
    "circle",
    "ellipse",
    "lissajous",
    "parse_shape",
    "rectangle",
    "regular_polygon",
    "spiral",
    "spiral_length",
    "square",
    "star",
]


#: Most sides of a regular polygon (more is a circle: use ``circle``).
MAX_SIDES = 10_000
#: Most turns of a spiral (its end angle, theta1, at most this many times 2 pi).
MAX_TURNS = 100
#: Largest frequency of a Lissajous curve.
MAX_LOBES = 50


def rectangle(
    width: float,
    height: float,
    *,
    corner_radius: float = 0.0,
    center: tuple[float, float] = (0.0, 0.0),
) -> Path:
    """A rectangle, counter-clockwise from the middle of its bottom edge.

    Parameters
    ----------
    width, height : float
        Side lengths, m.
    corner_radius : float
        Radius of the rounded corners, m (0 for sharp corners, at most half the shorter
        side).
    center : tuple of float
        Centre, m.
    """
    w, h = check_positive("width", width, "m"), check_positive("height", height, "m")
    r = check_in_range("corner_radius", corner_radius, 0.0, 0.5 * min(w, h), "m")
    cx, cy = (float(c) for c in center)
    a, b = w / 2, h / 2
    corners = [(a, -b), (a, b), (-a, b), (-a, -b)]
    segs: list[Segment] = []
    start = np.array([cx, cy - b])
    p = start
    for k, (qx, qy) in enumerate(corners):
        # edge towards the corner, stopping r before it, then the corner arc
        ang = np.pi / 2 * k  # direction of travel along this edge: 0, 90, 180, 270 degrees
        d = np.array([np.cos(ang), np.sin(ang)]).round(15)
        corner = np.array([cx + qx, cy + qy])
        edge_end = corner - r * d
        if np.hypot(*(edge_end - p)) > 0:
            segs.append(LineSegment(p, edge_end))
        if r > 0:
            n = np.array([-d[1], d[0]])
            segs.append(ArcSegment(edge_end + r * n, r, ang - np.pi / 2, np.pi / 2))
            p = corner + r * n
        else:
            p = corner
    if np.hypot(*(start - p)) > 0:
        segs.append(LineSegment(p, start))
    return Path(tuple(segs), closed=True)


def square(
    side: float, *, corner_radius: float = 0.0, center: tuple[float, float] = (0, 0)
) -> Path:
    """A square of side ``side`` (m); see :func:`rectangle`."""
    return rectangle(side, side, corner_radius=corner_radius, center=center)


def circle(radius: float, *, center: tuple[float, float] = (0.0, 0.0), theta0: float = 0.0) -> Path:
    """A circle, counter-clockwise from angle ``theta0`` (rad)."""
    r = check_positive("radius", radius, "m")
    return Path((ArcSegment(center, r, theta0, 2 * np.pi),), closed=True)


def regular_polygon(
    n_sides: int, radius: float, *, center: tuple[float, float] = (0.0, 0.0), theta0: float = 0.0
) -> Path:
    """A regular polygon: ``n_sides`` (3 to `MAX_SIDES`) vertices on a circle of ``radius``."""
    if not (3 <= n_sides <= MAX_SIDES and int(n_sides) == n_sides):
        raise ValueError(f"n_sides must be an integer from 3 to {MAX_SIDES}, got {n_sides}")
    n = int(n_sides)
    r = check_positive("radius", radius, "m")
    th = theta0 + 2 * np.pi * np.arange(n) / n
    pts = np.column_stack([center[0] + r * np.cos(th), center[1] + r * np.sin(th)])
    return Path.polyline(pts, closed=True)


def star(
    points: int,
    radius: float,
    *,
    inner_radius: float | None = None,
    center: tuple[float, float] = (0.0, 0.0),
) -> Path:
    """A star of ``points`` sharp tips on a circle of ``radius`` (m), no fillets.

    The inner corners lie on ``inner_radius`` (default ``0.4 radius``, a star whose
    edges run tip to tip for five points, about); the first tip points along +y.
    """
    if not (3 <= points <= MAX_SIDES // 2 and int(points) == points):
        raise ValueError(f"points must be an integer from 3 to {MAX_SIDES // 2}, got {points}")
    r_out = check_positive("radius", radius, "m")
    r_in = (
        0.4 * r_out if inner_radius is None else check_positive("inner_radius", inner_radius, "m")
    )
    if not r_in < r_out:
        raise ValueError(f"inner_radius must be below radius ({r_out:g} m), got {r_in:g} m")
    n = 2 * int(points)
    th = np.pi / 2 + np.pi * np.arange(n) / points
    rad = np.where(np.arange(n) % 2 == 0, r_out, r_in)
    pts = np.column_stack([center[0] + rad * np.cos(th), center[1] + rad * np.sin(th)])
    return Path.polyline(pts, closed=True)


def _curve(f: Callable[[np.ndarray], np.ndarray], closed: bool) -> Path:
    # an absurd scale overflows inside ``f``: no warning printed, the segment's own check
    # refuses the non-finite points it returns
    with np.errstate(over="ignore", invalid="ignore"):
        segs = CurveSegment.from_function(f)
    if closed:
        # the pieces' ends agree to ~1e-13; close exactly on the first point
        return Path(tuple(segs), closed=True, gap_tol=1e-9 * _size(segs))
    return Path(tuple(segs))


def _size(segs: list[CurveSegment]) -> float:
    pts = np.vstack([s.point(np.linspace(0, 1, 9)) for s in segs])
    return float(np.max(np.ptp(pts, axis=0))) + 1e-300


def spiral(b: float = 50e-3 / (2 * np.pi), theta0: float = 0.0, theta1: float = 4 * np.pi) -> Path:
    """The Archimedean spiral ``r = b θ`` for ``θ ∈ [theta0, theta1]`` (open).

    The default is seed 002 Fig. 1: ``b = 50/(2π) mm/rad``, ``θ ∈ [0, 4π]``.

    Parameters
    ----------
    b : float
        Growth, m/rad.
    theta0, theta1 : float
        Angle range, rad, ``0 <= theta0 < theta1 <= 2π MAX_TURNS``.
    """
    b = check_positive("b", b, "m/rad")
    if not (0 <= theta0 < theta1 and np.isfinite(theta1)):
        raise ValueError(f"need 0 <= theta0 < theta1, got [{theta0}, {theta1}] rad")
    if theta1 > 2 * np.pi * MAX_TURNS:
        raise ValueError(
            f"theta1 = {theta1:g} rad is more than {MAX_TURNS} turns ({MAX_TURNS} x 2 pi rad)"
        )
    # split by turns so each piece stays low-degree
    n_turns = max(int(np.ceil((theta1 - theta0) / (2 * np.pi))), 1)
    segs: list[Segment] = []
    for k in range(n_turns):
        a0 = theta0 + (theta1 - theta0) * k / n_turns
        a1 = theta0 + (theta1 - theta0) * (k + 1) / n_turns

        def f(u: np.ndarray, a0: float = a0, a1: float = a1) -> np.ndarray:
            t = a0 + (a1 - a0) * u
            return np.column_stack([b * t * np.cos(t), b * t * np.sin(t)])

        segs.extend(CurveSegment.from_function(f))
    return Path(tuple(segs), gap_tol=1e-9 * b * theta1 + 1e-15)


def spiral_length(b: float, theta0: float, theta1: float) -> float:
    """Closed-form arc length of ``r = b θ`` on ``[theta0, theta1]``, m."""

    def g(t: float) -> float:
        return 0.5 * b * (t * np.sqrt(1 + t * t) + np.arcsinh(t))

    return g(theta1) - g(theta0)


def ellipse(
    a: float, b: float, *, center: tuple[float, float] = (0.0, 0.0), angle: float = 0.0
) -> Path:
    """An ellipse with semi-axes ``a`` (along ``angle``) and ``b``, counter-clockwise."""
    a, b = check_positive("a", a, "m"), check_positive("b", b, "m")
    c, s = np.cos(angle), np.sin(angle)

    def f(u: np.ndarray) -> np.ndarray:
        t = 2 * np.pi * u
        x, y = a * np.cos(t), b * np.sin(t)
        return np.column_stack([center[0] + c * x - s * y, center[1] + s * x + c * y])

    return _curve(f, closed=True)


def lissajous(
    ax: float = 0.01, ay: float = 0.01, fx: int = 3, fy: int = 2, phase: float = np.pi / 2
) -> Path:
    """The closed Lissajous curve ``(ax sin(fx t + phase), ay sin(fy t))``, t ∈ [0, 2π].

    ``fx`` and ``fy`` are coprime integers from 1 to `MAX_LOBES`; the curve crosses itself
    but is one closed contour.
    """
    ax, ay = check_positive("ax", ax, "m"), check_positive("ay", ay, "m")
    if not (1 <= fx <= MAX_LOBES and 1 <= fy <= MAX_LOBES):
        raise ValueError(f"fx and fy must lie between 1 and {MAX_LOBES}, got {fx}, {fy}")
    if int(fx) != fx or int(fy) != fy or np.gcd(int(fx), int(fy)) != 1:
        raise ValueError(f"fx and fy must be coprime positive integers, got {fx}, {fy}")

    phase = math.remainder(check_finite("phase", phase, "rad"), 2 * np.pi)  # keep precision

    def f(u: np.ndarray) -> np.ndarray:
        t = 2 * np.pi * u
        return np.column_stack([ax * np.sin(fx * t + phase), ay * np.sin(fy * t)])

    return _curve(f, closed=True)


def butterfly(scale: float = 0.005) -> Path:
    """Temple Fay's butterfly curve, ``t ∈ [0, 12π]``, scaled by ``scale`` (m).

    ``x = sin t (e^{cos t} − 2 cos 4t − sin⁵(t/12))``, ``y = cos t (…)``; closed.
    """
    k = check_positive("scale", scale, "m")

    def f(u: np.ndarray) -> np.ndarray:
        t = 12 * np.pi * u
        r = np.exp(np.cos(t)) - 2 * np.cos(4 * t) - np.sin(t / 12) ** 5
        return k * np.column_stack([np.sin(t) * r, np.cos(t) * r])

    return _curve(f, closed=True)


SHAPES: dict[str, Callable[..., Path]] = {
    "rectangle": rectangle,
    "square": square,
    "circle": circle,
    "polygon": regular_polygon,
    "star": star,
    "spiral": spiral,
    "ellipse": ellipse,
    "lissajous": lissajous,
    "butterfly": butterfly,
}


def parse_shape(spec: str) -> Path:
    """Build a shape from ``"name"`` or ``"name:key=value,key=value"`` (SI values).

    Examples
    --------
    >>> parse_shape("circle:radius=0.01").length  # doctest: +ELLIPSIS
    0.0628...
    """
    name, _, args = spec.partition(":")
    name = name.strip().lower()
    if name not in SHAPES:
        raise ValueError(f"unknown shape {name!r}; known: {', '.join(sorted(SHAPES))}")
    kwargs: dict[str, float] = {}
    for item in filter(None, (a.strip() for a in args.split(","))):
        key, eq, val = item.partition("=")
        if not eq:
            raise ValueError(f"shape argument {item!r} must look like key=value")
        try:
            kwargs[key.strip()] = float(val)
        except ValueError:
            raise ValueError(f"shape argument {key}={val!r} is not a number") from None
        if not math.isfinite(kwargs[key.strip()]):  # no builder is meant for inf or NaN
            raise ValueError(f"shape argument {key.strip()}={val.strip()} must be a finite number")
    try:
        # an absurd size overflows inside a builder: no numpy warning printed, the
        # segments' own finiteness checks refuse the points
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return SHAPES[name](**kwargs)
    except TypeError as exc:
        raise ValueError(f"bad arguments for shape {name!r}: {exc}") from None
